"""Textures, OBJ texture coordinates and the camera's clip range against values written out by hand.

* Nori's checker (spec §12): p = trunc(u·scalex), trunc(v·scaley), 0.9 where the C remainders mod 2 agree,
  else 0.1 — a table with scalex ≠ scaley and negative coordinates (C truncation and remainder differ from
  floor and Python's modulo there).
* A checker-albedo diffuse quad whose OBJ ``vt`` run from −1 to 1, under a constant white environment: at
  a point x of the quad (one-sided, the sky's full upper hemisphere) L_o = albedo(uv(x)) · L exactly,
  with uv interpolated from the ``vt`` lines — every estimator.
* Camera: world rays of an identity camera start on the near plane z = near and end on the far plane
  z = far (Nori clips in camera-space depth, not in distance).
"""

from __future__ import annotations

import numpy as np
import pytest

from brdflab.film import Camera
from brdflab.math import transform as tf
from brdflab.scene.loader import load_scene
from brdflab.texture import CheckerTexture
from tests.conftest import write_scene


@pytest.mark.parametrize(("u", "v", "expected"), [
    (0.1, 0.1, 0.9),  # p = (0, 0)
    (0.4, 0.1, 0.1),  # scalex 3: p = (1, 0)
    (0.4, 0.6, 0.9),  # scaley 2: p = (1, 1)
    (0.7, 0.6, 0.1),  # (2, 1)
    (0.7, 0.2, 0.9),  # (2, 0)
    (-0.2, 0.2, 0.9),  # trunc(−0.6) = 0: the cell about 0 is twice as wide
    (-0.5, 0.2, 0.1),  # trunc(−1.5) = −1, fmod(−1, 2) = −1 ≠ 0
    (-0.5, -0.7, 0.9),  # (−1, −1)
    (0.5, -0.7, 0.1),  # (1, −1): fmod gives 1 ≠ −1 (Python's modulo would say equal)
    (0.9, -0.4, 0.9),  # trunc(−0.8) = 0: (2, 0)
])
def test_checker_table(u, v, expected):
    px, py = int(np.trunc(u * 3)), int(np.trunc(v * 2))
    hand = 0.9 if np.fmod(px, 2) == np.fmod(py, 2) else 0.1
    assert hand == expected  # the table above agrees with the rule as written
    got = CheckerTexture(3, 2).eval(np.array([[u, v]]))[0]
    assert np.allclose(got, expected)


QUAD = """v -1 0 -1
v 1 0 -1
v 1 0 1
v -1 0 1
vt 1 0.85
vt -1 0.85
vt -1 -0.65
vt 1 -0.65
f 1/3 4/2 3/1 2/4
"""  # the vt indices differ from the v indices: uv(x, z) = (x, 0.75 z + 0.1), no symmetry of the checker


def _rule(u: float, v: float) -> float:
    px, py = int(np.trunc(u * 3)), int(np.trunc(v * 2))
    return 0.9 if np.fmod(px, 2) == np.fmod(py, 2) else 0.1


@pytest.mark.parametrize("integ", ["direct_ems", "direct_mats", "direct_mis"])
def test_checker_albedo_quad_under_a_constant_sky(tmp_path, integ):
    body = (f'<integrator type="{integ}"/><camera type="perspective"><integer name="width" value="4"/>'
            '<integer name="height" value="4"/></camera>'
            '<mesh type="obj"><string name="filename" value="quad.obj"/><bsdf type="diffuse">'
            '<texture type="checker" name="albedo"><integer name="scalex" value="3"/>'
            '<integer name="scaley" value="2"/></texture></bsdf></mesh>'
            '<emitter type="environment"><color name="radiance" value="1,1,1"/></emitter>')
    s = load_scene(write_scene(tmp_path, body, {"quad.obj": QUAD}))
    pts = np.array([[0.1, 0.1], [0.4, 0.1], [0.4, 0.6], [-0.2, 0.2], [-0.5, 0.2], [0.5, -0.7], [-0.5, -0.7],
                    [0.7, 0.9], [-0.9, -0.9]])
    expected = [_rule(x, 0.75 * z + 0.1) for x, z in pts]
    assert expected == [0.9, 0.1, 0.9, 0.9, 0.1, 0.1, 0.1, 0.1, 0.1]
    n = 2000
    for (x, z), e in zip(pts, expected, strict=True):
        o = np.tile([x, 1.0, z], (n, 1))
        d = np.tile([0.0, -1.0, 0.0], (n, 1))
        L = s.integrator.li(s, o, d, np.full(n, np.inf), np.random.default_rng(int(100 * (x + 2) + z * 10 + 50)))
        m, se = L.mean(axis=0), L.std(axis=0) / np.sqrt(n)
        assert np.all(np.abs(m - e) <= 5 * se + 1e-9), (integ, x, z, m, e)


def test_camera_rays_span_near_to_far_in_depth():
    near, far = 0.5, 7.0
    cam = Camera(40, 20, 70.0, near, far, tf.Transform(np.eye(4)))
    rng = np.random.default_rng(3)
    px, py = rng.random(500) * 40, rng.random(500) * 20
    o, d, tmax = cam.generate_rays(px, py)
    o = o.astype(np.float64)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, rtol=1e-6)
    np.testing.assert_allclose(o[:, 2], near, rtol=1e-6)
    np.testing.assert_allclose((o + tmax[:, None] * d)[:, 2], far, rtol=1e-6)
    # A translated and rotated camera: the same in camera space.
    m = tf.translate(np.array([1.0, -2.0, 3.0])) @ tf.rotate(30.0, np.array([0.0, 1.0, 0.0]))
    cam2 = Camera(40, 20, 70.0, near, far, tf.Transform(m))
    o2, d2, t2 = cam2.generate_rays(px, py)
    inv = np.linalg.inv(m)
    o_cam = (o2.astype(np.float64) @ inv[:3, :3].T) + inv[:3, 3]
    end_cam = ((o2 + t2[:, None] * d2) @ inv[:3, :3].T) + inv[:3, 3]
    np.testing.assert_allclose(o_cam[:, 2], near, rtol=1e-5)
    np.testing.assert_allclose(end_cam[:, 2], far, rtol=1e-5)


def _to_world(tmp_path, ops: str) -> np.ndarray:
    from brdflab.scene.xmlparser import parse_scene_file

    p = write_scene(tmp_path, f'<mesh type="obj"><transform name="toWorld">{ops}</transform></mesh>')
    return parse_scene_file(p).children[0].props.get_transform("toWorld").matrix


def test_xml_transforms_by_hand(tmp_path):
    # lookat: columns (l, u', d, o) with d = (1, 0, 1)/√2, l = up × d = (1, 0, −1)/√2, u' = d × l = (0, 1, 0).
    m = _to_world(tmp_path, '<lookat origin="1,2,3" target="2,2,4" up="0,5,0"/>')
    r = 1 / np.sqrt(2)
    np.testing.assert_allclose(m, [[r, 0, r, 1], [0, 1, 0, 2], [-r, 0, r, 3], [0, 0, 0, 1]], atol=1e-12)
    # rotate: the axis is used as given (Nori does not normalise it): 90° about (0, 0, 2) maps x to (0, 2, 0).
    m = _to_world(tmp_path, '<rotate axis="0,0,2" angle="90"/>')
    np.testing.assert_allclose(m[:3, :3] @ [1.0, 0, 0], [0, 2, 0], atol=1e-12)
    m = _to_world(tmp_path, '<rotate axis="1,0,0" angle="30"/>')
    c, s = np.cos(np.radians(30)), np.sin(np.radians(30))
    np.testing.assert_allclose(m[:3, :3], [[1, 0, 0], [0, c, -s], [0, s, c]], atol=1e-12)
    # matrix: row-major, all 16 values in place.
    full = np.array([[2, 1, 0, 5], [0, 3, 1, 6], [1, 0, 4, 7], [0, 0, 0, 1]], dtype=float)
    vals = " ".join(str(v) for v in full.ravel())
    np.testing.assert_array_equal(_to_world(tmp_path, f'<matrix value="{vals}"/>'), full)
    # Composition order (M ← Op·M): scale, then rotate, then translate.
    m = _to_world(tmp_path, '<scale value="2,1,1"/><rotate axis="0,0,1" angle="90"/><translate value="0,0,5"/>')
    np.testing.assert_allclose(m @ [1.0, 0, 0, 1], [0, 2, 5, 1], atol=1e-12)


def test_environment_rotate_when_applied():
    """``apply_rotate``: a rotation about +Y by ``rotate`` degrees shifts u by rotate/360, i.e. the map seen at
    φ + rotate without it (φ = atan2(ω_z, ω_x)); its samples carry their own eval and pdf."""
    from brdflab.emitter.environment import EnvironmentEmitter

    rng = np.random.default_rng(8)
    img = (rng.random((8, 16, 3)) * 255).astype(np.float32)
    plain = EnvironmentEmitter(img, np.ones(3))
    turned = EnvironmentEmitter(img, np.ones(3), rotate=90.0, apply_rotate=True)
    assert np.allclose(EnvironmentEmitter(img, np.ones(3), rotate=90.0).eval(np.eye(3)), plain.eval(np.eye(3)))
    d = rng.normal(size=(200, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d_turned = np.stack([-d[:, 2], d[:, 1], d[:, 0]], axis=1)  # φ + 90°
    np.testing.assert_allclose(turned.eval(d), plain.eval(d_turned), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(turned.pdf(d), plain.pdf(d_turned), rtol=1e-9, atol=1e-12)
    s = turned.sample(np.zeros((500, 3)), rng.random((500, 3)))
    ok = s.pdf > 0
    np.testing.assert_allclose(s.pdf[ok], turned.pdf(s.wi[ok]), rtol=1e-6)
    np.testing.assert_allclose(s.radiance[ok], turned.eval(s.wi[ok]), rtol=1e-6, atol=1e-9)
