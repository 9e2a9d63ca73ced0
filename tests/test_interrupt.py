"""No lost work: --time-limit renders whole passes (signals: tests/test_signals.py)."""

from __future__ import annotations

import time

from brdflab.imageio import read_exr_header
from tests.conftest import CAMERA, QUAD_OBJ, write_scene


def _big_scene(tmp_path):
    cam = CAMERA.replace('value="32"', 'value="320"').replace('value="24"', 'value="240"')
    return write_scene(tmp_path, '<integrator type="direct_ems"/>' + cam
                       + '<emitter type="pointlight"><point name="position" value="0,2,0"/></emitter>'
                       + '<mesh type="obj"><string name="filename" value="q.obj"/></mesh>', {"q.obj": QUAD_OBJ})


def test_time_limit_renders_whole_passes(tmp_path):
    from brdflab.cli.main import main

    scene = _big_scene(tmp_path)
    t0 = time.perf_counter()
    assert main(["render", str(scene), "--spp", "100000", "--time-limit", "2", "--quiet"]) == 0
    assert time.perf_counter() - t0 < 120  # hang bound (not a speed check)
    spp = int(read_exr_header(tmp_path / "scene.exr")["brdflab_spp"])
    assert 1 <= spp < 100000
    assert not list(tmp_path.glob("*partial*"))
