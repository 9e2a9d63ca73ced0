"""Render paths the other tests do not see, each against an independently computed expectation.

* **Several scaled area lights, fused.** The generated ``polygon_lights`` scene (a planar hexagon and a
  smooth sphere light: the fused :class:`~brdflab.emitter.area.AreaLightSet`) with each light's radiance
  divided by a different ``scale`` (2 and 0.25) that the scene then gives back: every estimator (light
  sampling, BSDF sampling hitting the lights, MIS, one sample per light), under uniform and power
  selection, must give the closed forms of tests/test_light_paths.py (Lambert's polygon formula, the smooth
  light's surface quadrature) — a dropped ``scale`` halves one light and quadruples the other.
* **A smooth mesh under a non-uniform scale.** A unit sphere with exact vertex normals, given a toWorld of
  scale (2, 1, 0.5), a rotation and a translation: an ellipsoid. Its vertex normals must be the gradient of
  the ellipsoid's implicit equation (computed here, not with the inverse transpose), and rendered shading
  normals must match the analytic normal at the analytic ray–ellipsoid intersection.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from brdflab.judges.estimators import agreement as ag
from brdflab.scene.loader import load_scene
from brdflab.scene.obj import load_obj
from tests.conftest import write_scene
from tests.test_light_paths import LIGHTS, POINTS, UP, closed_form_at


def _scaled_polygon_scene(tmp_path):
    text = (LIGHTS / "polygon_lights_mis.xml").read_text()
    text = text.replace('value="meshes/', f'value="{LIGHTS}/meshes/')
    hexagon = '<emitter type="area"><color name="radiance" value="5, 5, 6"/></emitter>'
    sphere = '<emitter type="area"><color name="radiance" value="12, 9, 6"/></emitter>'
    assert hexagon in text and sphere in text
    text = text.replace(hexagon, '<emitter type="area"><color name="radiance" value="2.5, 2.5, 3"/>'
                                 '<float name="scale" value="2"/></emitter>')
    text = text.replace(sphere, '<emitter type="area"><color name="radiance" value="48, 36, 24"/>'
                                '<float name="scale" value="0.25"/></emitter>')
    path = tmp_path / "scaled_lights.xml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("selection", ["uniform", "power"])
def test_fused_scaled_area_lights_are_the_closed_form(tmp_path, selection):
    """z-test of every estimator's mean at three floor points against the closed form (Šidák over 36 values
    per selection rule; 0.3 % tolerance for the smooth light's quadrature)."""
    from brdflab.integrator.common import area_light_set

    path = _scaled_polygon_scene(tmp_path)
    n = 3000
    zs = []
    for integ in ("direct_ems", "direct_mats", "direct_mis", "direct_whitted"):
        s = load_scene(path, integ)
        s.set_emitter_selection(selection)
        if integ != "direct_whitted":
            assert area_light_set(s) is not None  # the fused path is the one under test
        for j, x in enumerate(POINTS):
            o = np.tile(x + [0.0, 0.01, 0.0], (n, 1))
            d = np.tile(-UP, (n, 1))
            rng = np.random.default_rng(ag._seed("scaled-fused", selection, integ, j))
            L = s.integrator.li(s, o, d, np.full(n, 1.0), rng)
            ref = closed_form_at("polygon_lights", j, True)
            se = L.std(axis=0) / np.sqrt(n)
            z = np.maximum(np.abs(L.mean(axis=0) - ref) - 3e-3 * ref, 0.0) / se
            zs.append((float(z.max()), integ, j, L.mean(axis=0), ref))
            assert np.all(se > 0)
    alpha = 1 - (1 - 0.01) ** (1 / (3 * len(zs)))
    worst = max(zs, key=lambda t: t[0])
    assert 2 * stats.norm.sf(worst[0]) > alpha, worst


def test_fused_set_radiance_and_pdf_include_each_scale(tmp_path):
    """The fused set's light samples carry radiance·scale of the emitter they landed on, and rays that hit an
    emitter see its radiance·scale, for each of the two scaled lights."""
    from brdflab.integrator.common import area_light_set

    s = load_scene(_scaled_polygon_scene(tmp_path), "direct_ems")
    fused = area_light_set(s)
    rng = np.random.default_rng(7)
    n = 4000
    es = fused.sample(np.tile([-0.5, 0.0, 0.3], (n, 1)), rng.random((n, 3)))
    seen = {tuple(np.round(r, 9)) for r in es.radiance[es.pdf > 0]}
    assert seen == {(5.0, 5.0, 6.0), (12.0, 9.0, 6.0)}, seen
    le, _ = fused.eval_pdf_hit(np.array([0, 1]), np.ones(2), np.tile(UP, (2, 1)), np.tile(-UP, (2, 1)))
    assert np.allclose(le, [[5.0, 5.0, 6.0], [12.0, 9.0, 6.0]])


# -- a smooth mesh under a non-uniform scale ----------------------------------------------------------------
AXES = np.array([2.0, 1.0, 0.5])
ANGLE = 35.0
AXIS = np.array([1.0, 2.0, 0.5]) / np.linalg.norm([1.0, 2.0, 0.5])
CENTRE = np.array([0.3, -0.2, 0.1])


def _rotation() -> np.ndarray:
    """Rodrigues' rotation matrix (ANGLE about AXIS)."""
    k = AXIS
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    a = math.radians(ANGLE)
    return np.eye(3) + math.sin(a) * kx + (1 - math.cos(a)) * kx @ kx


def _sphere_obj(n_theta: int = 24, n_phi: int = 48) -> str:
    """A unit uv sphere with exact vertex normals (vn = v), written with full precision; the vn lines come in
    reverse order, so that a face's normal index differs from its position index."""
    vs, vns = [], []
    for i in range(n_theta + 1):
        th = math.pi * i / n_theta
        for j in range(n_phi):
            ph = 2 * math.pi * j / n_phi
            p = (math.sin(th) * math.cos(ph), math.sin(th) * math.sin(ph), math.cos(th))
            vs.append("v {!r} {!r} {!r}".format(*p))
            vns.append("vn {!r} {!r} {!r}".format(*p))
    total = len(vs)
    faces = []
    for i in range(n_theta):
        for j in range(n_phi):
            a, b = i * n_phi + j + 1, i * n_phi + (j + 1) % n_phi + 1
            c, d = a + n_phi, b + n_phi
            na, nb, nc, nd = (total + 1 - k for k in (a, b, c, d))
            if i > 0:
                faces.append(f"f {a}//{na} {c}//{nc} {b}//{nb}")
            if i < n_theta - 1:
                faces.append(f"f {b}//{nb} {c}//{nc} {d}//{nd}")
    return "\n".join(vs + vns[::-1] + faces) + "\n"


def _to_world_xml() -> str:
    ax = ",".join(repr(float(v)) for v in AXIS)
    return (f'<transform name="toWorld"><scale value="{AXES[0]},{AXES[1]},{AXES[2]}"/>'
            f'<rotate axis="{ax}" angle="{ANGLE}"/><translate value="{CENTRE[0]},{CENTRE[1]},{CENTRE[2]}"/>'
            "</transform>")


def _ellipsoid_normal(p: np.ndarray) -> np.ndarray:
    """Unit gradient of F(p) = |S⁻¹ Rᵀ (p − c)|² (the ellipsoid's implicit equation): ∝ R S⁻² Rᵀ (p − c)."""
    r = _rotation()
    g = ((p - CENTRE) @ r) / AXES**2 @ r.T
    return g / np.linalg.norm(g, axis=1, keepdims=True)


def _ellipsoid_hit(o: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(hit mask, point) of rays with the analytic ellipsoid (the smaller positive root of the quadratic)."""
    r = _rotation()
    ol = ((o - CENTRE) @ r) / AXES
    dl = (d @ r) / AXES
    a = np.sum(dl * dl, axis=1)
    b = 2 * np.sum(ol * dl, axis=1)
    c = np.sum(ol * ol, axis=1) - 1
    disc = b * b - 4 * a * c
    ok = disc > 0
    t = (-b - np.sqrt(np.where(ok, disc, 0.0))) / (2 * a)
    return ok & (t > 0), o + t[:, None] * d


def _ellipsoid_scene(tmp_path, integrator: str = "normals"):
    body = (f'<integrator type="{integrator}"/><camera type="perspective"><integer name="width" value="8"/>'
            f'<integer name="height" value="8"/></camera>'
            f'<mesh type="obj"><string name="filename" value="sphere.obj"/>{_to_world_xml()}'
            '<bsdf type="diffuse"/></mesh>')
    return write_scene(tmp_path, body, {"sphere.obj": _sphere_obj()})


def test_obj_normals_under_a_non_uniform_scale_are_the_ellipsoid_gradient(tmp_path):
    """load_obj with toWorld = translate · rotate · scale(2, 1, 0.5): the vertices lie on the ellipsoid and
    their normals are its implicit equation's gradient (to 1e-9)."""
    from brdflab.math import transform as tf

    _ellipsoid_scene(tmp_path)
    r4 = np.eye(4)
    r4[:3, :3] = _rotation()
    assert np.allclose(r4, tf.rotate(ANGLE, AXIS))  # Rodrigues here = brdflab's rotate (the same convention)
    mesh = load_obj(tmp_path / "sphere.obj", tf.Transform(tf.translate(CENTRE) @ r4 @ tf.scale(AXES)))
    local = ((mesh.positions - CENTRE) @ _rotation()) / AXES
    assert np.allclose(np.linalg.norm(local, axis=1), 1.0, atol=1e-9)
    np.testing.assert_allclose(mesh.normals, _ellipsoid_normal(mesh.positions), atol=1e-9)


def test_rendered_shading_normals_of_a_scaled_smooth_mesh(tmp_path):
    """Rays from outside onto the ellipsoid: the normals integrator's |n_s| against the analytic |normal| at the
    analytic hit (the mesh is inscribed: the median angle is < 1°, normals transformed as directions give
    > 15°)."""
    s = load_scene(_ellipsoid_scene(tmp_path))
    rng = np.random.default_rng(11)
    n = 4000
    target = CENTRE + (rng.random((n, 3)) - 0.5) * 2.0 * AXES.max()
    o = np.tile(CENTRE + [0.7, 3.0, 4.0], (n, 1))
    d = target - o
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    hit, p = _ellipsoid_hit(o, d)
    L = s.integrator.li(s, o, d, np.full(n, np.inf), rng)
    ref = np.abs(_ellipsoid_normal(p))
    both = hit & (L.sum(axis=1) > 0)
    assert both.sum() > 500 and (both == hit).mean() > 0.98  # the mesh and the ellipsoid agree on coverage
    cos = np.sum(L[both] * ref[both], axis=1) / np.linalg.norm(L[both], axis=1)
    angle = np.degrees(np.arccos(np.clip(cos, -1, 1)))
    assert np.median(angle) < 1.0 and np.quantile(angle, 0.99) < 4.0, (np.median(angle), angle.max())
