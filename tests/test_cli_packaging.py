"""The command-line layer is installed as ``brdflab.cli`` (no top-level ``cli`` package); --version, --debug."""

from __future__ import annotations

import subprocess
import sys

import pytest

import brdflab
from brdflab.cli.main import main
from brdflab.errors import BrdflabError


def _run_outside(tmp_path, code: str) -> subprocess.CompletedProcess:
    # From a folder outside the repository, so only the installed packages are importable.
    return subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=120)


def test_cli_installed_under_brdflab_not_top_level(tmp_path):
    ok = _run_outside(tmp_path, "import brdflab.cli.main, brdflab.cli.render_cmd; print(brdflab.cli.main.__name__)")
    assert ok.returncode == 0, ok.stderr
    assert ok.stdout.strip() == "brdflab.cli.main"
    top = _run_outside(tmp_path, "import importlib.util, sys; sys.exit(importlib.util.find_spec('cli') is not None)")
    assert top.returncode == 0, "a top-level package named 'cli' is installed"


def test_version(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"brdflab {brdflab.__version__}"


@pytest.mark.parametrize("argv", [["--debug", "render", "missing.xml"], ["render", "missing.xml", "--debug"]])
def test_debug_before_or_after_subcommand_shows_traceback(tmp_path, argv):
    argv = [a if a != "missing.xml" else str(tmp_path / a) for a in argv]
    with pytest.raises(BrdflabError):
        main(argv)


def test_without_debug_one_line_exit_2(tmp_path, capsys):
    assert main(["render", str(tmp_path / "missing.xml")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err


@pytest.mark.parametrize(("argv", "command"), [
    (["render", "scene.xml"], "render"),
    (["--debug", "--engine", "numpy", "chi2", "--bsdf", "diffuse"], "chi2"),
    (["--engine=numpy", "check", "x.exr"], "check"),
    (["--engine", "render"], None),  # "render" is the value of --engine here (an invalid one)
    (["rendr", "scene.xml"], None),
    (["--help"], None),
    (["--", "render"], None),
])
def test_one_command_imports_only_its_module(argv, command):
    """The command named on the line is found past the global options; anything else builds the full parser,
    so that errors and --help list every command."""
    from brdflab.cli.main import COMMANDS, build_parser, requested_command

    assert requested_command(argv) == command
    parser = build_parser(command)
    subs = next(a for a in parser._actions if a.dest == "command").choices
    assert list(subs) == ([command] if command else list(COMMANDS))


def test_a_misspelt_command_still_lists_every_command(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["rendr", "scene.xml"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "invalid choice: 'rendr'" in err and "'validate'" in err and "'explore'" in err


def test_a_render_process_does_not_import_the_other_commands(tmp_path):
    code = ("import sys; from brdflab.cli.main import main\n"
            "try:\n    main(['render', '--help'])\nexcept SystemExit:\n    pass\n"
            "print(sorted(m for m in sys.modules if m.startswith('brdflab.cli.') and m.endswith('_cmd')))")
    out = _run_outside(tmp_path, code)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == "['brdflab.cli.render_cmd']"
