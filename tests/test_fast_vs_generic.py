"""Fast paths against the generic paths they replace, on inputs where both apply.

``tests/test_speed_paths.py`` checks each fast path on its own (the parallelogram light is uniform, family
members match a lone member, shading points match a full hit reconstruction). Here each fast path is run
beside the generic one on the same inputs:

* parallelogram light sampling vs the generic triangle path (choose a triangle by area, fold): the same
  density at the same points, and the same distribution of points (two-sample chi-square);
* one shared normal of a planar light vs the per-triangle normal table, and a flat light without normal
  interpolation vs interpolating its (flat) vertex normals: the same samples;
* the fused area-light set (one triangle distribution for all emitters) vs emitters sampled one by one:
  the same radiance and pdf of BSDF-sampled hits, and the same direct-light estimate in distribution;
* material families (one batched call per material type) vs one call per material, at the integrator
  level (``eval_bsdfs``/``sample_bsdfs`` over a scene's shading points): bit-identical per camera ray.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

import brdflab.bsdf.base
from brdflab.emitter.area import sample_triangle_points
from brdflab.integrator import common
from brdflab.scene.loader import load_scene
from tests.conftest import ROOT


def _floor_points(n: int, rng, half: float = 2.0, y: float = 0.0) -> np.ndarray:
    return np.column_stack([rng.uniform(-half, half, n), np.full(n, y), rng.uniform(-half, half, n)])


def _homogeneity_p(a: np.ndarray, b: np.ndarray, bins: int) -> float:
    """Two-sample chi-square p-value that bin indices ``a`` and ``b`` come from one distribution."""
    ca, cb = np.bincount(a, minlength=bins), np.bincount(b, minlength=bins)
    keep = (ca + cb) > 0
    return float(stats.chi2_contingency(np.stack([ca[keep], cb[keep]]))[1])


def test_parallelogram_matches_the_triangle_path():
    """Cornell-box light: the parallelogram fast path and the generic triangle path give the same pdf and
    radiance at the same points (pdf_hit is the generic density) and the same point distribution."""
    s = load_scene(ROOT / "scenes/cbox/cbox_diffuse.xml")
    em = s.emitters[0]
    assert em._quad is not None
    rng = np.random.default_rng(21)
    n = 100_000
    c, e1, e2 = em._quad
    ref = _floor_points(n, rng, 0.2) + [0.28, 0.0, 0.28]
    fast = em.sample(ref, rng.random((n, 3)))
    # The generic density of the same directions, as a BSDF-sampled ray hitting the light would get it.
    np.testing.assert_allclose(fast.pdf, em.pdf_hit(fast.dist, np.tile(em._face_n[0], (n, 1)), fast.wi), rtol=1e-12)
    quad, em._quad = em._quad, None
    try:
        slow = em.sample(ref, rng.random((n, 3)))
    finally:
        em._quad = quad
    np.testing.assert_allclose(slow.pdf, em.pdf_hit(slow.dist, np.tile(em._face_n[0], (n, 1)), slow.wi), rtol=1e-12)
    np.testing.assert_array_equal(fast.radiance[0], slow.radiance[0])

    def cells(r):
        y = ref + r.wi * r.dist[:, None]
        st = np.linalg.lstsq(np.column_stack([e1, e2]), (y - c).T, rcond=None)[0].T
        k = np.clip((st * 8).astype(int), 0, 7)
        return k[:, 0] * 8 + k[:, 1]

    assert _homogeneity_p(cells(fast), cells(slow), 64) > 1e-3
    # Power: a triangle path that over-weights one triangle (choice by 0.6/0.4 instead of 0.5/0.5) differs.
    u = rng.random((n, 3))
    u[:, 2] = np.where(rng.random(n) < 0.2, 0.0, u[:, 2])  # a fifth of the choices forced to triangle 0
    em._quad = None
    try:
        skew = em.sample(ref, u)
    finally:
        em._quad = quad
    assert _homogeneity_p(cells(fast), cells(skew), 64) < 1e-6


def test_planar_light_normal_and_flat_interpolation_match_generic():
    """A planar light (hexagon fan) keeps one normal instead of the per-triangle table, and a flat light
    skips vertex-normal interpolation: the same uniforms give the same samples as the generic tables."""
    s = load_scene(ROOT / "scenes/lights/polygon_lights_mis.xml")
    hexagon = next(e for e in s.emitters if len(e.tris) == 6)
    assert hexagon._normal.ndim == 1 and hexagon._nrm is None and hexagon._quad is None
    rng = np.random.default_rng(22)
    n = 20_000
    ref = _floor_points(n, rng)
    u = rng.random((n, 3))
    k = hexagon._choose_triangles(u[:, 2])
    fast = sample_triangle_points(hexagon._pos, hexagon._normal, None, k, u, ref)
    table = sample_triangle_points(hexagon._pos, hexagon._face_n, None, k, u, ref)
    # The generic interpolation of vertex normals that all equal the face normal.
    nrm = np.concatenate([hexagon._face_n.T, np.zeros((6, len(hexagon.tris)))])
    interp = sample_triangle_points(hexagon._pos, hexagon._face_n, nrm, k, u, ref)
    for other in (table, interp):
        for a, b in zip(fast, other, strict=True):
            np.testing.assert_allclose(a, b, rtol=1e-13, atol=1e-15)
    # And the emitter's own sample() uses exactly the fast one.
    r = hexagon.sample(ref, u)
    np.testing.assert_array_equal(r.wi, fast[0])


def _without_fusion(scene):
    scene.__dict__["_area_light_set"] = None
    return scene


@pytest.mark.parametrize("rel", ["scenes/lights/polygon_lights_mis.xml", "scenes/veach/veach_mis.xml"])
def test_fused_area_lights_match_per_emitter_sampling(rel):
    """The fused area-light set and per-emitter sampling: BSDF-sampled rays that hit a light get the same
    radiance and light pdf (selection included); light-sampling estimates agree in distribution."""
    fused = load_scene(ROOT / rel)
    fused.set_emitter_selection("power")
    assert common.area_light_set(fused) is not None
    plain = _without_fusion(load_scene(ROOT / rel))
    plain.set_emitter_selection("power")
    assert common.area_light_set(plain) is None
    cam = fused.camera
    rng = np.random.default_rng(23)
    m = 4000
    o, d, tmax = cam.generate_rays(rng.uniform(0, cam.width, m), rng.uniform(0, cam.height, m))
    _, sp = common.trace_camera(fused, o, d, tmax)
    # Rays from the shading points toward random points on the lights (so that many of them hit one).
    em = [fused.emitters[k] for k in rng.integers(0, len(fused.emitters), 400)]
    targets = np.array([e.sample(p[None], rng.random((1, 3))).wi[0] for e, p in zip(em, sp.p[:400], strict=True)])
    origin = sp.p[:400] + 1e-4 * sp.ng[:400]
    le_f, pdf_f = common.emission_along(fused, origin, targets)
    le_p, pdf_p = common.emission_along(plain, origin, targets)
    assert np.count_nonzero(pdf_f) > 100
    np.testing.assert_allclose(le_f, le_p, rtol=1e-14)
    np.testing.assert_allclose(pdf_f, pdf_p, rtol=1e-12)
    # Light sampling: E[L_e cos / p] per shading point is the same (z-test on the mean over points × reps).
    pts = common.ShadingPoints(sp.index[:200], sp.p[:200], sp.ng[:200], sp.ns[:200], sp.frames.take(np.arange(200)),
                               None if sp.uv is None else sp.uv[:200], sp.wi[:200], [], None)
    reps = 400
    rep = np.repeat(np.arange(200), reps)
    big = common.ShadingPoints(pts.index[rep], pts.p[rep], pts.ng[rep], pts.ns[rep], pts.frames.take(rep), None,
                               pts.wi[rep], [], None)
    est = {}
    for name, scene in (("fused", fused), ("plain", plain)):
        ls = common.sample_lights(scene, big, rng.random((len(rep), common.light_dims(scene))))
        cos = np.maximum(np.sum(ls.wi * big.ns, axis=1), 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            v = np.where(ls.pdf > 0, ls.radiance[:, 1] * cos / ls.pdf, 0.0)
        est[name] = v.reshape(200, reps).mean(axis=1)
    diff = est["fused"] - est["plain"]
    z = diff.mean() / (diff.std(ddof=1) / np.sqrt(len(diff)))
    assert abs(z) < 4, (z, est["fused"].mean(), est["plain"].mean())


def test_fused_light_set_applies_only_to_constant_lights_of_positive_area():
    """The fused set divides by each light's area: a zero-area light (degenerate triangles, built through the
    API — the loader rejects it) or a textured one stays on the generic per-emitter path."""
    from brdflab.emitter.area import AreaEmitter, AreaLightSet

    light = AreaEmitter(np.ones(3))
    light.area = 2.0
    assert AreaLightSet.applies([light])
    assert not AreaLightSet.applies([])
    light.area = 0.0
    assert not AreaLightSet.applies([light])


@pytest.mark.parametrize("rel", ["scenes/veach/veach_mis.xml", "scenes/cbox/cbox_substrate.xml",
                                 "scenes/lights/mixed_lights_mis.xml"])
def test_material_families_match_per_material_evaluation(rel, monkeypatch):
    """eval_bsdfs/sample_bsdfs over a scene's shading points, with families (one call per material type,
    per-point constants) and without (one call per material): bit-identical per camera ray."""
    fam = load_scene(ROOT / rel)
    assert common.scene_tables(fam).bsdf_families.any_tables
    monkeypatch.setattr(brdflab.bsdf.base.BSDF, "family_key", lambda self: None)
    one = load_scene(ROOT / rel)
    tab = common.scene_tables(one)
    assert not tab.bsdf_families.any_tables and len(tab.bsdf_families.families) == len(one.bsdfs)
    cam = fam.camera
    rng = np.random.default_rng(24)
    m = 6000
    o, d, tmax = cam.generate_rays(rng.uniform(0, cam.width, m), rng.uniform(0, cam.height, m))
    _, a = common.trace_camera(fam, o, d, tmax)
    _, b = common.trace_camera(one, o, d, tmax)
    np.testing.assert_array_equal(np.sort(a.index), np.sort(b.index))
    # Per camera ray: the same local directions and uniforms, whatever the order of the shading points.
    wo_cam = rng.normal(size=(m, 3))
    wo_cam /= np.linalg.norm(wo_cam, axis=1)[:, None]
    wo_cam[:, 2] = np.abs(wo_cam[:, 2])
    u_cam = rng.random((m, 3))
    res = {}
    for key, sp, scene in (("fam", a, fam), ("one", b, one)):
        order = np.argsort(sp.index)
        f, pdf = common.eval_bsdfs(scene, sp, np.asfortranarray(wo_cam[sp.index]), with_pdf=True)
        wo, w, p = common.sample_bsdfs(scene, sp, np.ascontiguousarray(u_cam[sp.index]))
        res[key] = [x[order] for x in (f, pdf, wo, w, p, sp.wi)]
    for x, y in zip(res["fam"], res["one"], strict=True):
        np.testing.assert_array_equal(x, y)


def test_any_positive_is_the_reduction_it_replaces():
    """The column-wise mask that skips shadow rays of zero contributions equals ``(rgb > 0).any(axis=1)``."""
    rgb = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1e-300], [0.0, 2.0, 0.0], [3.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])
    np.testing.assert_array_equal(common.any_positive(rgb), (rgb > 0).any(axis=1))
    np.testing.assert_array_equal(common.any_positive(rgb), [False, True, True, True, False])


@pytest.mark.parametrize("n_codes", [1, 3, 12])
def test_sort_by_code_matches_a_plain_grouping(n_codes):
    """Grouping shading points by code (one pass, per-code comparisons, or the radix argsort beyond 8
    codes) equals the obvious grouping, also when the highest possible codes do not occur."""
    rng = np.random.default_rng(77)
    codes = list(range(n_codes))
    code = rng.integers(-1, max(n_codes - 2, 1), 500)  # the last code(s) absent; −1 entries left out
    order, runs = common.sort_by_code(code, codes)
    want = [(c, np.flatnonzero(code == c)) for c in codes if np.any(code == c)]
    if n_codes == 1:
        want = [(0, np.flatnonzero(code >= 0))]
    assert [c for c, _ in runs] == [c for c, _ in want]
    for (_, sl), (_, idx) in zip(runs, want, strict=True):
        np.testing.assert_array_equal(order[sl], idx)


@pytest.mark.parametrize("n_groups", [1, 3, 8, 9, 12, 100])
def test_by_group_matches_a_plain_grouping(n_groups):
    """The per-material/per-emitter loop's grouping (one group: the whole batch; up to 8: one comparison
    each; more: a stable argsort split) yields each non-negative id once, ascending, with its indices."""
    rng = np.random.default_rng(n_groups)
    ids = rng.integers(-1, n_groups, 700)
    got = [(g, np.arange(len(ids))[sel]) for g, sel in common.by_group(ids)]
    want = [(g, np.flatnonzero(ids == g)) for g in range(n_groups) if np.any(ids == g)]
    assert [g for g, _ in got] == [g for g, _ in want]
    for (_, a), (_, b) in zip(got, want, strict=True):
        np.testing.assert_array_equal(a, b)
    assert list(common.by_group(np.zeros(0, np.int64))) == []
    (g, sel), = common.by_group(np.full(5, 3))
    assert g == 3 and sel == slice(None)
