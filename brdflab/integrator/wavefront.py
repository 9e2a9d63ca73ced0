"""The wavefront path loop shared by ``path``, ``path_nee`` and ``path_mis`` (spec §13.2.6–8).

One call traces a whole batch of camera rays; every step works on the arrays of the paths still alive, which
are compacted at each bounce (no Python loop per path). With β the throughput of a path and k the number of
its vertices so far (the first surface hit is vertex 1):

1. Camera rays (:func:`~brdflab.integrator.common.trace_camera`): a miss returns the background, a hit on an
   emitter its L_e, and such a path ends (the *emitter-hit rule*); the camera counts as a delta vertex, so all
   three estimators count that emission with weight 1. β = 1 at vertex 1.
2. At every vertex (a :class:`~brdflab.integrator.common.ShadingPoints` batch):

   * **emitter sample** (``nee``, ``mis``): L += β · L_e f |cos θ_o| / p_l · w_l
     (:func:`~brdflab.integrator.common.light_term`), with w_l = 1 (``nee``) or the balance heuristic
     p_l / (p_l + p_bsdf(ω_l)) (``mis``; 1 for delta lights). Not at vertices whose material is all delta
     (``all_delta``: their f is 0 for every light direction): :func:`nee_mask`.
   * **BSDF sample** (ω, weight = f |cos θ_o| / p, p, delta): β' = β · weight; samples of weight 0 end.
   * **Russian roulette** (:func:`roulette`), from vertex :attr:`rr_depth` on: the path survives with
     probability s = min(0.95, max_c β'_c) and the survivors' β' is divided by s, so that
     E[β'·1{ξ < s}/s] = β' — unbiased for any s > 0, and s ≤ 0.95 ends every path with probability 1 (no depth
     cap is needed). Dividing by s also keeps max_c β' near 1, so that s stays near 0.95 on bright paths.
   * **trace** the ray ω: a miss finds the environment, an emitter hit its L_e (front side only, spec §9.1),
     and both end the path: L += β' · L_e · w_b (:func:`bsdf_emission_weight`: 1 for ``bsdf``; for ``nee`` 1
     after a delta sample and 0 otherwise (light sampling already counted it); for ``mis`` 1 after a delta
     sample, else p_b / (p_b + p_l(ω)) with p_l the light-sampling density of ω, selection included). A hit on
     any other surface is the next vertex, with β ← β'.
3. :attr:`max_depth` (segments of the longest path, −1 = none: the default, unbiased): a path of k vertices
   takes its emitter sample and continues only while k + 1 ≤ max_depth (1 = only emitters seen by the camera,
   2 = direct light), so all three estimators estimate the same truncated sum.

Random numbers: at every bounce each live path draws its uniforms (emitter sample, BSDF sample, roulette) in
ascending camera-sample order (:func:`path_uniforms`), from the render unit's own generator, so an image
depends neither on the number of workers nor on how the points are grouped by material (fast and generic
paths give the same image).

The negative controls of the tests replace :func:`roulette` (survivors not divided by s), :func:`nee_mask`
(emitter samples at delta vertices only, the inverted condition of spec §13.2.7) and
:func:`bsdf_emission_weight` (BSDF-found emission counted twice, spec §13.2.8); each must be rejected.
"""

from __future__ import annotations

import numpy as np

from brdflab.integrator.common import (
    ShadingPoints,
    accumulate,
    any_positive,
    emission_of,
    light_dims,
    light_term,
    sample_bsdfs,
    surface_points,
    trace_camera,
)
from brdflab.integrator.direct_mats import spawn_rays
from brdflab.integrator.direct_mis import mis_weight
from brdflab.integrator.tables import scene_tables
from brdflab.math.frame import take_rows

#: The estimators of the loop: BSDF sampling only, next-event estimation, and both combined by MIS.
MODES = ("bsdf", "nee", "mis")

#: Upper bound of the roulette's survival probability (every path ends with probability 1).
MAX_SURVIVAL = 0.95


def path_uniforms(rng: np.random.Generator, sp: ShadingPoints, dims: int) -> np.ndarray:
    """(M, dims) uniforms for the points ``sp`` (one per live path), drawn in ascending order of the paths'
    camera samples ``sp.index`` whatever order the points are in (they are sorted by material family)."""
    m = len(sp.index)
    rank = np.empty(m, np.intp)
    rank[np.argsort(sp.index, kind="stable")] = np.arange(m)
    return np.take(rng.random((m, dims)), rank, axis=0)


def roulette(beta: np.ndarray, xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Russian roulette: (indices of the surviving paths, their throughput divided by the survival probability).

    s = min(:data:`MAX_SURVIVAL`, max_c β_c); a path survives when ξ < s. Unbiased: E[1{ξ < s}/s] = 1.
    """
    s = np.minimum(np.maximum(np.maximum(beta[:, 0], beta[:, 1]), beta[:, 2]), MAX_SURVIVAL)
    keep = np.flatnonzero(xi < s)
    out = take_rows(beta, keep)
    out /= np.take(s, keep)[:, None]
    return keep, out


def nee_mask(scene, sp: ShadingPoints) -> np.ndarray | None:
    """(M,) True at the points that take an emitter sample: those whose material is not all delta (a delta
    vertex gets no emitter-sample contribution, spec §13); None when that is every point."""
    families = scene_tables(scene).bsdf_families.families
    delta = [sel for g, sel in sp.groups if getattr(families[g].members[0], "all_delta", False)]
    if not delta:
        return None
    mask = np.ones(len(sp.index), bool)
    for sel in delta:
        mask[sel] = False
    return mask


def bsdf_emission_weight(mode: str, delta: np.ndarray | None, p_bsdf: np.ndarray,
                         p_light: np.ndarray) -> np.ndarray | None:
    """Weight of the emission found by BSDF-sampled rays ((K,), or None for weight 1 everywhere): see the module
    docstring (``delta``: the samples from delta lobes, None when there are none)."""
    if mode == "bsdf":
        return None
    if mode == "nee":
        return np.zeros(len(p_bsdf)) if delta is None else delta.astype(np.float64)
    w = mis_weight(p_bsdf, p_light, 1.0)
    return w if delta is None else np.where(delta, 1.0, w)


def trace_paths(scene, o: np.ndarray, d: np.ndarray, tmax: np.ndarray, rng: np.random.Generator, mode: str,
                max_depth: int = -1, rr_depth: int = 3) -> np.ndarray:
    """Radiance (N, 3) along the camera rays (o, d), t ≤ tmax, by the path estimator ``mode`` (module docstring).

    Examples
    --------
    >>> import numpy as np, brdflab as bl
    >>> from pathlib import Path
    >>> scene = bl.load_scene(Path(bl.__file__).parents[1] / "scenes" / "cbox" / "cbox_diffuse.xml", width=8,
    ...                       height=6)
    >>> rng = np.random.default_rng(1)
    >>> o, d, tmax = scene.camera.generate_rays(rng.random(64) * 8, rng.random(64) * 6)
    >>> L = trace_paths(scene, o, d, tmax, rng, "mis")
    >>> L.shape, bool(np.isfinite(L).all() and (L >= 0).all())
    ((64, 3), True)
    """
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, not {mode!r}")
    L, sp = trace_camera(scene, o, d, tmax)
    beta = np.ones((len(sp.index), 3), order="F")
    k = light_dims(scene)
    nee = mode != "bsdf" and bool(scene.emitters)
    mis = (lambda ls, p_bsdf: np.where(ls.delta, 1.0, mis_weight(ls.pdf, p_bsdf, 1.0))) if mode == "mis" else None
    depth = 1
    while len(sp.index) and (max_depth < 0 or depth < max_depth):
        u = path_uniforms(rng, sp, k + 4)
        if nee:
            c = light_term(scene, sp, u[:, :k], mis)
            mask = nee_mask(scene, sp)
            accumulate(L, sp.index, beta, c, None if mask is None else mask.astype(np.float64))
        wo, weight, pdf, delta = sample_bsdfs(scene, sp, u[:, k:k + 3], with_delta=True)
        live, dw, ow, weight, pdf = spawn_rays(scene, sp, wo, weight, pdf)
        pid = np.take(sp.index, live)
        beta = take_rows(beta, live)
        beta *= weight
        delta = None if delta is None else np.take(delta, live)
        if depth >= rr_depth:
            keep, beta = roulette(beta, np.take(u[:, k + 3], live))
            pid, pdf, dw, ow = np.take(pid, keep), np.take(pdf, keep), take_rows(dw, keep), np.take(ow, keep, axis=0)
            delta = None if delta is None else np.take(delta, keep)
        rh = scene.geometry.trace(ow, dw)
        if mode != "nee" or (delta is not None and delta.any()):  # path_nee: only after delta samples
            Le, p_light = emission_of(scene, rh, dw)
            w = bsdf_emission_weight(mode, delta, pdf, p_light)
            lit = np.flatnonzero(any_positive(Le))
            if len(lit):
                accumulate(L, np.take(pid, lit), take_rows(beta, lit), take_rows(Le, lit),
                           None if w is None else np.take(w, lit))
        sp = surface_points(scene, rh, dw)
        beta = take_rows(beta, sp.index)
        sp.index = np.take(pid, sp.index)
        depth += 1
    return L
