"""Every file any command writes goes through the output rules of :mod:`brdflab.outputs` (issue 41).

For each output option of each command (the table :data:`CASES`), the command runs once in a fresh folder to learn
what it writes; then, in another fresh folder, every one of those files is planted as the user's own (content
brdflab did not write) and the command runs again: it must refuse with one line and exit 2, before any work, and
leave every planted file as it was. A command that writes one file outside the rules (as ``bench --json`` and
``chi2 --against-emitter`` did) fails here whatever the file is called.

:func:`test_every_output_option_is_covered` enumerates the parsers: a new option that names an output (a path
that is written) without a case here fails, so the table cannot fall behind the commands.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import numpy as np
import pytest

from brdflab.cli.main import COMMANDS, main
from tests.conftest import CAMERA, QUAD_OBJ, write_scene

POINT = '<emitter type="pointlight"><point name="position" value="0,2,0"/><color name="radiance" value="17,12,0"/>' \
        '</emitter>'
MESH = '<mesh type="obj"><string name="filename" value="q.obj"/></mesh>'


def _scene(folder: Path) -> Path:
    return write_scene(folder, '<integrator type="direct_ems"/>' + CAMERA + POINT + MESH, {"q.obj": QUAD_OBJ})


def _exrs(folder: Path) -> tuple[Path, Path]:
    from brdflab.imageio import write_exr

    rng = np.random.default_rng(1)
    a, b = folder / "a.exr", folder / "b.exr"
    write_exr(a, rng.random((24, 32, 3)).astype(np.float32))
    write_exr(b, rng.random((24, 32, 3)).astype(np.float32))
    return a, b


def _bsdf_samples(folder: Path) -> Path:
    from brdflab.math import warps

    d = warps.square_to_cosine_hemisphere(np.random.default_rng(2).random((3_000, 2)))
    np.savetxt(folder / "cos.txt", np.column_stack([d, d[:, 2] / np.pi]))
    return folder / "cos.txt"


def _light_samples(folder: Path) -> tuple[Path, Path]:
    from brdflab.judges.samples.light_samples import own_samples
    from brdflab.scene.loader import load_scene

    scene = _scene(folder)
    np.savetxt(folder / "light.txt", own_samples(load_scene(scene), 0, 3_000, seed=3))
    return folder / "light.txt", scene


def _merl(folder: Path) -> Path:
    import brdflab as bl
    from brdflab.bsdf.measured import tabulate, write_merl

    write_merl(folder / "m.binary", tabulate(bl.RoughConductor(R0=0.8, alpha=0.3)))
    return folder / "m.binary"


def _render_for_check(folder: Path) -> tuple[Path, Path]:
    import brdflab as bl

    scene = _scene(folder)
    img = bl.render(bl.load_scene(scene), spp=2, seed=5, workers=1)
    bl.write_exr(folder / "mine.exr", img)
    return folder / "mine.exr", scene


#: (command, output option) → a function of the folder giving the arguments (run with the folder as cwd).
CASES = {
    ("render", "-o"): lambda d: ["render", str(_scene(d)), "--spp", "1", "--workers", "1", "--quiet",
                                 "-o", "out/pic.exr"],
    ("render", "--figures"): lambda d: ["render", str(_scene(d)), "--spp", "1", "--workers", "1", "--quiet",
                                        "--figures", "figs"],
    ("check", "-o"): lambda d: ["check", str(_render_for_check(d)[0]), "--scene", str(d / "scene.xml"), "--spp",
                                "2", "--runs", "2", "--user-spp", "2", "--block", "8", "--levels", "1",
                                "--where-spp", "0", "--workers", "1", "--quiet", "-o", "chk"],
    ("chi2", "-o"): lambda d: ["chi2", "--bsdf", "diffuse", "--theta", "30", "-n", "2000", "-o", "c2"],
    ("chi2", "-o", "--samples --against"): lambda d: ["chi2", "--samples", str(_bsdf_samples(d)), "--against",
                                                      "cosine_hemisphere", "-o", "c2s"],
    ("chi2", "-o", "--samples --against-emitter"): lambda d: ["chi2", "--samples", str(_light_samples(d)[0]),
                                                              "--against-emitter", f"{d / 'scene.xml'}:0",
                                                              "-o", "c2e"],
    ("compare", "--heatmap"): lambda d: ["compare", *map(str, _exrs(d)), "--no-flip", "--heatmap", "heat.png"],
    ("compare", "--signed"): lambda d: ["compare", *map(str, _exrs(d)), "--no-flip", "--signed", "signed.png"],
    ("fit", "-o"): lambda d: ["fit", str(_merl(d)), "--effort", "quick", "-o", "fitted"],
    ("plot", "-o"): lambda d: ["plot", "--bsdf", "diffuse", "--views", "polar", "--effort", "quick", "-o", "plt"],
    ("report", "-o"): lambda d: ["report", str(_scene(d)), "--integrators", "direct_ems,direct_mats", "--spp",
                                 "1,2", "--runs", "2", "--ref-spp", "2", "--no-flip", "--no-mis-weights",
                                 "--workers", "1", "-o", "rep"],
    ("validate", "-o"): lambda d: ["validate", "--bsdf", "diffuse", "--theta", "30", "--samples", "2000",
                                   "--effort", "quick", "-o", "val"],
    ("bench", "--json"): lambda d: ["bench", str(_scene(d)), "--spp", "1", "--runs", "1", "--workers", "1",
                                    "--json", "bench/out.json"],
}

#: Options whose value is a path that is read, never written (or a flag that prints to the terminal).
NOT_OUTPUTS = {("compare", "--json"), ("fit", "--json")}


def _files(folder: Path) -> dict[Path, tuple[int, int]]:
    out = {}
    for root, _, names in os.walk(folder):
        for n in names:
            p = Path(root) / n
            st = p.stat()
            out[p.relative_to(folder)] = (st.st_mtime_ns, st.st_size)
    return out


@pytest.mark.parametrize("case", list(CASES), ids=lambda c: " ".join(c))
def test_no_command_replaces_a_file_it_did_not_write(case, tmp_path, monkeypatch, capsys):
    first, second = tmp_path / "first", tmp_path / "second"
    first.mkdir()
    second.mkdir()
    monkeypatch.chdir(first)
    argv = CASES[case](first)
    before = _files(first)
    status = main(argv)
    assert status in (0, 1), capsys.readouterr().err
    written = sorted(p for p, st in _files(first).items() if before.get(p) != st and p.name != ".brdflab-outputs")
    assert written, f"{case}: the command wrote nothing (a test with no data proves nothing)"
    capsys.readouterr()
    # The same run where each of those files is the user's own: refused before any work, nothing touched.
    monkeypatch.chdir(second)
    argv = [a.replace(str(first), str(second)) for a in CASES[case](second)]
    planted = {}
    for rel in written:
        p = second / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        planted[rel] = f"the user's own {rel.name}\n".encode()
        p.write_bytes(planted[rel])
    status = main(argv)
    err = capsys.readouterr().err
    assert status == 2, f"{case}: exit {status}, expected a refusal; {err[-300:]}"
    assert "refusing to replace" in err and "Traceback" not in err and err.count("\n") == 1, err
    for rel, data in planted.items():
        assert (second / rel).read_bytes() == data, f"{case}: {rel} was replaced"


def test_every_output_option_is_covered():
    """Every option of every command that takes a path-like value and names where something is written (-o,
    --output, --json FILE, --figures, --heatmap, --signed, …) has a case above; a new one fails here."""
    from brdflab.cli import main as cli_main

    parser = cli_main.build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    covered = {(c[0], c[1]) for c in CASES}
    words = ("out", "json", "figure", "heatmap", "signed", "save", "write", "dir", "report", "dest")
    found = set()
    for name in COMMANDS:
        for action in sub.choices[name]._actions:
            if not action.option_strings or action.nargs == 0:  # positionals are inputs; flags write nothing
                continue
            text = " ".join([*action.option_strings, str(action.dest), str(action.metavar or ""),
                             str(action.help or "")]).lower()
            if any(w in text for w in words) and ("write" in text or "output" in text or "folder" in text):
                found.add((name, action.option_strings[0]))
    missing = sorted(found - covered - NOT_OUTPUTS)
    assert not missing, f"output options without a case in CASES: {missing}"
    assert covered <= found, f"the enumeration misses options the table knows: {sorted(covered - found)}"


def test_the_rule_check_catches_a_command_that_bypasses_it(tmp_path, monkeypatch, capsys):
    """Negative control: with the bench's guard removed (the state before issue 41), the test's second run finds
    the user's file replaced."""
    import brdflab.outputs as outputs

    monkeypatch.setattr(outputs, "check_replaceable", lambda *a, **k: None)
    monkeypatch.chdir(tmp_path)
    scene = _scene(tmp_path)
    (tmp_path / "bench").mkdir()
    (tmp_path / "bench" / "out.json").write_text("the user's own notes\n")
    main(["bench", str(scene), "--spp", "1", "--runs", "1", "--workers", "1", "--json", "bench/out.json"])
    assert (tmp_path / "bench" / "out.json").read_text() != "the user's own notes\n"
    capsys.readouterr()

