"""Emitter samplers: chi-square against their densities, and ``sample().pdf`` equal to the pdf of a hit.

* **Area lights** (any triangle mesh, the parallelogram fast path of quad lights, and the fused set of all
  area lights of a scene): the sampled points y = x + ω·d are located on the light's own triangles
  (barycentric coordinates, independent of the sampler's tables) and binned into the n² congruent
  sub-triangles of every triangle. The claimed density is uniform by area (p_sel·A_k/A_e per triangle for the
  fused set), so each cell expects N·P(triangle)/n²; Pearson's X² with pooling of cells below 5 expected
  counts (:func:`brdflab.judges.material.chi2.pearson`).
* **Environment maps**: directions against :meth:`EnvironmentEmitter.pdf` with the spherical binning and
  adaptive quadrature of :func:`brdflab.judges.material.chi2.chi2_test`.
* **pdf consistency**: for every emitter of a scene, light samples drawn from the scene's shading points
  are located on the light's triangles (with the light's shading normal there, from the geometry); the
  density the integrators use for a BSDF-sampled ray that reaches the same point (``pdf_hit``,
  ``eval_pdf_hit`` of the fused set, the environment's ``pdf``) must equal the sample's own pdf
  (relative error ≤ 1e-8). Point lights: pdf 1 and radiance I/r² exactly. A check with too few
  comparable samples fails (no data is not a pass).

Negative controls (:func:`negative_controls`): triangles chosen uniformly instead of by area, an
environment pdf without the sin θ Jacobian, and a hit pdf without the light's cosine must all be rejected.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from brdflab.judges.material import chi2 as c2
from brdflab.scene import BUNDLED_SCENES

SUB = 4
"""Sub-triangles per triangle edge at most (SUB² cells per triangle; fewer for large meshes, so that a cell
expects ≥ 20 samples)."""
PDF_RTOL = 1e-8
MIN_COMPARED = 200


@dataclass
class PdfCheck:
    """``sample().pdf`` against the hit/direction pdf for one emitter (or the fused set)."""

    name: str
    compared: int
    max_rel_error: float
    rtol: float = PDF_RTOL

    @property
    def passed(self) -> bool:
        """True when enough samples were compared and all agree."""
        return bool(self.compared >= MIN_COMPARED and self.max_rel_error <= self.rtol)


def _seed(*parts) -> int:
    return zlib.crc32(repr(parts).encode())


def locate_on_triangles(y: np.ndarray, tris: np.ndarray, candidates: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """Triangle index (−1 if none) and barycentrics (b1, b2) of points ``y`` (N, 3) on triangles ``tris``
    (K, 3, 3): among the triangles with the nearest centroids (k-d tree; all of them for the few points that
    are not found there), the one whose plane is nearest and that contains the projected point."""
    from scipy.spatial import cKDTree

    p0 = tris[:, 0]
    e1, e2 = tris[:, 1] - p0, tris[:, 2] - p0
    g11, g12, g22 = np.sum(e1 * e1, 1), np.sum(e1 * e2, 1), np.sum(e2 * e2, 1)
    det = g11 * g22 - g12 * g12
    nrm = np.cross(e1, e2)
    nrm /= np.linalg.norm(nrm, axis=1)[:, None]
    size = np.sqrt(np.maximum(g11, g22))

    def test(pts, cand):  # pts (n, 3), cand (n, c) triangle indices
        d = pts[:, None, :] - p0[cand]
        r1, r2 = np.sum(d * e1[cand], 2), np.sum(d * e2[cand], 2)
        b1 = (g22[cand] * r1 - g12[cand] * r2) / det[cand]
        b2 = (g11[cand] * r2 - g12[cand] * r1) / det[cand]
        off = np.abs(np.sum(d * nrm[cand], 2)) / size[cand]
        eps = 1e-7
        inside = (b1 >= -eps) & (b2 >= -eps) & (b1 + b2 <= 1 + eps) & (off < 1e-6)
        score = np.where(inside, off, np.inf)
        j = np.argmin(score, axis=1)
        rows = np.arange(len(j))
        ok = np.isfinite(score[rows, j])
        return np.where(ok, cand[rows, j], -1), np.stack([b1[rows, j], b2[rows, j]], 1)

    c = min(candidates, len(tris))
    _, cand = cKDTree(tris.mean(axis=1)).query(y, k=c)
    k, b = test(y, np.asarray(cand).reshape(len(y), c))
    miss = np.flatnonzero(k < 0)
    for s in range(0, len(miss), 256):  # not among the nearest centroids: try every triangle
        sel = miss[s:s + 256]
        k[sel], b[sel] = test(y[sel], np.broadcast_to(np.arange(len(tris)), (len(sel), len(tris))))
    return k, b


def subtriangle_cell(b: np.ndarray, n: int) -> np.ndarray:
    """Index in [0, n²) of the congruent sub-triangle (of n² equal-area ones) holding barycentrics b."""
    x = np.clip(b[:, 0], 0.0, 1.0) * n
    y = np.clip(b[:, 1], 0.0, 1.0) * n
    i = np.minimum(np.floor(x).astype(int), n - 1)
    j = np.minimum(np.floor(y).astype(int), n - 1)
    j = np.minimum(j, n - 1 - i)
    upper = (x - i) + (y - j) > 1.0
    # Upright cells (i, j) with i + j ≤ n − 1 number n(n+1)/2, the inverted ones (i + j ≤ n − 2) the rest.
    upright = i * n - i * (i - 1) // 2 + j
    inverted = n * (n + 1) // 2 + i * (n - 1) - i * (i - 1) // 2 + j
    return np.where(upper & (i + j <= n - 2), inverted, upright)


def area_points_test(name: str, sample: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]],
                     tris: np.ndarray, prob: np.ndarray, ref: np.ndarray, n: int, seed: int,
                     threshold: float = c2.SIGNIFICANCE, uniforms: int = 3,
                     params: dict | None = None) -> c2.Chi2Result:
    """Chi-square of sampled light points against a density uniform within each triangle.

    Parameters
    ----------
    sample
        (reference points (N, 3), uniforms (N, ``uniforms``)) → (unit directions, distances).
    tris
        (K, 3, 3) the light's triangles.
    prob
        (K,) claimed probability of each triangle (area share, times the selection probability for a
        fused set).
    ref
        Reference points the samples are drawn from (cycled).
    """
    rng = np.random.default_rng(seed)
    x = ref[rng.integers(0, len(ref), n)]
    wi, dist = sample(x, rng.random((n, uniforms)))
    y = x + wi * dist[:, None]
    k, b = locate_on_triangles(y, tris)
    sub = int(np.clip(np.floor(np.sqrt(n / (20.0 * len(tris)))), 1, SUB))
    cells = sub * sub
    obs = np.zeros(len(tris) * cells + 1)
    found = k >= 0
    np.add.at(obs, k[found] * cells + subtriangle_cell(b[found], sub), 1.0)
    obs[-1] = np.count_nonzero(~found)  # points off the light: expected 0
    exp = np.append(np.repeat(prob / cells, cells) * n, 0.0)
    stat, dof, p = c2.pearson(obs, exp)
    if obs[-1] > 0:
        p = 0.0
    return c2.Chi2Result(name, params or {}, stat, dof, p, threshold, obs[:-1].reshape(len(tris), cells),
                         exp[:-1].reshape(len(tris), cells), integral=float(prob.sum()),
                         valid_fraction=float(found.mean()))


def emitter_triangles(emitter) -> np.ndarray:
    """(K, 3, 3) world-space triangles of an area emitter, from the scene geometry."""
    g = emitter.geometry
    return g.positions[g.faces[emitter.tris]]


def area_emitter_test(name: str, emitter, ref: np.ndarray, n: int, seed: int,
                      threshold: float = c2.SIGNIFICANCE) -> c2.Chi2Result:
    """:func:`area_points_test` of one area emitter's own sampler (parallelogram or triangle path)."""
    areas = emitter.geometry.tri_area[emitter.tris]

    def sample(x, u):
        r = emitter.sample(x, u)
        return r.wi, r.dist

    return area_points_test(name, sample, emitter_triangles(emitter), areas / areas.sum(), ref, n, seed, threshold,
                            params={"triangles": len(areas), "path": "parallelogram" if emitter._quad is not None
                                    else "triangles"})


def fused_set_test(name: str, scene, ref: np.ndarray, n: int, seed: int,
                   threshold: float = c2.SIGNIFICANCE) -> c2.Chi2Result | None:
    """:func:`area_points_test` of the scene's fused area-light set (None when it does not apply)."""
    from brdflab.integrator.common import area_light_set

    fused = area_light_set(scene)
    if fused is None:
        return None
    tris = np.concatenate([emitter_triangles(e) for e in fused.emitters])
    prob = np.concatenate([p * e.geometry.tri_area[e.tris] / e.area for e, p in zip(fused.emitters, scene.emitter_pmf,
                                                                                   strict=True)])

    def sample(x, u):
        r = fused.sample(x, u)
        return r.wi, r.dist

    return area_points_test(name, sample, tris, prob, ref, n, seed, threshold,
                            params={"emitters": len(fused.emitters), "triangles": len(prob), "path": "fused"})


def environment_test(name: str, env, n: int, seed: int, threshold: float = c2.SIGNIFICANCE,
                     pdf: Callable | None = None) -> c2.Chi2Result:
    """Chi-square of the environment's sampled directions against its pdf (or ``pdf`` if given)."""
    def sample(u):
        r = env.sample(np.zeros((len(u), 3)), u)
        return r.wi, r.pdf

    return c2.chi2_test(name, sample, pdf or env.pdf, np.array([0.0, 1.0, 0.0]), n=n, seed=seed,
                        params={"map": "constant" if env.image is None else f"{env.w}x{env.h}"}, threshold=threshold)


def reference_points(scene, n: int = 4096, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Shading points of the scene (positions and geometric normals) seen through a random set of pixels."""
    from brdflab.integrator.common import trace_camera

    rng = np.random.default_rng(seed)
    cam = scene.camera
    o, d, tmax = cam.generate_rays(rng.uniform(0, cam.width, n), rng.uniform(0, cam.height, n))
    _, sp = trace_camera(scene, o, d, tmax)
    return sp.p, sp.ng


def shading_normals(emitter, k: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The light's shading normal at barycentrics ``b`` of its triangles ``k`` (interpolated vertex normals,
    renormalised, where its mesh has them; else the face normal), from the scene geometry (spec §9.1)."""
    g = emitter.geometry
    f = g.faces[emitter.tris[k]]
    p = g.positions[f]
    face = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    face /= np.linalg.norm(face, axis=1)[:, None]
    if not g.mesh_has_normals[emitter.mesh_index]:
        return face
    n = g.normals[f]
    ns = n[:, 0] + b[:, :1] * (n[:, 1] - n[:, 0]) + b[:, 1:] * (n[:, 2] - n[:, 0])
    return ns / np.linalg.norm(ns, axis=1)[:, None]


def pdf_checks(scene, label: str, n: int = 20_000, seed: int = 0,
               pdf_hit: Callable | None = None) -> list[PdfCheck]:
    """``sample().pdf`` against the pdf the integrators give a BSDF-sampled ray that reaches the same light
    point (``pdf_hit`` at the point's own shading normal and distance; the fused set's ``eval_pdf_hit``; the
    environment's ``pdf``), for every emitter of ``scene`` and its fused set. Points seen at grazing angles
    (|cos θ_l| < 1e-6, where the density is unbounded) are left out.

    ``pdf_hit(emitter, dist, ns, d)`` replaces the area emitters' own ``pdf_hit`` (negative controls).
    """
    from brdflab.integrator.common import area_light_set

    p, _ = reference_points(scene, seed=seed)
    rng = np.random.default_rng(seed + 1)
    x = p[rng.integers(0, len(p), n)]
    out = []

    def rel(a, b):
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.abs(a - b) / np.maximum(np.abs(b), 1e-300)
        return float(r.max()) if len(r) else float("inf")

    def on_light(emitters, r):
        """(selected samples, emitter index, shading normal, distance) of samples located on ``emitters``."""
        tris = np.concatenate([emitter_triangles(e) for e in emitters])
        owner = np.concatenate([np.full(len(e.tris), i) for i, e in enumerate(emitters)])
        first = np.concatenate([[0], np.cumsum([len(e.tris) for e in emitters])])
        y = x + r.wi * r.dist[:, None]
        k, b = locate_on_triangles(y, tris)
        ns = np.zeros((n, 3))
        for i, e in enumerate(emitters):
            mine = (k >= 0) & (owner[np.maximum(k, 0)] == i)
            if mine.any():
                ns[mine] = shading_normals(e, k[mine] - first[i], b[mine])
        cos = -np.sum(ns * r.wi, axis=1)
        sel = (k >= 0) & (np.abs(cos) > 1e-6) & (r.pdf > 0)
        return sel, owner[np.maximum(k, 0)], ns, np.linalg.norm(y - x, axis=1)

    for e_idx, em in enumerate(scene.emitters):
        r = em.sample(x, rng.random((n, 3)))
        if em.is_delta:
            delta = em.position - x
            r2 = np.sum(delta * delta, axis=1)
            err = max(rel(r.pdf, np.ones(n)), rel(r.radiance, em.intensity / r2[:, None]))
            out.append(PdfCheck(f"{label}: point light {e_idx} (pdf 1, I/r²)", n, err))
        elif em.is_environment:
            ok = r.pdf > 0
            out.append(PdfCheck(f"{label}: environment {e_idx}", int(ok.sum()), rel(r.pdf[ok], em.pdf(r.wi[ok]))))
        else:
            sel, _, ns, dist = on_light([em], r)
            ph = (pdf_hit or (lambda e, *a: e.pdf_hit(*a)))(em, dist[sel], ns[sel], r.wi[sel])
            out.append(PdfCheck(f"{label}: area light {e_idx} ({len(em.tris)} triangles, "
                                f"{'parallelogram' if em._quad is not None else 'triangles'})", int(sel.sum()),
                                rel(r.pdf[sel], ph)))
    fused = area_light_set(scene)
    if fused is not None:
        r = fused.sample(x, rng.random((n, 3)))
        sel, owner, ns, dist = on_light(fused.emitters, r)
        _, ph = fused.eval_pdf_hit(owner[sel], dist[sel], ns[sel], r.wi[sel])
        out.append(PdfCheck(f"{label}: fused area lights ({len(fused.emitters)} emitters)", int(sel.sum()),
                            rel(r.pdf[sel], ph)))
    return out


def _scenes(root: Path | None = None) -> list[Path]:
    root = root or BUNDLED_SCENES
    rels = ["cbox/cbox_diffuse.xml", "lights/sphere_light_mis.xml", "lights/polygon_lights_mis.xml",
            "lights/mixed_lights_mis.xml", "envlit/envlit_mis.xml", "veach/veach_mis.xml"]
    return [root / r for r in rels if (root / r).exists()]


def run(n: int = 100_000, progress: Callable[[str], None] | None = None, selection: str = "power"
        ) -> tuple[list[c2.Chi2Result], list[PdfCheck]]:
    """Every emitter sampler of the bundled scenes: chi-square (Šidák-corrected at 0.01 over all of them)
    and pdf consistency. The fused sets are checked with ``selection`` (non-uniform by default)."""
    from brdflab.scene.loader import load_scene

    jobs = []
    for path in _scenes():
        s = load_scene(path)
        s.set_emitter_selection(selection)
        jobs.append((path.stem, s))
    planned = []
    for label, s in jobs:
        for k, em in enumerate(s.emitters):
            if em.is_environment or not em.is_delta:
                planned.append((label, s, k))
        planned.append((label, s, None))
    threshold = c2.sidak(c2.SIGNIFICANCE, len(planned))
    chi, pdfs = [], []
    for label, s, k in planned:
        seed = _seed(label, k)
        if k is None:
            ref, _ = reference_points(s, seed=seed)
            r = fused_set_test(f"{label}: fused area lights", s, ref, n, seed, threshold)
        elif s.emitters[k].is_environment:
            r = environment_test(f"{label}: environment", s.emitters[k], n, seed, threshold)
        else:
            ref, _ = reference_points(s, seed=seed)
            r = area_emitter_test(f"{label}: area light {k}", s.emitters[k], ref, n, seed, threshold)
        if r is None:
            continue
        chi.append(r)
        if progress:
            progress(f"{'PASS' if r.passed else 'FAIL'}  emitter chi2 {r.name:40s} {c2_params(r)} p = {r.p_value:.4f}")
    for label, s in jobs:
        for r in pdf_checks(s, label, seed=_seed("pdf", label)):
            pdfs.append(r)
            if progress:
                progress(f"{'PASS' if r.passed else 'FAIL'}  emitter pdf {r.name}: {r.compared} samples, max rel. "
                         f"error {r.max_rel_error:.1e}")
    return chi, pdfs


def c2_params(r: c2.Chi2Result) -> str:
    return " ".join(f"{k}={v}" for k, v in r.params.items())


def negative_controls(n: int = 100_000, progress: Callable[[str], None] | None = None) -> list[tuple[str, bool, str]]:
    """Deliberately broken samplers/pdfs that the checks above must reject: (what, rejected, detail)."""
    from brdflab.emitter.area import DiscreteChooser
    from brdflab.scene.loader import load_scene

    out = []
    root = BUNDLED_SCENES
    sphere = root / "lights/sphere_light_mis.xml"
    if sphere.exists():
        s = load_scene(sphere)
        em = s.emitters[0]
        ref, _ = reference_points(s, seed=1)
        good = em.chooser
        em.chooser = DiscreteChooser(np.ones(len(em.tris)))  # triangles chosen uniformly, not by area
        try:
            r = area_emitter_test("faceted sphere light, triangles chosen uniformly", em, ref, n, seed=2)
        finally:
            em.chooser = good
        out.append((r.name, not r.passed, f"p = {r.p_value:.3g}"))
        checks = pdf_checks(s, "sphere light", n=5000, seed=3,
                            pdf_hit=lambda e, dist, ns, d: dist * dist / e.area)  # the light's cosine forgotten
        out.append(("sphere light, hit pdf without the light's cosine", not all(c.passed for c in checks),
                    f"max rel. error {max(c.max_rel_error for c in checks):.3g}"))
    env = root / "envlit/envlit_mis.xml"
    if env.exists():
        e = load_scene(env).environment

        def no_sin(d):
            x, y, st = e._to_xy(d)
            return e._pdf_xy(x, y, st) * np.maximum(st, 1e-12)

        r = environment_test("sky environment, pdf without the 1/sin θ Jacobian", e, n, seed=4, pdf=no_sin)
        out.append((r.name, not r.passed, f"p = {r.p_value:.3g}"))
    if progress:
        for name, rejected, detail in out:
            progress(f"{'REJECTED (good)' if rejected else 'NOT REJECTED (bad)'}  emitter negative control {name}: "
                     f"{detail}")
    return out
