"""The fast paths of the render loop give the same answers as the plain ones.

* Walker's alias table (light-triangle choice) samples its pmf: chi-square over the outcomes, and a
  table built from the wrong weights is rejected.
* A quad light is sampled as one parallelogram: uniform by area (chi-square, with a negative control),
  the same pdf as the triangle path. Mirrored lights (vertex normals opposite the winding) skip the
  normal interpolation, bit-identical to the interpolating path.
* Shading points interpolate vertex normals only on meshes whose normals are bent, and match fully
  reconstructed hits.
* Material families (one batched call per material type) reproduce the per-material evaluation.
* Parallel workers (forked processes, or the thread fallback) give the image of one in-process worker, bit
  for bit, and count the rays they trace; a parallel render stopped midway keeps exactly its completed
  passes.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from brdflab.bsdf.diffuse import Diffuse
from brdflab.bsdf.family import BSDFFamilies
from brdflab.bsdf.roughconductor import RoughConductor
from brdflab.bsdf.roughsubstrate import RoughSubstrate
from brdflab.emitter.area import DiscreteChooser
from brdflab.math.distribution import AliasTable
from brdflab.renderer import render
from brdflab.scene.loader import load_scene
from brdflab.texture import CheckerTexture
from tests.conftest import ROOT


def _chi2_p(idx: np.ndarray, pmf: np.ndarray) -> float:
    counts = np.bincount(idx, minlength=len(pmf))
    expected = pmf * len(idx)
    assert counts[expected == 0].sum() == 0, "an outcome of probability 0 was drawn"
    keep = expected > 0
    return float(stats.chisquare(counts[keep], expected[keep]).pvalue)


@pytest.mark.parametrize("n", [9, 100, 3840])
def test_alias_table_samples_its_pmf(n):
    rng = np.random.default_rng(n)
    w = rng.random(n) ** 3
    w[::7] = 0.0  # zero-weight outcomes must never be drawn
    table = AliasTable(w)
    idx = table.sample(rng.random(400_000))
    assert idx.min() >= 0 and idx.max() < n
    assert _chi2_p(idx, w / w.sum()) > 1e-4
    # Negative control: the same samples against a slightly different pmf are rejected.
    wrong = w.copy()
    wrong[: n // 2] *= 1.2
    assert _chi2_p(idx, wrong / wrong.sum()) < 1e-6
    # Edge of the unit interval.
    assert 0 <= table.sample(np.array([0.0, np.nextafter(1.0, 0.0)])).max() < n


def test_discrete_chooser_small_and_large_agree_in_distribution():
    rng = np.random.default_rng(3)
    for w in (np.array([1.0, 2.0, 0.0, 5.0]), rng.random(50)):
        ch = DiscreteChooser(w)
        assert (ch.alias is None) == (len(w) <= 8)
        assert _chi2_p(ch.sample(rng.random(200_000)), w / w.sum()) > 1e-4


def test_families_group_materials_that_differ_in_constants_only():
    bsdfs = [Diffuse([0.7, 0.1, 0.1]), RoughSubstrate(0.2, 0.3), Diffuse(0.5), RoughSubstrate([0.1, 0.2, 0.3], 0.01),
             RoughSubstrate(0.2, 0.3, intIOR=1.33), Diffuse(CheckerTexture()), RoughConductor(0.9, 0.1)]
    fams = BSDFFamilies.build(bsdfs, np.arange(len(bsdfs)))
    f = fams.mesh_family
    assert f[0] == f[2] and f[1] == f[3]  # same class, same IORs
    assert len({f[1], f[4]}) == 2  # other IOR
    assert f[5] not in (f[0], f[1], f[4], f[6])  # a textured material is on its own
    assert len(fams.families) == 5


@pytest.mark.parametrize("kind", ["diffuse", "roughsubstrate", "roughconductor"])
def test_family_evaluation_matches_each_member(kind):
    rng = np.random.default_rng(7)
    make = {"diffuse": lambda k: Diffuse(rng.random(3)),
            "roughsubstrate": lambda k: RoughSubstrate(rng.random(3), [0.3, 0.05, 0.001][k]),
            "roughconductor": lambda k: RoughConductor(rng.random(3), [0.3, 0.05, 0.001][k])}[kind]
    members = [make(k) for k in range(3)]
    fams = BSDFFamilies.build(members, np.arange(3))
    assert len(fams.families) == 1
    n = 3000
    member = rng.integers(0, 3, n)
    wi = rng.normal(size=(n, 3))
    wi /= np.linalg.norm(wi, axis=1)[:, None]
    wi[:, 2] = np.abs(wi[:, 2])
    u = rng.random((n, 3))
    bound = fams.families[0].bind(member)
    fused = bound.sample(wi, u)
    f_fused, p_fused = bound.eval_pdf(wi, fused.wo)
    for k, m in enumerate(members):
        sel = member == k
        alone = m.sample(wi[sel], u[sel])
        np.testing.assert_array_equal(fused.wo[sel], alone.wo)
        np.testing.assert_array_equal(fused.weight[sel], alone.weight)
        np.testing.assert_array_equal(fused.pdf[sel], alone.pdf)
        np.testing.assert_array_equal(f_fused[sel], m.eval(wi[sel], fused.wo[sel]))
        np.testing.assert_array_equal(p_fused[sel], m.pdf(wi[sel], fused.wo[sel]))


@pytest.mark.parametrize("fork", [True, False])
def test_parallel_workers_match_one_worker_and_count_rays(fork, monkeypatch):
    import brdflab.renderer

    monkeypatch.setattr(brdflab.renderer, "FORK_WORKERS", fork)  # False: the thread pool used off Linux
    s = load_scene(ROOT / "scenes/veach/veach_mis.xml")
    s.camera.width, s.camera.height = 96, 64
    a, sa = render(s, spp=8, seed=2, workers=1)
    b, sb = render(s, spp=8, seed=2, workers=2)
    np.testing.assert_array_equal(a, b)
    assert sa.rays == sb.rays > 0
    assert sb.ray_seconds > 0


def test_distribution2d_alias_sampling_is_uniform_within_cells():
    from brdflab.math.distribution import Distribution2D

    rng = np.random.default_rng(11)
    w = rng.random((6, 10)) ** 2
    w[2, 3] = 0.0
    dist = Distribution2D(w)
    pts, dens = dist.sample(rng.random((600_000, 2)))
    assert np.all((pts[:, 0] >= 0) & (pts[:, 0] < 10) & (pts[:, 1] >= 0) & (pts[:, 1] < 6))
    np.testing.assert_allclose(dens, dist.pdf(pts))
    # 4 × 4 sub-bins per cell: the density is constant inside a cell, so each sub-bin expects 1/16 of it.
    sub = 4
    bins = (np.floor(pts[:, 1] * sub).astype(int) * (10 * sub) + np.floor(pts[:, 0] * sub).astype(int))
    expected = np.repeat(np.repeat(dist.density, sub, axis=0), sub, axis=1).ravel() / sub**2
    assert _chi2_p(bins, expected) > 1e-4
    # Negative control: a density that is not uniform inside the cells (a ramp in x) is rejected.
    ramp = np.tile(np.linspace(0.7, 1.3, sub), 6 * 10 * sub)
    wrong = expected * ramp
    assert _chi2_p(bins, wrong / wrong.sum()) < 1e-6


def _quad_light_scene(tmp_path, corners: str):
    obj = tmp_path / "light.obj"
    obj.write_text(corners + "f 1 3 2\nf 1 4 3\n")
    floor = tmp_path / "floor.obj"
    floor.write_text("v -5 0 -5\nv 5 0 -5\nv 5 0 5\nv -5 0 5\nf 1 3 2\nf 1 4 3\n")
    xml = tmp_path / "s.xml"
    xml.write_text(f"""<scene><integrator type="direct_ems"/>
<camera type="perspective"><integer name="width" value="8"/><integer name="height" value="8"/>
<transform name="toWorld"><lookat origin="0,3,3" target="0,0,0" up="0,1,0"/></transform></camera>
<mesh type="obj"><string name="filename" value="{floor}"/><bsdf type="diffuse"/></mesh>
<mesh type="obj"><string name="filename" value="{obj}"/>
<emitter type="area"><color name="radiance" value="1,1,1"/></emitter></mesh></scene>""")
    return load_scene(xml)


def test_parallelogram_light_samples_uniformly_by_area(tmp_path):
    """A quad light made of two triangles is sampled as one parallelogram: the points are uniform over it
    (chi-square on a grid of its own coordinates, 8 × 8 cells), the pdf is ‖y − x‖²/(A cos θ_l), as for
    the triangle path, and a warp that is not uniform is rejected."""
    # A sheared, tilted parallelogram facing down (−y), wound so that its normal points at the floor.
    s = _quad_light_scene(tmp_path, "v -1 2 -1\nv -0.5 2.2 1\nv 1.5 2.2 1\nv 1 2 -1\n")
    em = s.emitters[0]
    assert em._quad is not None and em._normal[1] < 0
    c, e1, e2 = em._quad
    assert np.linalg.norm(np.cross(e1, e2)) == pytest.approx(em.area)
    rng = np.random.default_rng(4)
    n = 200_000
    ref = np.column_stack([rng.uniform(-2, 2, n), np.zeros(n), rng.uniform(-2, 2, n)])
    r = em.sample(ref, rng.random((n, 3)))
    y = ref + r.wi * r.dist[:, None]
    # Coordinates in the (e1, e2) basis (least squares: the points lie in the plane).
    st = np.linalg.lstsq(np.column_stack([e1, e2]), (y - c).T, rcond=None)[0].T
    assert np.all((st > -1e-9) & (st < 1 + 1e-9))
    cells = np.minimum((st * 8).astype(int), 7)
    bins = cells[:, 0] * 8 + cells[:, 1]
    assert _chi2_p(bins, np.full(64, 1 / 64)) > 1e-4
    cos_l = -(r.wi @ em._normal)
    np.testing.assert_allclose(r.pdf, r.dist**2 / (em.area * cos_l), rtol=1e-12)
    # The triangle path gives the same density at its own points.
    em._quad = None
    rt = em.sample(ref, rng.random((n, 3)))
    np.testing.assert_allclose(rt.pdf, rt.dist**2 / (em.area * -(rt.wi @ em._normal)), rtol=1e-12)
    # Negative control: points crowded toward one edge (ξ1² instead of ξ1) are rejected.
    bad = np.minimum((np.column_stack([st[:, 0] ** 2, st[:, 1]]) * 8).astype(int), 7)
    assert _chi2_p(bad[:, 0] * 8 + bad[:, 1], np.full(64, 1 / 64)) < 1e-6


def test_parallelogram_detection(tmp_path):
    # A trapezoid (two triangles sharing an edge, but not a parallelogram) keeps the triangle path.
    s = _quad_light_scene(tmp_path, "v -1 2 -1\nv -0.5 2 1\nv 0.5 2 1\nv 1 2 -1\n")
    assert s.emitters[0]._quad is None
    assert load_scene(ROOT / "scenes/cbox/cbox_spheres.xml").emitters[0]._quad is not None


def test_mirrored_lights_sample_without_normal_interpolation(tmp_path):
    """Lights mirrored by their toWorld (the course table scene: ``scale 0.06,0.06,-1``) have vertex
    normals that oppose their winding normal. They keep one normal per triangle (a quad light is sampled as
    a parallelogram facing down), and two of them fused into one light set give, bit for bit, the samples
    of the generic path that interpolates the vertex normals."""
    import copy

    from brdflab.emitter.area import AreaLightSet

    light = tmp_path / "light.obj"
    light.write_text("v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nvn 0 1 0\nf 1//1 3//1 2//1\nf 1//1 4//1 3//1\n")
    floor = tmp_path / "floor.obj"
    floor.write_text("v -5 0 -5\nv 5 0 -5\nv 5 0 5\nv -5 0 5\nf 1 3 2\nf 1 4 3\n")
    lights = "".join(f"""<mesh type="obj"><string name="filename" value="{light}"/>
<transform name="toWorld"><scale value="{sc},-1,{sc}"/><translate value="{x},2,0"/></transform>
<emitter type="area"><color name="radiance" value="1,1,1"/></emitter></mesh>""" for sc, x in ((0.5, -1), (0.3, 1.5)))
    xml = tmp_path / "s.xml"
    xml.write_text(f"""<scene><integrator type="direct_ems"/>
<camera type="perspective"><integer name="width" value="8"/><integer name="height" value="8"/>
<transform name="toWorld"><lookat origin="0,3,3" target="0,0,0" up="0,1,0"/></transform></camera>
<mesh type="obj"><string name="filename" value="{floor}"/><bsdf type="diffuse"/></mesh>{lights}</scene>""")
    s = load_scene(xml)
    g = s.geometry
    for em in s.emitters:
        assert em._nrm is None and em._quad is not None
        assert em._normal[1] == -1.0  # the vn lines (mirrored: pointing down), not the winding normal (up)
        assert np.all(g.face_normals[em.tris][:, 1] > 0)
    generic = []
    for em in s.emitters:
        e = copy.copy(em)
        e._face_n, e._nrm = g.face_normals[em.tris], g.tri_nrm[:, em.tris]
        generic.append(e)
    rng = np.random.default_rng(23)
    ref = np.asfortranarray(np.column_stack([rng.uniform(-3, 3, 4096), np.zeros(4096), rng.uniform(-3, 3, 4096)]))
    u = rng.random((4096, 3))
    fast = AreaLightSet(s.emitters, s.emitter_pmf).sample(ref, u)
    slow = AreaLightSet(generic, s.emitter_pmf).sample(ref, u)
    assert fast.pdf.max() > 0  # the floor below sees the lights' emitting side
    for a, b in zip(fast, slow, strict=True):
        np.testing.assert_array_equal(a, b)


def test_shading_points_skip_interpolation_only_where_normals_are_flat():
    """Meshes whose vertex normals are their face normals (the Cornell box walls are written with vn lines)
    shade with the face normal without interpolating; the bent wall and the spheres interpolate. The
    shading points match fully reconstructed hits either way."""
    from brdflab.integrator.common import trace_camera

    s = load_scene(ROOT / "scenes/cbox/cbox_spheres.xml", "direct_ems")
    g = s.geometry
    assert g.mesh_smooth.any() and not g.mesh_smooth.all()
    cam = s.camera
    ys, xs = np.mgrid[0:cam.height:4, 0:cam.width:4] + 0.5
    o, d, tmax = cam.generate_rays(xs.ravel(), ys.ravel())
    _, sp = trace_camera(s, o, d, tmax)
    full = g.intersect(o, d, tmax)
    np.testing.assert_allclose(sp.ns, full.ns[sp.index], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(sp.p, full.p[sp.index])
    # Both kinds occur, and the smooth meshes' normals do vary over a triangle.
    smooth = g.mesh_smooth[full.mesh[sp.index]]
    assert smooth.any() and not smooth.all()
    tri_n = g.face_normals[full.prim[sp.index]]
    assert np.abs(sp.ns - tri_n)[smooth].max() > 1e-3
    assert np.abs(sp.ns - tri_n)[~smooth].max() < 1e-12


@pytest.mark.parametrize("n_codes", [1, 3, 12])
def test_sort_by_code_groups_stably(n_codes):
    """Both paths of sort_by_code (comparisons for ≤ 8 codes, radix argsort beyond) return the entries with
    code ≥ 0 grouped by code, in ascending index order within a group, with the right slices."""
    from brdflab.integrator.common import sort_by_code

    rng = np.random.default_rng(n_codes)
    codes = sorted(rng.choice(40, n_codes, replace=False).tolist())
    code = rng.choice(codes + [-1, -2], 5000)
    order, runs = sort_by_code(code, codes)
    keep = np.flatnonzero(code >= 0)
    np.testing.assert_array_equal(order, keep[np.argsort(code[keep], kind="stable")])
    assert [c for c, _ in runs] == sorted(set(code[keep].tolist()))
    for c, sl in runs:
        assert np.all(code[order[sl]] == c)
    assert runs[-1][1].stop == len(keep)


def test_stopped_parallel_render_equals_a_render_of_its_completed_passes():
    """A render stopped midway by 2 forked workers (tile films through shared-memory slots, 8 units per
    task) keeps exactly its completed passes: the image equals an uninterrupted one-worker render of that
    many samples, bit for bit."""
    import threading

    s = load_scene(ROOT / "scenes/veach/veach_mis.xml")
    s.camera.width, s.camera.height = 96, 64
    stop = threading.Event()

    def progress(frac, stats):
        if frac >= 0.5:
            stop.set()

    img, st = render(s, spp=192, seed=4, workers=2, progress=progress, stop=stop)
    assert st.spp in (64, 128)
    ref, _ = render(s, spp=st.spp, seed=4, workers=1)
    np.testing.assert_array_equal(img, ref)
