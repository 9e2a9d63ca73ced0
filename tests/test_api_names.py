"""One API with the command line's names (issue 43): docs/api.md's table maps every option of every command to
its Python name. Every option of every parser has a row, every row names an option that exists, and every Python
name in it is a parameter of the function it names — so the table, the parsers and the signatures cannot drift."""

from __future__ import annotations

import argparse
import importlib
import inspect
import re

import pytest

import brdflab as bl
from brdflab.cli import main as cli_main
from tests.conftest import ROOT


def _rows() -> list[tuple[str, list[str], str]]:
    text = (ROOT / "docs" / "api.md").read_text()
    section = text.split("### Every option and its Python name", 1)[1].split("\n## ", 1)[0]
    rows = []
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) != 3 or cells[0] in ("command", "---"):
            continue
        rows.append((cells[0], re.findall(r"`([^`]+)`", cells[1]), cells[2]))
    return rows


def _parsers() -> dict[str, argparse.ArgumentParser]:
    parser = cli_main.build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return {name: sub.choices[name] for name in cli_main.COMMANDS}


def _names(action: argparse.Action) -> list[str]:
    return list(action.option_strings) or [action.dest.upper()]


def _resolve(path: str):
    """``bl.render`` / ``bl.kernels.use_engine`` / ``brdflab.cluster.Cluster`` → the object."""
    parts = path.split(".")
    if parts[0] == "bl":
        obj = bl
        for p in parts[1:]:
            obj = getattr(obj, p)
        return obj
    for k in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:k]))
        except ImportError:
            continue
        for p in parts[k:]:
            obj = getattr(obj, p)
        return obj
    raise AssertionError(path)


def test_every_option_has_a_row():
    rows = _rows()
    assert len(rows) > 80
    missing = []
    for name, p in _parsers().items():
        for action in p._actions:
            if isinstance(action, argparse._HelpAction) or action.dest == "func":
                continue
            names = _names(action)
            if not any(c in (name, "(all)") and set(names) & set(opts) for c, opts, _ in rows):
                missing.append(f"{name} {names[-1]}")
    assert not missing, f"options without a row in docs/api.md: {missing}"


def test_every_row_names_a_real_option_and_a_real_parameter():
    parsers = _parsers()
    for command, opts, python in _rows():
        if command != "(all)":
            known = {n for a in parsers[command]._actions for n in _names(a)}
            assert set(opts) <= known, f"{command} {opts}: no such option"
        if python.startswith("—"):
            assert len(python) > 10, f"{command} {opts}: say why there is no Python name"
            continue
        calls = re.findall(r"`((?:bl|brdflab)\.[\w.]+)\((\w*)=?\)`", python)
        if command != "(all)":
            assert calls, f"{command} {opts}: the Python cell names no function: {python}"
        for func, param in calls:
            obj = _resolve(func)
            if param:
                assert param in inspect.signature(obj).parameters, f"{func} has no parameter {param!r}"


@pytest.mark.parametrize("func, new, old", [(bl.plot, "cos", "times_cos"), (bl.plot, "size", "sphere_size"),
                                           (bl.plot, "spp", "sphere_spp"), (bl.fit, "fix", "fixed"),
                                           (bl.chi2_test, "count", "samples")])
def test_the_command_line_names_exist_beside_the_older_ones(func, new, old):
    params = inspect.signature(func).parameters
    assert new in params and old in params


def test_defaults_agree_with_the_command_line():
    assert inspect.signature(bl.report).parameters["spp"].default == (1, 4, 16, 64, 256)
    args = _parsers()["report"].parse_args(["scene.xml"])
    assert tuple(int(v) for v in str(args.spp).split(",")) == (1, 4, 16, 64, 256)
