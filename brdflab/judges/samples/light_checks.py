"""The checks of users' light samples (the file format and the verdict rules are in
:mod:`brdflab.judges.samples.light_samples`): the light under test, points on it, the method-agnostic self-consistency
of the points against their own pdf, and the comparisons with brdflab's own method (pdf, distribution, radiance)
with the hints that name the usual bugs.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from brdflab.errors import BrdflabError
from brdflab.judges.core.precision import rounding_variance
from brdflab.judges.lights.samplers import SUB, emitter_triangles, shading_normals, subtriangle_cell
from brdflab.judges.material import chi2 as c2
from brdflab.judges.samples.bsdf_checks import COLUMN_FRACTION, COLUMN_RTOL, _ratio_hint

#: A point is on the light when its distance to the nearest triangle is at most this × the light's size.
ON_RTOL = 1e-4


#: Fewest points on the light for a chi-square test (fewer: the test fails, no data is not a pass).
MIN_SAMPLES = 100


#: Points per bin of the self-consistency test (consecutive cells of one emitter pooled).
POOL = 100


#: Normals agree when their dot product is at least this (≈ 2.6°).
NORMAL_DOT = 0.999


@dataclass
class EmitterSamples:
    """Columns of an emitter-samples file (see module docstring)."""

    path: str
    x: np.ndarray
    y: np.ndarray
    n: np.ndarray
    pdf: np.ndarray
    solid_angle: np.ndarray
    """(N,) True where the pdf is per steradian (measure 1), False per unit area (0)."""
    radiance: np.ndarray | None
    lines: np.ndarray


@dataclass
class Check:
    """One of the checks (module docstring): passed, a one-line summary and a hint."""

    name: str
    passed: bool
    summary: str
    hint: str = ""
    data: dict = field(default_factory=dict)


class _Light:
    """The triangles (and point lights) of the emitters under test, with their selection probabilities."""

    def __init__(self, scene, index: int | None):
        if not scene.emitters:
            raise BrdflabError("the scene has no emitter")
        if index is not None and not 0 <= index < len(scene.emitters):
            raise BrdflabError(f"emitter index {index} out of range: the scene has {len(scene.emitters)} "
                               f"emitter(s), 0 … {len(scene.emitters) - 1}")
        ids = list(range(len(scene.emitters))) if index is None else [index]
        pmf = np.asarray(scene.emitter_pmf, float) if index is None else np.ones(1)
        self.ids, self.p_sel = ids, (pmf if index is None else np.ones(1))
        self.emitters = [scene.emitters[i] for i in ids]
        for i, e in zip(ids, self.emitters, strict=True):
            if e.is_environment:
                raise BrdflabError(f"emitter {i} is an environment map: --against-emitter checks area and "
                                   "point lights (test environment sampling with 'brdflab validate')")
        tris, owner, local, areas = [], [], [], []
        for j, e in enumerate(self.emitters):
            if e.is_delta:
                continue
            t = emitter_triangles(e)
            tris.append(t)
            owner.append(np.full(len(t), j))
            local.append(np.arange(len(t)))
            areas.append(e.geometry.tri_area[e.tris])
        self.tris = np.concatenate(tris) if tris else np.zeros((0, 3, 3))
        self.owner = np.concatenate(owner) if owner else np.zeros(0, int)
        self.local = np.concatenate(local) if local else np.zeros(0, int)
        self.tri_area = np.concatenate(areas) if areas else np.zeros(0)
        self.area = np.array([getattr(e, "area", 0.0) for e in self.emitters])
        pts = [e.position for e in self.emitters if e.is_delta]
        ext = np.concatenate([self.tris.reshape(-1, 3), np.array(pts).reshape(-1, 3)])
        self.size = float(np.linalg.norm(ext.max(0) - ext.min(0))) or 1.0
        # Probability of each triangle (and point light) under brdflab's sampling: p_sel · A_k / A_e.
        self.tri_prob = np.array([self.p_sel[o] * a / self.area[o] for o, a in zip(self.owner, self.tri_area,
                                                                                   strict=True)])

    def label(self, j: int) -> str:
        e = self.emitters[j]
        return f"{getattr(e, 'type_name', '') or type(e).__name__} #{self.ids[j]}"


def nearest_triangle(y: np.ndarray, tris: np.ndarray, candidates: int = 12, far: float = np.inf
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nearest of ``tris`` (K, 3, 3) to each point ``y`` (N, 3): index, exact point–triangle distance and
    the barycentrics (b1, b2) of the point's projection clamped into the triangle. The triangles with the
    nearest centroids are tried first; points farther than ``far`` from all of them try every triangle."""
    from scipy.spatial import cKDTree

    p0 = tris[:, 0]
    e1, e2 = tris[:, 1] - p0, tris[:, 2] - p0
    g11, g12, g22 = np.sum(e1 * e1, 1), np.sum(e1 * e2, 1), np.sum(e2 * e2, 1)
    det = np.where(g11 * g22 - g12 * g12 > 0, g11 * g22 - g12 * g12, 1.0)

    def seg(p, a, b):  # distance of p (n, c, 3) to segments a→b (n, c, 3)
        ab = b - a
        t = np.clip(np.sum((p - a) * ab, -1) / np.maximum(np.sum(ab * ab, -1), 1e-300), 0.0, 1.0)
        return np.linalg.norm(p - a - t[..., None] * ab, axis=-1)

    def test(pts, cand):
        d = pts[:, None, :] - p0[cand]
        r1, r2 = np.sum(d * e1[cand], 2), np.sum(d * e2[cand], 2)
        b1 = (g22[cand] * r1 - g12[cand] * r2) / det[cand]
        b2 = (g11[cand] * r2 - g12[cand] * r1) / det[cand]
        inside = (b1 >= 0) & (b2 >= 0) & (b1 + b2 <= 1)
        proj = p0[cand] + b1[..., None] * e1[cand] + b2[..., None] * e2[cand]
        q = pts[:, None, :]
        t = tris[cand]
        edge = np.minimum(np.minimum(seg(q, t[..., 0, :], t[..., 1, :]), seg(q, t[..., 1, :], t[..., 2, :])),
                          seg(q, t[..., 2, :], t[..., 0, :]))
        dist = np.where(inside, np.linalg.norm(q - proj, axis=-1), edge)
        j = np.argmin(dist, axis=1)
        rows = np.arange(len(j))
        bb = np.stack([b1[rows, j], b2[rows, j]], 1)
        bb = np.clip(bb, 0.0, 1.0)
        s = bb.sum(1)
        bb = np.where((s > 1)[:, None], bb / np.maximum(s, 1e-300)[:, None], bb)
        return cand[rows, j], dist[rows, j], bb

    c = min(candidates, len(tris))
    _, cand = cKDTree(tris.mean(axis=1)).query(y, k=c)
    k, dist, b = test(y, np.asarray(cand).reshape(len(y), c))
    miss = np.flatnonzero(dist > far) if c < len(tris) else np.zeros(0, int)
    for s in range(0, len(miss), 256):
        sel = miss[s:s + 256]
        k[sel], dist[sel], b[sel] = test(y[sel], np.broadcast_to(np.arange(len(tris)), (len(sel), len(tris))))
    return k, dist, b


def _pearson(obs: np.ndarray, exp: np.ndarray) -> tuple[float, int, float]:
    return c2.pearson(np.asarray(obs, float), np.asarray(exp, float))


def _vertex_planes(light: _Light) -> tuple[np.ndarray, np.ndarray]:
    """Per vertex slot v and triangle: brdflab's shading normal n there (vertex normals where the mesh has them,
    else the face normal), (3, T, 3), and p·n, (3, T): x faces the vertex when x·n > p·n."""
    t = len(light.tris)
    nv = np.zeros((3, t, 3))
    corners = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])  # barycentrics (b1, b2) of the three vertices
    for j, e in enumerate(light.emitters):
        mine = np.flatnonzero(light.owner == j)
        for v in range(3):
            nv[v, mine] = shading_normals(e, light.local[mine], np.repeat(corners[v:v + 1], len(mine), axis=0))
    return nv, np.einsum("vtk,vtk->vt", light.tris.transpose(1, 0, 2), nv)


def _facing_counts(planes, xs: np.ndarray) -> np.ndarray:
    """How many of the points ``xs`` each triangle faces at all three vertices (T,), in chunks of about 4 M
    (point, triangle) pairs: no table of that size is ever held."""
    nv, dv = planes
    counts = np.zeros(nv.shape[1], np.int64)
    step = max(1, (1 << 22) // max(nv.shape[1], 1))
    for a in range(0, len(xs), step):
        x = xs[a:a + step]
        ok = (x @ nv[0].T) > dv[0]
        for v in (1, 2):
            ok &= (x @ nv[v].T) > dv[v]
        counts += ok.sum(axis=0)
    return counts


def _faces(planes, xs: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Whether triangle ``tri[i]`` faces point ``xs[i]`` at all three vertices (the test of :func:`_facing_counts`)."""
    nv, dv = planes
    ok = np.ones(len(xs), bool)
    for v in range(3):
        ok &= np.einsum("rk,rk->r", xs, nv[v, tri]) > dv[v, tri]
    return ok


def _self_consistency_check(s: EmitterSamples, light: _Light, owner, tri, bary, ns, on,
                            threshold: float) -> Check | None:
    """The light points against *their own* pdf, whatever method drew them (the verdict on area lights).

    For any sampler, a call yielding y with area density p_A(y) (the file's pdf, converted from solid angle by
    p_A = p_ω |cos θ_y| / r², selection probability included) gives an unbiased estimate 1_c(y)/p_A(y) of a
    cell's area a_c, for every cell c (n² congruent sub-triangles of each light triangle); averaged over the N
    calls (also those that produced no point) Ŝ_c estimates a_c. Rows in solid-angle measure carry no density
    where the light faces away from their x (one-sided lights: p_ω is 0 or infinite there), so a solid-angle row
    counts only on the triangles its x sees the front of at all three vertices (shading normals), in Ŝ_c and,
    equally, in its expectation: E[Ŝ_c] = a_c · (fraction of rows that count c; area-measure rows always).
    Consecutive cells of one emitter are pooled into bins of ≥ :data:`POOL` points (a mean of a few 1/p terms
    is not normal); per bin z = (Ŝ − E)/σ̂ with σ̂² estimated from the same samples, and the same for the sum;
    all are tested at the family-wise level by Šidák's correction (two-sided Student-t tails with the bin's
    points − 1 degrees of freedom; normal for the sum). A cell that holds
    no sample while the file's own density elsewhere implies ≥ ln(cells/level) there fails (the sampler leaves
    light out). Point lights have no area and are not tested here.
    """
    from scipy import stats

    area = on & (tri >= 0)
    n_calls = len(s.pdf)
    if not area.any() or not len(light.tris):
        return None
    solid = s.solid_angle
    rows = np.flatnonzero(area)
    t_r = tri[rows]
    # solid-angle rows count where their x sees the whole triangle's front (elsewhere p_ω may be 0 or infinite)
    planes = _vertex_planes(light)
    faced = _facing_counts(planes, s.x[solid])
    use = ~solid[rows]
    sol = solid[rows]
    use[sol] = _faces(planes, s.x[rows][sol], t_r[sol])
    v = s.x[rows] - s.y[rows]
    r2 = np.sum(v * v, axis=1)
    cos = np.sum(ns[rows] * v, axis=1) / np.sqrt(np.where(r2 > 0, r2, 1.0))
    m = int(use.sum())
    if m < MIN_SAMPLES:
        return Check("self-consistency", False, f"only {m} usable points on area lights: at least {MIN_SAMPLES} "
                     "are needed (no data is not a pass)")
    pdf = s.pdf[rows]
    with np.errstate(divide="ignore", invalid="ignore"):
        p_a = np.where(solid[rows], pdf * np.abs(cos) / r2, pdf)
    good = np.isfinite(p_a) & (p_a > 0)
    bad = use & ~good
    use &= good
    sub = int(np.clip(np.floor(np.sqrt(m / (20.0 * len(light.tris)))), 1, SUB))
    cells = sub * sub
    n_cells = len(light.tris) * cells
    cid = t_r * cells + subtriangle_cell(bary[rows], sub)
    inv = np.where(use, 1.0 / np.where(good, p_a, 1.0), 0.0)
    s1 = np.bincount(cid, inv, minlength=n_cells) / n_calls
    s2 = np.bincount(cid, inv * inv, minlength=n_cells) / n_calls
    # E_c: the fraction of calls whose row counts c (area rows always; solid-angle rows where x sees c's front)
    seen = (np.count_nonzero(~solid) + faced) / n_calls
    expect = np.repeat(light.tri_area * seen / cells, cells)
    hits = np.bincount(cid[use], minlength=n_cells)
    density = hits.sum() / max(float(expect.sum()), 1e-300)
    # an empty cell is evidence only where the file's own density implies so many points that none at all has
    # probability e^(−λ) below the family's share of the level: λ ≥ ln(cells / level)
    missing = (hits == 0) & (expect * density >= np.log(max(n_cells, 1) / threshold))
    bin_of = _pool(hits, np.repeat(light.owner, cells))
    n_bins = int(bin_of.max()) + 1
    s1 = np.bincount(bin_of, s1, minlength=n_bins)
    s2 = np.bincount(bin_of, s2, minlength=n_bins)
    expect_b = np.bincount(bin_of, expect, minlength=n_bins)
    hits_b = np.bincount(bin_of, hits, minlength=n_bins)
    # sample variances + the rounding floor of float32 pdf columns (judges.core.precision): rounding is no bug
    var = np.maximum(s2 - s1 * s1, 0.0) / n_calls + rounding_variance(expect_b)
    total_s, total_e = float(s1.sum()), float(expect_b.sum())
    var_total = max((float(np.sum(inv * inv)) / n_calls - total_s ** 2) / n_calls, 0.0) + rounding_variance(total_e)
    tested_b = (hits_b >= POOL // 2) & (var > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(tested_b, (s1 - expect_b) / np.sqrt(np.where(var > 0, var, 1.0)), 0.0)
        z_total = (total_s - total_e) / np.sqrt(var_total) if var_total > 0 else 0.0
    tested = int(tested_b.sum()) + 1
    # Student's t with (points − 1) degrees of freedom: σ̂ is estimated from the bin's own points
    p_cells = (2 * stats.t.sf(np.abs(z[tested_b]), np.maximum(hits_b[tested_b] - 1, 1)) if tested_b.any()
               else np.ones(1))
    p_min = float(min(p_cells.min(), 2 * stats.norm.sf(abs(z_total))))
    p_family = float(-np.expm1(tested * np.log1p(-min(p_min, 1.0 - 1e-16))))  # 1 − (1 − p_min)^tested
    ok = bool(p_family >= threshold and not missing.any() and not bad.any())
    summary = (f"Σ 1/p_A = {total_s:.4g} for the expected {total_e:.4g} (z = {z_total:+.2f}); {tested - 1} bins "
               f"of ≥ {POOL // 2} points ({sub}² cells per triangle), largest |z| = {float(np.max(np.abs(z))):.2f}; "
               f"family p = {p_family:.3g} (threshold {threshold:g})")
    hint = ""
    if bad.any():
        summary += f"; {int(bad.sum())} front-facing points with pdf ≤ 0 or not finite"
        hint = "a point on the light was returned with a zero or invalid pdf"
    elif missing.any():
        lam = np.log(max(n_cells, 1) / threshold)
        summary += f"; {int(missing.sum())} cells never sampled where the others imply ≥ {lam:.0f} samples each"
        hint = "part of the light is never sampled: the sampler must reach every point of the light"
    elif not ok:
        hint = (f"the pdf column does not describe where the points are (Σ 1/p_A is {total_s / total_e:.3g}× what "
                "it should be: a missing or extra factor, or points denser than the pdf says somewhere)")
    return Check("self-consistency", ok, summary, hint, {"p": p_family, "ratio": total_s / total_e})


def _pool(hits: np.ndarray, owner: np.ndarray) -> np.ndarray:
    """Bins of consecutive cells of one emitter, each closed once it holds :data:`POOL` points (a mean of a few
    1/p terms is not normal; an emitter's last bin may hold fewer and is then not tested). One pass over the
    cells (about N/20 of them, once per file): bins of at least POOL points keep the false alarms at the
    nominal level (0.8 % at 1 %, where fixed-width cuts of the running count gave 1.8 %)."""
    bin_of = np.zeros(len(hits), np.int64)
    b, acc = 0, 0
    for c in range(len(hits)):
        if c and (owner[c] != owner[c - 1] or acc >= POOL):
            b, acc = b + 1, 0
        bin_of[c] = b
        acc += hits[c]
    return bin_of


def _geometry(s: EmitterSamples, ns: np.ndarray, sel: np.ndarray):
    """r, r² and cos θ_y (brdflab's normal, toward x) of the samples ``sel``."""
    v = s.x[sel] - s.y[sel]
    r2 = np.sum(v * v, axis=1)
    r = np.sqrt(r2)
    cos = np.sum(ns[sel] * v, axis=1) / np.where(r > 0, r, 1.0)
    return r, r2, cos


def _pdf_check(s: EmitterSamples, light: _Light, owner, tri, ns, on) -> Check:
    area = on & (tri >= 0)
    _, r2, cos = _geometry(s, ns, area)
    o = owner[area]
    p_sel = light.p_sel[o]
    p_a = p_sel / light.area[o]
    with np.errstate(divide="ignore", invalid="ignore"):
        p_w = p_a * r2 / np.abs(cos)
    solid = s.solid_angle[area]
    ours = np.where(solid, p_w, p_a)
    fv = s.pdf[area]
    front = cos > 1e-6
    cmp_ = front & np.isfinite(ours) & (ours > 0)
    # Points on a point light: a discrete choice, whose probability is the selection's p_sel (either measure).
    point = on & (tri < 0)
    if cmp_.sum() + point.sum() == 0:
        return Check("pdf", False, "no front-facing sample on an area light and none on a point light to compare "
                     "(no data is not a pass)")
    f = np.concatenate([fv[cmp_], s.pdf[point]])
    ob = np.concatenate([ours[cmp_], light.p_sel[owner[point]]])
    units = np.concatenate([np.where(solid[cmp_], "per sr", "per unit area"), np.full(int(point.sum()), "discrete")])
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.abs(f - ob) / np.maximum(np.maximum(f, ob), 1e-300)
    frac = float((rel > COLUMN_RTOL).mean())
    ok = frac <= COLUMN_FRACTION
    i = int(np.argmax(rel))
    lines = np.concatenate([s.lines[area][cmp_], s.lines[point]])
    what = " and ".join(w for w, k in (("front-facing samples on area lights", cmp_.sum()),
                                        ("samples of point lights", point.sum())) if k)
    summary = (f"{len(f)} {what} compared: {100 * frac:.2f} % differ by more than "
               f"{100 * COLUMN_RTOL:g} % (worst line {int(lines[i])}: file {f[i]:.6g}, brdflab {ob[i]:.6g} "
               f"{units[i]})")
    hint = ""
    f, ob = f[: int(cmp_.sum())], ob[: int(cmp_.sum())]  # the hints below explain area-light pdfs
    if not ok and not len(f):
        hint = "a point light's pdf is the probability of choosing it (1 for a single light), in either measure"
    elif not ok:
        c, rr2, sol = np.abs(cos[cmp_]), r2[cmp_], solid[cmp_]
        ps = p_sel[cmp_]
        tri_a = light.tri_area[tri[area][cmp_]]
        ea = light.area[o[cmp_]]
        kk = np.bincount(light.owner, minlength=len(light.emitters))[o[cmp_]]  # triangles per emitter
        one = np.ones_like(c)
        base = [("the pdf is in area measure but flagged as solid angle (missing r²/|cos θ_y|: p_ω = p_A·r²/|cos θ_y|)",
                 np.where(sol, c / rr2, np.nan)),
                ("the pdf is in solid-angle measure but flagged as area (set the measure column to 1)",
                 np.where(sol, np.nan, rr2 / c)),
                ("a missing |cos θ_y| in p_ω = p_A·r²/|cos θ_y|", np.where(sol, c, np.nan)),
                ("a missing r² in p_ω = p_A·r²/|cos θ_y|", np.where(sol, 1.0 / rr2, np.nan)),
                ("a missing emitter-selection probability (p = p_sel · p_emitter)",
                 np.where(ps < 1, 1.0 / ps, np.nan)),
                ("the emitter-selection probability applied twice", np.where(ps < 1, ps, np.nan)),
                ("the pdf of the chosen triangle (1/A_k) instead of the emitter's (1/A)", ea / tri_a),
                ("triangles chosen uniformly (pdf 1/(K·A_k)) instead of by area (1/A)",
                 np.where(kk > 1, ea / (kk * tri_a), np.nan))]
        cands = [(t, v) for t, v in base if np.isfinite(v).any() and not np.allclose(v[np.isfinite(v)], 1.0)]
        pairs = [(f"{a} and {b}", va * vb) for i1, (a, va) in enumerate(cands) for b, vb in cands[i1 + 1:]]
        with np.errstate(divide="ignore", invalid="ignore"):
            hint = _ratio_hint(f / ob, cands + pairs + [("", one)])
    return Check("pdf", ok, summary, hint, {"compared": int(cmp_.sum()), "fraction_off": frac})


def _distribution_check(s: EmitterSamples, light: _Light, owner, tri, bary, on, threshold: float) -> Check:
    m = int(on.sum())
    n_tri = len(light.tris)
    deltas = [j for j, e in enumerate(light.emitters) if e.is_delta]
    if m < MIN_SAMPLES:
        return Check("distribution", False, f"only {m} points on the light: at least {MIN_SAMPLES} are needed for "
                     "a chi-square test (no data is not a pass)")
    sub = int(np.clip(np.floor(np.sqrt(m / (20.0 * max(n_tri, 1)))), 1, SUB)) if n_tri else 1
    cells = sub * sub
    area_on = on & (tri >= 0)
    obs = np.zeros(n_tri * cells + len(deltas))
    if n_tri:
        np.add.at(obs, tri[area_on] * cells + subtriangle_cell(bary[area_on], sub), 1.0)
    for i, j in enumerate(deltas):
        obs[n_tri * cells + i] = np.count_nonzero(on & (owner == j))
    prob = np.concatenate([np.repeat(light.tri_prob / cells, cells), light.p_sel[deltas]])
    if len(obs) == 1 and deltas:  # one point light: all its points are the point itself (checked above)
        return Check("distribution", True, f"{m} points on a single point light: one cell, nothing to distribute "
                     "(the points' position is the check 'points on the emitter')")
    exp = prob / prob.sum() * m
    stat, dof, p = _pearson(obs, exp)
    ok = bool(np.isfinite(p) and p >= threshold)
    summary = (f"{m} points in {len(obs)} cells ({sub}² per triangle): X² = {stat:.1f}, {dof} dof, p = {p:.3g} "
               f"(threshold {threshold:g})")
    hints = []
    if not ok:
        j_obs = np.bincount(owner[on], minlength=len(light.emitters)).astype(float)
        if len(light.emitters) > 1:
            _, _, pe = _pearson(j_obs, light.p_sel * m)
            if np.isfinite(pe) and pe < threshold:
                freq = ", ".join(f"{light.label(j)} {j_obs[j] / m:.3f} (scene: {light.p_sel[j]:.3f})"
                                 for j in range(len(light.emitters)))
                hints.append(f"emitters chosen with other frequencies than the scene's selection: {freq}")
        t_obs = np.bincount(tri[area_on], minlength=n_tri).astype(float) if n_tri else np.zeros(0)
        for j in range(len(light.emitters)):
            mine = np.flatnonzero(light.owner == j)
            if len(mine) < 2 or t_obs[mine].sum() < MIN_SAMPLES:
                continue
            a = light.tri_area[mine]
            tot = t_obs[mine].sum()
            _, _, p_area = _pearson(t_obs[mine], a / a.sum() * tot)
            _, _, p_unif = _pearson(t_obs[mine], np.full(len(mine), tot / len(mine)))
            if np.isfinite(p_area) and p_area < threshold and np.isfinite(p_unif) and p_unif >= threshold:
                hints.append(f"{light.label(j)}: triangles are chosen uniformly, not by area (choose triangle k with "
                             "probability A_k/A, e.g. a discrete pdf over the areas)")
        if sub >= 2 and n_tri:
            exp_in = np.repeat(t_obs / cells, cells)
            _, _, p_in = _pearson(obs[:n_tri * cells], exp_in)
            if np.isfinite(p_in) and p_in < threshold:
                hints.append("points are not uniform within their triangles: check the square-to-triangle warp "
                             "(b = (1 − √u₁, u₂ √u₁))")
    return Check("distribution", ok, summary, "; ".join(hints), {"statistic": stat, "dof": dof, "p": p})


def _radiance_check(s: EmitterSamples, light: _Light, owner, ns, on) -> Check | None:
    ours = np.full((len(s.pdf), 3), np.nan)
    for j, e in enumerate(light.emitters):
        mine = np.flatnonzero(on & (owner == j))
        if not len(mine):
            continue
        if e.is_delta:
            r2 = np.sum((s.y[mine] - s.x[mine]) ** 2, axis=1)
            ours[mine] = e.intensity / r2[:, None]
        elif e.radiance.constant:
            _, _, cos = _geometry(s, ns, mine)
            ours[mine] = np.where((cos > 0)[:, None], e.radiance.value * e.scale, 0.0)
    sel = np.isfinite(ours).all(axis=1)
    if not sel.any():
        return None
    f, ob = s.radiance[sel], ours[sel]
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.where(f == ob, 0.0, np.abs(f - ob) / np.maximum(np.maximum(np.abs(f), np.abs(ob)), 1e-300))
    rel = rel.max(axis=1)
    frac = float((rel > COLUMN_RTOL).mean())
    ok = frac <= COLUMN_FRACTION
    hint = ""
    if not ok:
        back = (np.abs(ob).sum(axis=1) == 0)
        if back.any() and (rel[back] > COLUMN_RTOL).mean() > 0.5 and \
                (not (~back).any() or (rel[~back] > COLUMN_RTOL).mean() <= COLUMN_FRACTION):
            hint = "radiance returned for points seen from behind the light (area lights emit on their front side only)"
        elif np.any(s.pdf[sel] > 0):
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = (f / ob).mean(axis=1)
            hint = _ratio_hint(ratio, [("the radiance divided by the pdf (that is the sample's weight, not L_e)",
                                        1.0 / s.pdf[sel])])
    i = int(np.argmax(rel))
    return Check("radiance", ok, f"{int(sel.sum())} samples compared: {100 * frac:.2f} % differ by more than "
                 f"{100 * COLUMN_RTOL:g} % (worst line {int(s.lines[sel][i])})", hint)
