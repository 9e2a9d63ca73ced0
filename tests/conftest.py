"""Shared fixtures: paths to the user scenes (optional) and tiny synthetic scenes."""

from __future__ import annotations

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SHARED = ROOT.parent / "shared" / "scenes"


def pytest_sessionstart(session) -> None:
    """Build the compiled kernels first, once (a fresh clone's first run; then they load in milliseconds):
    the tests that compare the engines need them, and with them every test process and subprocess runs
    the same engine from its first test on (without, a run's processes would switch from the NumPy engine
    to the compiled one when the background build ends)."""
    import signal

    # A suite started in the background of a shell without job control (``cmd &``, nohup, some CI runners)
    # inherits SIGINT ignored, and every process it starts would too: the tests that press Ctrl-C on a render
    # would see it ignored. Handled (not ignored), it is the default again in every child after exec.
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)

    from brdflab.kernels import ensure_built

    ensure_built()

QUAD_OBJ = """v -1 0 -1
v 1 0 -1
v 1 0 1
v -1 0 1
vt 0 0
vt 1 0
vt 1 1
vt 0 1
f 1/1 4/4 3/3 2/2
"""


def shared_scene(rel: str) -> Path:
    """Path of a user scene under ../shared/scenes, or skip the test when it is absent."""
    p = SHARED / rel
    if not p.exists():
        pytest.skip(f"user scenes not available ({p})")
    return p


def write_scene(tmp_path: Path, body: str, files: dict[str, str] | None = None, name: str = "scene.xml") -> Path:
    """Write ``<scene>body</scene>`` and extra files into ``tmp_path``; return the scene path."""
    for fname, text in (files or {}).items():
        (tmp_path / fname).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / fname).write_text(text)
    path = tmp_path / name
    path.write_text(f"<scene>\n{body}\n</scene>\n")
    return path


def sphere_scene(tmp_path: Path, bsdf_xml: str) -> Path:
    """An 8×6 direct_mis scene of the bundled left sphere with ``bsdf_xml`` (a ``<bsdf …>…</bsdf>`` element)."""
    sphere = ROOT / "scenes" / "cbox" / "meshes" / "sphere_left.obj"
    xml = tmp_path / "s.xml"
    xml.write_text('<scene><integrator type="direct_mis"/><camera type="perspective"><integer name="width" '
                   'value="8"/><integer name="height" value="6"/></camera><mesh type="obj">'
                   f'<string name="filename" value="{sphere}"/>{bsdf_xml}</mesh></scene>')
    return xml


CAMERA = """<camera type="perspective">
  <transform name="toWorld"><lookat origin="0,3,0.001" target="0,0,0" up="0,0,1"/></transform>
  <float name="fov" value="60"/><integer name="width" value="32"/><integer name="height" value="24"/>
</camera>"""
