"""Ray queries, analytic radiometry, determinism, and the CLI."""

from __future__ import annotations

import numpy as np
import pytest

from brdflab.cli.main import main
from brdflab.imageio import read_exr
from brdflab.renderer import pass_schedule, render
from brdflab.scene.loader import load_scene
from tests.conftest import CAMERA, QUAD_OBJ, write_scene

LIGHT_OBJ = """v -1 1 -1
v 1 1 -1
v 1 1 1
v -1 1 1
f 1 2 3 4
"""  # winding normal (p1 − p0) × (p2 − p0) = (2,0,0) × (2,0,2) → −y: faces down


def _scene(tmp_path, extra: str, integrator="direct_ems", light=True):
    mesh_light = ('<mesh type="obj"><string name="filename" value="light.obj"/>'
                  '<emitter type="area"><color name="radiance" value="1,1,1"/></emitter></mesh>') if light else ""
    return write_scene(
        tmp_path,
        f'<integrator type="{integrator}"/>' + CAMERA
        + '<mesh type="obj"><string name="filename" value="quad.obj"/>'
          '<transform name="toWorld"><scale value="10,1,10"/></transform>'
          '<bsdf type="diffuse"><color name="albedo" value="0.5,0.5,0.5"/></bsdf></mesh>'
        + mesh_light + extra,
        {"quad.obj": QUAD_OBJ, "light.obj": LIGHT_OBJ},
    )


def test_hits_misses_and_occlusion(tmp_path):
    s = load_scene(_scene(tmp_path, ""))
    g = s.geometry
    o = np.array([[0, 0.5, 0], [0, 0.5, 0], [20, 0.5, 0], [0, 2, 0]], float)
    d = np.array([[0, -1, 0], [0, 1, 0], [0, -1, 0], [0, -1, 0]], float)
    h = g.intersect(o, d)
    assert h.valid.tolist() == [True, True, False, True]
    np.testing.assert_allclose(h.t[:2], [0.5, 0.5], rtol=1e-6)
    np.testing.assert_allclose(h.p[0], [0, 0, 0], atol=1e-6)
    np.testing.assert_allclose(h.ng[0], [0, 1, 0])  # quad winding normal is +y
    assert h.mesh[0] == 0 and h.mesh[1] == 1 and h.mesh[3] == 1
    occ = g.occluded(o, d, np.full(4, 1e30))
    assert occ.tolist() == h.valid.tolist()
    # Shorter than the hit distance: not occluded.
    assert not g.occluded(o[:1], d[:1], np.array([0.4]))[0]


def test_no_self_intersection(tmp_path):
    """Shadow rays from points of the lit floor toward the light are never blocked by the floor itself."""
    s = load_scene(_scene(tmp_path, ""))
    g = s.geometry
    rng = np.random.default_rng(0)
    p = np.column_stack([rng.uniform(-0.9, 0.9, 20000), np.zeros(20000), rng.uniform(-0.9, 0.9, 20000)])
    h = g.intersect(p + [0, 0.3, 0], np.tile([0, -1.0, 0], (len(p), 1)))
    ls = s.emitters[0].sample(h.p, rng.random((len(p), 3)))
    o = g.offset_origin(h.p, h.ng, ls.wi)
    assert not g.occluded(o, ls.wi, g.shadow_tmax(ls.dist)).any()


def _form_factor_corner(x, y):
    """Point-to-parallel-rectangle form factor for a rectangle with a corner above the point."""
    a, b = np.sqrt(1 + x * x), np.sqrt(1 + y * y)
    return (x / a * np.arctan(y / a) + y / b * np.arctan(x / b)) / (2 * np.pi)


def test_irradiance_under_area_light(tmp_path):
    """Diffuse floor (ρ = 0.5) under a 2×2 emitting quad at height 1: L = ρ/π · E, E = π L_e F."""
    s = load_scene(_scene(tmp_path, ""))
    n = 400_000
    o = np.tile([0.0, 0.5, 0.0], (n, 1))
    d = np.tile([0.0, -1.0, 0.0], (n, 1))
    L = s.integrator.li(s, o, d, np.full(n, 1e4), np.random.default_rng(3))[:, 0]
    expected = 0.5 / np.pi * np.pi * 4 * _form_factor_corner(1.0, 1.0)
    se = L.std() / np.sqrt(n)
    assert abs(L.mean() - expected) < 3 * se, (L.mean(), expected, se)


def test_point_light_closed_form(tmp_path):
    s = load_scene(_scene(tmp_path, '<emitter type="pointlight"><point name="position" value="0,2,0"/>'
                                    '<color name="radiance" value="10,10,10"/></emitter>', light=False))
    p = np.array([[0.5, 0.0, 0.0]])
    L = s.integrator.li(s, p + [0, 0.5, 0], np.array([[0, -1.0, 0]]), np.array([1e4]),
                        np.random.default_rng(0))
    r2 = 0.25 + 4
    assert L[0, 0] == pytest.approx(0.5 / np.pi * 10 * (2 / np.sqrt(r2)) / r2, rel=1e-6)


def test_pass_schedule_hits_powers_of_two():
    sched = pass_schedule(256)
    cum = np.cumsum(sched)
    assert cum[-1] == 256
    for k in range(9):
        assert 2**k in cum


def test_workers_give_identical_images(tmp_path):
    s = load_scene(_scene(tmp_path, ""))
    a, _ = render(s, spp=8, seed=5, workers=1)
    b, _ = render(s, spp=8, seed=5, workers=2)
    c, _ = render(s, spp=8, seed=6, workers=2)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)


def test_cli_render_writes_exr_and_png(tmp_path, capsys):
    scene = _scene(tmp_path, "")
    assert main(["render", str(scene), "--spp", "2", "--quiet"]) == 0
    img = read_exr(tmp_path / "scene.exr")
    assert img.shape == (24, 32, 3) and np.isfinite(img).all() and img.max() > 0
    assert (tmp_path / "scene.png").exists()
    assert main(["render", str(scene), "--spp", "2", "--quiet", "--figures", str(tmp_path / "figs")]) == 0
    assert (tmp_path / "figs" / "scene_2spp.exr").exists()


def test_cli_error_no_traceback_no_output(tmp_path, capsys):
    scene = write_scene(tmp_path, '<integrator type="direct_ems"/>\n<camera type="perspective">'
                        '<float name="fov" value="-3"/></camera>')
    assert main(["render", str(scene), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "scene.xml:3" in err and "fov" in err and "Traceback" not in err
    assert not (tmp_path / "scene.exr").exists() and not (tmp_path / "scene.png").exists()
    assert not list(tmp_path.glob("*.tmp*"))


def test_no_emitter_warns_and_renders_black(tmp_path, capsys):
    scene = _scene(tmp_path, "", light=False)
    assert main(["render", str(scene), "--spp", "1", "--quiet"]) == 0
    assert "no emitter" in capsys.readouterr().err
    assert read_exr(tmp_path / "scene.exr").max() == 0
