"""Hostile inputs that cannot be files in tests/bad_scenes: odd file types, huge and sparse files, non-UTF-8
names, memory and schedule limits, and every option's range check (issue 18). Each must end in one short
line and exit status 2 (no traceback, no hang, nothing written)."""

from __future__ import annotations

import itertools
import os
import re
import warnings

import numpy as np
import pytest

from brdflab.cli.main import build_parser, main
from brdflab.errors import BrdflabError, clean
from brdflab.judges.material import chi2 as c2
from brdflab.renderer import iter_passes, render
from brdflab.scene.loader import load_scene
from tests.conftest import CAMERA, QUAD_OBJ, write_scene

POINT = '<emitter type="pointlight"><point name="position" value="0,2,0"/></emitter>'
MESH = '<mesh type="obj"><string name="filename" value="q.obj"/>{}</mesh>'


def _scene(tmp_path, extra: str = "", integrator: str = "direct_ems", name: str = "scene.xml", camera: str = CAMERA):
    return write_scene(tmp_path, f'<integrator type="{integrator}"/>' + camera + POINT + MESH.format(extra),
                       {"q.obj": QUAD_OBJ}, name=name)


def _fails(argv, capsys, pattern: str, status: int = 2) -> str:
    assert main([str(a) for a in argv]) == status
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.count("\n") == 1 and len(err) <= 320, err
    assert re.search(pattern, err), err
    return err


# -- file types and sizes ----------------------------------------------------------------------------------
def test_fifo_scene_does_not_block(tmp_path, capsys):
    fifo = tmp_path / "scene.xml"
    os.mkfifo(fifo)
    _fails(["render", fifo, "--quiet"], capsys, "scene file is a FIFO")


@pytest.mark.parametrize("path, kind", [("/dev/zero", "a character device"), ("/", "a directory")])
def test_device_or_directory_scene(path, kind, capsys):
    _fails(["render", path, "--quiet"], capsys, f"scene file is {kind}, not a regular file")


def test_sparse_huge_files_refused_before_reading(tmp_path, capsys):
    big = tmp_path / "big.xml"
    with open(big, "wb") as f:
        f.truncate(3 * 2**30)  # sparse: no disk used, but larger than the 2 GiB default limit
    _fails(["render", big, "--quiet"], capsys, r"scene file is 3.0 GiB, larger than the input limit .*MAX_INPUT_MB")
    scene = write_scene(tmp_path, '<integrator type="direct_ems"/>' + CAMERA
                        + '<mesh type="obj"><string name="filename" value="big.obj"/></mesh>')
    with open(tmp_path / "big.obj", "wb") as f:
        f.truncate(20 * 2**30)
    _fails(["render", scene, "--quiet"], capsys, r"big.obj: OBJ file is 20.0 GiB")


def test_input_limit_can_be_raised_or_lowered(tmp_path, capsys, monkeypatch):
    scene = _scene(tmp_path)
    monkeypatch.setenv("BRDFLAB_MAX_INPUT_MB", "0.0001")
    _fails(["render", scene, "--quiet"], capsys, r"larger than the input limit")
    monkeypatch.setenv("BRDFLAB_MAX_INPUT_MB", "bogus\x1b")
    _fails(["render", scene, "--quiet"], capsys, r"BRDFLAB_MAX_INPUT_MB must be a positive number, got 'bogus\\x1b'")


def test_huge_attribute_gives_short_message(tmp_path):
    scene = _scene(tmp_path, '<bsdf type="diffuse"><color name="albedo" value="' + "7" * 20_000_000 + '"/></bsdf>')
    with pytest.raises(BrdflabError) as exc:
        load_scene(scene)
    assert "20,000,000 characters long" in str(exc.value) and len(str(exc.value)) <= 300


def test_non_utf8_scene_name_renders(tmp_path, capsys):
    src = _scene(tmp_path)
    odd = os.fsdecode(bytes(tmp_path) + b"/sc\xffene.xml")
    os.rename(src, odd)
    assert main(["render", odd, "--spp", "1", "--workers", "1", "--quiet"]) == 0
    assert os.path.exists(odd[:-4] + ".exr") and os.path.exists(odd[:-4] + ".png")
    assert not [p for p in os.listdir(tmp_path) if p.startswith(".")]


def test_clean_escapes_and_truncates():
    assert clean("a\x1b[31m\x07\x00") == "a\\x1b[31m\\x07\\x00"
    assert clean("x" * 1000) == "x" * 59 + "…"
    assert clean(os.fsdecode(b"\xff")) == "\\xff"
    assert clean("é") == "é"


# -- physically suspicious but legal values ------------------------------------------------------------------
@pytest.mark.parametrize("bsdf", ['<bsdf type="roughconductor"><color name="R0" value="1.5,0.5,0.5"/></bsdf>',
                                  '<bsdf type="roughsubstrate"><color name="kd" value="1.2,1,1"/></bsdf>',
                                  '<bsdf type="diffuse"><color name="albedo" value="2,2,2"/></bsdf>'])
def test_energy_creating_reflectance_warns_with_location(tmp_path, bsdf):
    scene = _scene(tmp_path, bsdf)
    with pytest.warns(UserWarning, match=r"scene.xml:\d+: .*creates energy"):
        load_scene(scene)


def test_bsdf_sampling_with_only_point_lights_warns(tmp_path, capsys):
    scene = _scene(tmp_path, integrator="direct_mats")
    with pytest.warns(UserWarning, match="can never hit point lights.*black"):
        load_scene(scene)
    assert main(["render", str(scene), "--spp", "1", "--workers", "1", "--quiet"]) == 0
    assert "brdflab: warning:" in capsys.readouterr().err


def test_no_raw_numpy_warning_from_a_render(tmp_path):
    # An emitter whose radiance is legal but whose products overflow in places: non-finite samples are
    # dropped and counted, NumPy's floating-point warnings are not shown.
    scene = write_scene(tmp_path, '<integrator type="direct_ems"/>' + CAMERA
                        + '<emitter type="pointlight"><point name="position" value="0,1e-160,0"/>'
                        '<color name="radiance" value="1e30,1e30,1e30"/></emitter>' + MESH.format(""),
                        {"q.obj": QUAD_OBJ})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        render(load_scene(scene), spp=1, workers=1)


@pytest.mark.parametrize("scale, ok", [("1", True), ("1.000001", False)])
def test_area_radiance_times_scale_bound_is_inclusive(tmp_path, scale, ok):
    # 'scale' × 'radiance' may reach MAX_COMPONENT (1e30, "at most") but not exceed it.
    light = ('<emitter type="area"><color name="radiance" value="1e30,1,1"/>'
             f'<float name="scale" value="{scale}"/></emitter>')
    scene = _scene(tmp_path, light)
    if ok:
        assert load_scene(scene).emitters
    else:
        with pytest.raises(BrdflabError, match=r"scene.xml:\d+: .*overflows the float32"):
            load_scene(scene)


# -- resources and schedules ------------------------------------------------------------------------------------
def test_schedules_are_lazy():
    first = list(itertools.islice(iter_passes(2**63 - 1, max_pass=64, progressive=False), 3))
    assert first == [64, 64, 64]
    prog = list(itertools.islice(iter_passes(2**40, checkpoints=(3, 2**39)), 6))
    assert prog == [1, 1, 1, 3, 6, 12]


def test_huge_sample_count_with_time_limit_ends(tmp_path):
    scene = _scene(tmp_path).read_text().replace("<integrator", '<sampler type="independent">'
                                                 '<integer name="sampleCount" value="9223372036854775807"/>'
                                                 "</sampler><integrator")
    (tmp_path / "scene.xml").write_text(scene)
    assert main(["render", str(tmp_path / "scene.xml"), "--time-limit", "0.5", "--workers", "1", "--quiet"]) == 0
    assert (tmp_path / "scene.exr").exists()


def test_memory_estimate_before_allocating(tmp_path, capsys, monkeypatch):
    big = CAMERA.replace('value="32"', 'value="8000"').replace('value="24"', 'value="8000"')
    scene = _scene(tmp_path, camera=big)
    monkeypatch.setenv("BRDFLAB_MEMORY_LIMIT_GB", "1")
    _fails(["render", scene, "--quiet", "--workers", "1"], capsys,
           r"would need \d+\.\d GiB for a 8000×8000 render with 1 worker, more than the memory limit of 1.0 GiB "
           r"\(raise it with BRDFLAB_MEMORY_LIMIT_GB")
    small = _scene(tmp_path)
    _fails(["render", small, "--quiet", "--workers", "200"], capsys, r"would need .* with 200 workers")


def test_environment_map_memory_estimate(tmp_path, capsys, monkeypatch):
    from brdflab.imageio import write_exr

    write_exr(tmp_path / "sky.exr", np.ones((512, 1024, 3), np.float32))
    scene = write_scene(tmp_path, '<integrator type="direct_ems"/>' + CAMERA
                        + '<emitter type="environment"><string name="filename" value="sky.exr"/></emitter>')
    monkeypatch.setenv("BRDFLAB_MEMORY_LIMIT_GB", "0.05")
    _fails(["render", scene, "--quiet"], capsys, r"scene.xml:\d+: environment map: would need 80 MiB for the "
           r"1024×512 environment map 'sky.exr'")


# -- option ranges (exit 2, one line) ---------------------------------------------------------------------------
@pytest.mark.parametrize("argv", [
    ["render", "S", "--seed", "-1"], ["render", "S", "--seed", "18446744073709551616"],
    ["render", "S", "--time-limit", "-5"], ["render", "S", "--time-limit", "nan"], ["render", "S", "--time-limit", "0"],
    ["render", "S", "--spp", "0"], ["render", "S", "--workers", "1000"], ["render", "S", "--workers", "0"],
    ["report", "S", "--seed", "-1"], ["report", "S", "--ref-spp", "0"],
    ["chi2", "--warp", "beckmann", "--samples", "-5"], ["chi2", "--warp", "beckmann", "--samples", "0"],
    ["chi2", "--bsdf", "roughconductor", "--alpha", "inf"], ["chi2", "--bsdf", "roughconductor", "--theta", "nan"],
    ["validate", "--samples", "0"], ["bench", "--runs", "0"],
])
def test_option_out_of_range_is_usage_error(argv, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "error: argument" in err


def test_every_option_has_help():
    parser = build_parser()
    sub = next(a for a in parser._actions if a.choices and isinstance(a.choices, dict))
    missing = [f"{name} {'/'.join(a.option_strings) or a.dest}" for name, p in sub.choices.items()
               for a in p._actions if not a.help and a.dest != "help"]
    assert not missing, missing


def test_bench_with_missing_scene_exits_2(capsys, monkeypatch):
    import brdflab.benchmarking

    monkeypatch.setitem(brdflab.benchmarking.CASES, "ghost", ("scenes/does_not_exist.xml", ("direct_ems",)))
    _fails(["bench", "ghost"], capsys, "bench scene of ghost not found")


# -- the validator never passes without data ----------------------------------------------------------------------
def test_chi2_without_data_is_never_a_pass():
    stat, dof, p = c2.pearson(np.zeros(10), np.full(10, 10.0))
    assert dof == 0 and np.isnan(p)
    stat, dof, p = c2.pearson(np.full(10, 10.0), np.full(10, np.nan))
    assert not c2.Chi2Result("x", {}, stat, dof, p).passed
    stat, dof, p = c2.pearson(np.array([3.0]), np.array([3.0]))  # one bin: no degree of freedom
    assert dof == 0 and not c2.Chi2Result("x", {}, stat, dof, p).passed
    with pytest.raises(BrdflabError, match="at least 1 sample"):
        c2.chi2_test("x", lambda u: (u, np.ones(len(u))), lambda w: np.ones(len(w)), np.array([0, 0, 1.0]), n=0)
