"""Output safety (issue 18): no output replaces an input, nothing is written outside the folder named by -o,
an EXR + PNG pair is replaced together or not at all (full disk, failed rename, concurrent writers), odd
output names are clean errors, and a closed pipe ends quietly."""

from __future__ import annotations

import errno
import os
import subprocess
import sys
import threading

import numpy as np
import pytest

import brdflab.imageio as io
from brdflab.cli.main import main
from brdflab.imageio import read_exr, read_png, srgb_bytes, write_exr, write_images
from tests.conftest import CAMERA, QUAD_OBJ, write_scene

POINT = '<emitter type="pointlight"><point name="position" value="0,2,0"/></emitter>'
MESH = '<mesh type="obj"><string name="filename" value="q.obj"/></mesh>'


def _scene(tmp_path, name="scene.xml", extra=""):
    return write_scene(tmp_path, '<integrator type="direct_ems"/>' + CAMERA + POINT + extra + MESH,
                       {"q.obj": QUAD_OBJ}, name=name)


def _render(scene, *extra):
    return main(["render", str(scene), "--spp", "1", "--workers", "1", "--quiet", *map(str, extra)])


def _one_line_error(capsys, pattern):
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.count("\n") == 1 and pattern in err, err


def _no_temporaries(folder):
    assert not [p for p in os.listdir(folder) if p.startswith(".brdflab-") or ".tmp" in p]


# -- outputs never replace inputs -------------------------------------------------------------------------------
def test_scene_named_png_is_not_overwritten(tmp_path, capsys):
    scene = _scene(tmp_path, name="scene.png")
    before = scene.read_bytes()
    assert _render(scene) == 2
    _one_line_error(capsys, "it is an input of this run")
    assert scene.read_bytes() == before and not (tmp_path / "scene.exr").exists()


def test_output_equal_to_environment_map_is_refused(tmp_path, capsys):
    write_exr(tmp_path / "sky.exr", np.ones((8, 16, 3), np.float32))
    scene = _scene(tmp_path, extra='<emitter type="environment"><string name="filename" value="sky.exr"/></emitter>')
    before = (tmp_path / "sky.exr").read_bytes()
    assert _render(scene, "-o", tmp_path / "sky.exr") == 2
    _one_line_error(capsys, "sky.exr'); choose another output name")
    assert (tmp_path / "sky.exr").read_bytes() == before


def test_heatmap_cannot_replace_the_reference(tmp_path, capsys):
    a, b = tmp_path / "a.exr", tmp_path / "b.exr"
    write_exr(a, np.ones((4, 4, 3), np.float32))
    write_exr(b, np.ones((4, 4, 3), np.float32))
    assert main(["compare", str(a), str(b), "--heatmap", str(b)]) == 2
    _one_line_error(capsys, "expected a .png or .svg")
    assert main(["compare", str(a), str(b), "--heatmap", str(tmp_path / "heat")]) == 0
    assert (tmp_path / "heat.png").exists()


# -- nothing outside the folder named by -o ------------------------------------------------------------------------
def test_chi2_does_not_touch_the_parent_index(tmp_path, capsys):
    user = tmp_path / "mine"
    user.mkdir()
    (user / "index.html").write_text("my own page")
    argv = ["chi2", "--warp", "uniform_disk", "-n", "2000"]
    assert main([*argv, "-o", str(user / "r")]) == 0
    assert (user / "index.html").read_text() == "my own page"
    assert (user / "r" / "index.html").exists()
    # Where brdflab creates the parent itself, it may index it.
    assert main([*argv, "-o", str(tmp_path / "new" / "r")]) == 0
    assert "r" in (tmp_path / "new" / "index.html").read_text()
    capsys.readouterr()


def test_existing_file_where_a_folder_is_expected(tmp_path, capsys):
    (tmp_path / "f").write_text("x")
    assert main(["chi2", "--warp", "uniform_disk", "-n", "2000", "-o", str(tmp_path / "f")]) == 2
    _one_line_error(capsys, "is an existing file, not a folder")
    scene = _scene(tmp_path)
    assert _render(scene, "--figures", tmp_path / "f") == 2
    _one_line_error(capsys, "is an existing file, not a folder")
    assert (tmp_path / "f").read_text() == "x"


def test_partial_renders_are_named_partial_everywhere(tmp_path):
    from brdflab.cli.render_cmd import output_paths

    scene = tmp_path / "s.xml"
    assert output_paths(scene, None, tmp_path / "figs", 12, partial=True)[0].name == "s_partial_12spp.exr"
    assert output_paths(scene, None, tmp_path / "figs", 12)[1].name == "s_12spp.png"
    assert output_paths(scene, tmp_path / "o.exr", None, 3, partial=True)[1].name == "o_partial_3spp.png"
    assert output_paths(scene, None, None, 3)[0] == tmp_path / "s.exr"


# -- the EXR + PNG pair ---------------------------------------------------------------------------------------------
def _old_pair(tmp_path):
    exr, png = tmp_path / "out.exr", tmp_path / "out.png"
    write_images(exr, png, np.zeros((24, 32, 3), np.float32))
    return exr, png, exr.read_bytes(), png.read_bytes()


def _failing(exc):
    def make_writer(*args, **kwargs):
        def writer(tmp):
            raise exc
        return writer
    return make_writer


@pytest.mark.parametrize("which, exc, message", [
    ("_png_writer", OSError(errno.ENOSPC, os.strerror(errno.ENOSPC)), "No space left on device"),  # full disk
    ("_exr_writer", RuntimeError("Error writing\x1b file: No space left on device"),  # OpenEXR's exception
     "cannot write image: Error writing\\x1b file"),
])
def test_failed_write_keeps_the_old_pair(tmp_path, capsys, monkeypatch, which, exc, message):
    scene = _scene(tmp_path)
    exr, png, exr_bytes, png_bytes = _old_pair(tmp_path)
    monkeypatch.setattr(io, which, _failing(exc))
    assert _render(scene, "-o", exr) == 2
    _one_line_error(capsys, message)
    assert exr.read_bytes() == exr_bytes and png.read_bytes() == png_bytes
    _no_temporaries(tmp_path)


def test_failed_second_rename_restores_the_first(tmp_path, monkeypatch):
    exr, png, exr_bytes, png_bytes = _old_pair(tmp_path)
    real = os.replace
    failed = []

    def flaky(src, dst):  # the rename of the new PNG fails once
        if str(dst) == str(png) and not failed:
            failed.append(src)
            raise OSError(errno.EIO, "I/O error")
        return real(src, dst)

    monkeypatch.setattr(io.os, "replace", flaky)
    with pytest.raises(io.ImageError, match="I/O error"):
        write_images(exr, png, np.ones((24, 32, 3), np.float32))
    assert exr.read_bytes() == exr_bytes and png.read_bytes() == png_bytes
    _no_temporaries(tmp_path)


def test_failed_rename_of_a_new_pair_leaves_neither(tmp_path, monkeypatch):
    exr, png = tmp_path / "n.exr", tmp_path / "n.png"
    real = os.replace

    def flaky(src, dst):
        if str(dst) == str(png):
            raise OSError(errno.EIO, "I/O error")
        return real(src, dst)

    monkeypatch.setattr(io.os, "replace", flaky)
    with pytest.raises(io.ImageError, match="I/O error"):
        write_images(exr, png, np.ones((8, 8, 3), np.float32))
    assert not exr.exists() and not png.exists()
    _no_temporaries(tmp_path)


def test_folder_named_like_an_output(tmp_path, capsys):
    (tmp_path / "out.png").mkdir()
    assert _render(_scene(tmp_path), "-o", tmp_path / "out.exr") == 2
    _one_line_error(capsys, "out.png' is a folder; expected an image file name")
    assert not (tmp_path / "out.exr").exists()
    _no_temporaries(tmp_path)


def test_concurrent_writers_leave_a_matching_pair(tmp_path):
    exr, png = tmp_path / "c.exr", tmp_path / "c.png"
    errors = []

    def writer(value):
        try:
            for _ in range(6):
                write_images(exr, png, np.full((16, 16, 3), value, np.float32))
        except Exception as exc:  # pragma: no cover - reported below
            errors.append(exc)

    threads = [threading.Thread(target=writer, args=(v,)) for v in (0.2, 0.7)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=120)  # hang bound
    assert not errors
    value = float(read_exr(exr)[0, 0, 0])
    assert value in (np.float32(0.2), np.float32(0.7))
    assert np.array_equal(read_png(png), srgb_bytes(np.full((16, 16, 3), value)))
    _no_temporaries(tmp_path)


# -- pipes -----------------------------------------------------------------------------------------------------------
def test_closed_pipe_ends_quietly(tmp_path):
    a, b = tmp_path / "a.exr", tmp_path / "b.exr"
    write_exr(a, np.ones((4, 4, 3), np.float32))
    write_exr(b, np.full((4, 4, 3), 2, np.float32))
    # `true` exits at once without reading: every write of brdflab hits a closed pipe.
    cmd = f"'{sys.executable}' -m brdflab.cli.main compare '{a}' '{b}' | true"
    out = subprocess.run(["bash", "-o", "pipefail", "-c", cmd], capture_output=True, text=True, timeout=120)
    assert "Traceback" not in out.stderr and "BrokenPipe" not in out.stderr, out.stderr


def test_srgb_bytes_by_the_formula():
    """srgb_bytes pinned to the spec's formula (§1) evaluated as written, so that a faster rewrite must give the
    same bytes: random values, the branch point and its neighbours, values whose 255·s lands next to an integer,
    1, above 1, zeros, negatives, NaN and ±inf; and the bytes of a few of them by hand."""
    rng = np.random.default_rng(5)
    t = 0.0031308
    edges = [0.0, -0.0, -1.0, t, np.nextafter(t, 0), np.nextafter(t, 1), 1.0, np.nextafter(1.0, 0), 1.5, 1e30,
             np.nan, np.inf, -np.inf, 1e-300]
    k = np.arange(256) / 255.0  # s = k/255 exactly: c = OETF⁻¹(s), then ± a few ulps
    c_k = np.where(k <= 0.04045, k / 12.92, ((k + 0.055) / 1.055) ** 2.4)
    near = np.concatenate([c_k, np.nextafter(c_k, 0), np.nextafter(c_k, 2)])
    vals = np.concatenate([rng.random(30000) ** 3, rng.random(3000) * 0.01, edges, near]).astype(np.float64)
    img = vals[: len(vals) // 3 * 3].reshape(-1, 1, 3)
    c = np.clip(np.nan_to_num(img.astype(np.float64), nan=0.0, posinf=1.0, neginf=0.0), 0.0, None)
    s = np.where(c <= t, 12.92 * c, 1.055 * np.power(c, 1.0 / 2.4) - 0.055)
    want = np.floor(np.clip(255.0 * s, 0.0, 255.0)).astype(np.uint8)
    np.testing.assert_array_equal(srgb_bytes(img), want)
    f32 = img.astype(np.float32)
    np.testing.assert_array_equal(srgb_bytes(f32), srgb_bytes(f32.astype(np.float64)))
    # c = 1: 1.055 − 0.055 rounds below 1 (254.99999999999997 before the floor); NaN → 0, +inf → 1 → 254.
    assert srgb_bytes(np.array([[[1.0, 1.0001, np.nan]], [[np.inf, -np.inf, 0.5]]])).tolist() == [
        [[254, 255, 0]], [[254, 0, 187]]]
