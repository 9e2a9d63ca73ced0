"""Helpers shared by the direct-illumination integrators (spec §13).

Batches flow one way: camera rays → :func:`trace_camera` (closest hits, background for misses, L_e
for rays that hit an emitter — the *emitter-hit rule*: stop there) → :class:`ShadingPoints` (the
compacted surface hits with their local frames) → emitter samples (:func:`sample_lights`) and/or BSDF
samples (:func:`sample_bsdfs`) → radiance per camera sample. Every function works on whole batches;
Python loops run over materials and emitters, never over rays.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from brdflab.emitter.area import AreaLightSet
from brdflab.integrator.sides import transmitted_cos
from brdflab.integrator.tables import CODE_EMITTER, CODE_MISS, SceneTables, scene_tables
from brdflab.kernels import compiled, load
from brdflab.math.frame import NormalFrames, take_rows
from brdflab.scene.geometry import Hits
from brdflab.scene.properties import PropertyList


class Integrator:
    """Base class: ``li`` returns the radiance (N, 3) carried by N camera rays."""

    type_name = ""
    #: Warn when the scene has no emitter (the image would be black).
    needs_emitters = True
    KNOWN: dict[str, str] = {}

    @classmethod
    def from_properties(cls, props: PropertyList) -> Integrator:
        """Build from an ``<integrator>`` property list (the direct integrators take none)."""
        props.check_known(cls.KNOWN)
        return cls()

    def li(self, scene, o: np.ndarray, d: np.ndarray, tmax: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Radiance along camera rays (o, d) with t ≤ tmax."""
        raise NotImplementedError


@dataclass
class ShadingPoints:
    """Compacted camera hits on non-emitting surfaces, with local shading frames."""

    index: np.ndarray
    """(M,) index of each point in the camera batch."""
    p: np.ndarray
    ng: np.ndarray
    ns: np.ndarray
    frames: NormalFrames
    """The shading frames (s, t, n_s), applied without tangent arrays."""
    uv: np.ndarray
    wi: np.ndarray
    """(M, 3) local direction toward the camera."""
    groups: list[tuple[int, slice]]
    """(family, rows) per material family present (:mod:`brdflab.bsdf.family`): the points are sorted by
    family, so each family's points are one contiguous slice (its inputs are views, its outputs one block
    copy, no gathers or scatters)."""
    member: np.ndarray | None
    """(M,) index of the point's material within its family (None when no family has several members
    with different constants)."""

    def local(self, w: np.ndarray, sel: np.ndarray | None = None) -> np.ndarray:
        """World directions → local shading frame (of the points ``sel``, default all)."""
        return (self.frames if sel is None else self.frames.take(sel)).to_local(w)

    def world(self, w: np.ndarray, sel: np.ndarray | None = None) -> np.ndarray:
        """Local directions → world (for the points ``sel``, default all)."""
        return (self.frames if sel is None else self.frames.take(sel)).to_world(w)


def background(scene, d: np.ndarray) -> np.ndarray:
    """Radiance of escaping rays: the environment, or black."""
    if scene.environment is None or len(d) == 0:
        return np.zeros((len(d), 3))
    return scene.environment.eval(d)


def sort_by_code(code: np.ndarray, codes: list[int]) -> tuple[np.ndarray, list[tuple[int, slice]]]:
    """Indices of the entries with ``code`` ≥ 0, grouped by code (ascending index within one), and the
    (code, slice) of each non-empty group in that order; ``codes`` lists the codes that can occur,
    ascending. Negative entries are left out.

    One pass for a single code, one comparison per code for up to 8, a stable (radix) argsort beyond.
    """
    if len(codes) <= 8:
        if len(codes) == 1:
            parts = [np.flatnonzero(code >= 0)]
        else:
            parts = [np.flatnonzero(code == c) for c in codes]
        sizes = [len(p) for p in parts]
        order = parts[0] if len(codes) == 1 else np.concatenate(parts)
    else:
        order = np.argsort(code.astype(np.int16), kind="stable")
        order = order[np.searchsorted(np.take(code, order), 0):]
        sizes = np.bincount(np.take(code, order), minlength=codes[-1] + 1)[codes]
    runs, start = [], 0
    for c, size in zip(codes, sizes, strict=True):
        if size:
            runs.append((int(c), slice(start, start + int(size))))
            start += int(size)
    return order, runs


def trace_camera(scene, o: np.ndarray, d: np.ndarray, tmax: np.ndarray) -> tuple[np.ndarray, ShadingPoints]:
    """Trace camera rays; apply the miss and emitter-hit rules; return (L, shading points).

    Hit records are reconstructed only where they are used: at the shading points, and (normals and uvs)
    at the few hits on emitters.
    """
    g = scene.geometry
    tab = scene_tables(scene)
    rh = g.trace(o, d, tmax)
    L = np.zeros((len(o), 3), order="F")
    code = np.take(tab.tri_code, rh.prim)
    if scene.environment is not None:
        miss = np.flatnonzero(code == CODE_MISS)
        if len(miss):
            L[miss] = background(scene, take_rows(d, miss))
    if tab.has_emitter_meshes:
        lit = np.flatnonzero(code == CODE_EMITTER)
        if len(lit):
            h = g.surface(rh, lit, positions=False)
            d_lit = take_rows(d, lit)
            for e, sel in by_group(np.take(tab.tri_emitter, h.prim)):
                L[rows(lit, sel)] = scene.emitters[e].eval_hit(rows(h.ns, sel), rows(h.uv, sel), rows(d_lit, sel))
    return L, surface_points(scene, rh, d, code)


def surface_points(scene, rh, d: np.ndarray, code: np.ndarray | None = None) -> ShadingPoints:
    """:class:`ShadingPoints` of the hits of the trace ``rh`` (rays ``d``) on non-emitting surfaces (``index``:
    the ray of each point); ``code`` is ``tri_code`` of the hits (:class:`SceneTables`) when already looked up."""
    tab = scene_tables(scene)
    if code is None:
        code = np.take(tab.tri_code, rh.prim)
    # Shading points sorted by material family, and within a family flat meshes before smooth ones (only
    # those interpolate vertex normals).
    idx, runs = sort_by_code(code, tab.codes)
    groups: list[tuple[int, slice]] = []
    for c, sl in runs:
        if groups and groups[-1][0] == c >> 1:
            groups[-1] = (c >> 1, slice(groups[-1][1].start, sl.stop))
        else:
            groups.append((c >> 1, sl))
    smooth = [sl for c, sl in runs if c & 1]
    smooth = None if len(smooth) == len(runs) else smooth
    if compiled():
        return _compiled_shading_points(scene, rh, d, idx, groups, smooth)
    h = scene.geometry.surface(rh, idx, uv=tab.bsdf_uv, smooth=smooth)
    return make_shading_points(scene, h, take_rows(d, idx), idx, groups)


def _compiled_shading_points(scene, rh, d: np.ndarray, idx: np.ndarray, groups: list[tuple[int, slice]],
                             smooth: list[slice] | None) -> ShadingPoints:
    """:class:`ShadingPoints` by the compiled engine (:mod:`brdflab.kernels.shading`), bit-identical to
    ``make_shading_points(scene, g.surface(rh, idx, …), …)``."""
    tab = scene_tables(scene)
    p, ng, ns, uv, sign, a, wi, member, tan = load("shading").shading_arrays(scene.geometry, rh, d, idx, tab.bsdf_uv,
                                                                             smooth, tab.tri_member, tab)
    return ShadingPoints(idx, p, ng, ns, NormalFrames(ns, sign, a, tan), uv, wi, groups, member)


def shading_points(scene, hits: Hits, d: np.ndarray, idx: np.ndarray) -> ShadingPoints:
    """Compact the hits ``idx`` of rays with directions ``d`` into :class:`ShadingPoints` (sorted by
    material family: ``index`` says which ray each point belongs to)."""
    fams = scene_tables(scene).bsdf_families
    order, groups = sort_by_code(np.take(fams.mesh_family, np.take(hits.mesh, idx)), list(range(len(fams.families))))
    idx = np.take(idx, order)
    h = Hits(np.take(hits.valid, idx), np.take(hits.t, idx), take_rows(hits.p, idx), take_rows(hits.ng, idx),
             take_rows(hits.ns, idx), take_rows(hits.uv, idx), np.take(hits.prim, idx), np.take(hits.mesh, idx))
    return make_shading_points(scene, h, take_rows(d, idx), idx, groups)


def make_shading_points(scene, h: Hits, d: np.ndarray, idx: np.ndarray,
                        groups: list[tuple[int, slice]]) -> ShadingPoints:
    """:class:`ShadingPoints` of the (already compacted, family-sorted) hits ``h`` of rays ``d``, camera
    indices ``idx``, family slices ``groups`` (:func:`sort_by_code`)."""
    frames, tab = NormalFrames(h.ns), scene_tables(scene)
    if tab.tri_tangent is not None:  # anisotropic materials on meshes with uvs: the uv tangent's frame
        frames = frames.with_uv_tangents(np.take(tab.dpdu, h.prim, axis=1).T, np.take(tab.tri_tangent, h.prim))
    wi = frames.to_local(d, negate=True)
    fams = tab.bsdf_families
    member = np.take(fams.mesh_member, h.mesh) if fams.any_tables else None
    return ShadingPoints(idx, h.p, h.ng, h.ns, frames, h.uv, wi, groups, member)


def bound_bsdfs(scene, sp: ShadingPoints):
    """Yield (material, slice of the points) per family present among the points ``sp``."""
    families = scene_tables(scene).bsdf_families.families
    for g, sel in sp.groups:
        fam = families[g]
        yield fam.bind(sp.member[sel] if fam.tables else None), sel


def by_group(ids: np.ndarray):
    """Yield (group id, selector) for each distinct non-negative id (a loop over materials/emitters).

    The selector is ``slice(None)`` when one group covers the whole batch (no copies), otherwise an
    index array. Few groups are split with one comparison each, many with one stable argsort.
    """
    if len(ids) == 0:
        return
    lo, hi = int(ids.min()), int(ids.max())
    if lo == hi:
        if lo >= 0:
            yield lo, slice(None)
        return
    groups = np.unique(ids) if hi - lo > 64 else np.flatnonzero(np.bincount(ids - lo)) + lo
    if len(groups) <= 8:
        for g in groups:
            if g >= 0:
                yield int(g), np.flatnonzero(ids == g)
        return
    order = np.argsort(ids, kind="stable")
    bounds = np.flatnonzero(np.diff(ids[order])) + 1
    for chunk in np.split(order, bounds):
        g = int(ids[chunk[0]])
        if g >= 0:
            yield g, chunk


def rows(a: np.ndarray | None, sel) -> np.ndarray | None:
    """``a[sel]`` for a selector of :func:`by_group` or :func:`sort_by_code`: a view for a slice, else a
    gather (None stays None)."""
    if a is None:
        return None
    if isinstance(sel, slice):
        return a[sel]
    return take_rows(a, sel) if a.ndim == 2 else np.take(a, sel)


def accumulate(L: np.ndarray, idx: np.ndarray, a: np.ndarray, b: np.ndarray, scale: np.ndarray | None = None) -> None:
    """``L[idx] += a · b · scale[:, None]`` channel by channel (1-D gathers and products, no (M, 3)
    temporaries); ``idx`` holds distinct rows."""
    if compiled() and L.dtype == a.dtype == b.dtype == np.float64 and idx.dtype == np.int64:
        return load("direct").accumulate(L, idx, a, b, np.zeros(0) if scale is None else scale, scale is not None)
    for j in range(3):
        c = a[:, j] * b[:, j]
        if scale is not None:
            c *= scale
        col = L[:, j]
        col[idx] = np.take(col, idx) + c


def point_uniforms(rng: np.random.Generator, n_rays: int, sp: ShadingPoints, dims: int) -> np.ndarray:
    """(M, dims) uniforms for the shading points ``sp``, drawn per camera ray and gathered by ray index.

    Tying the numbers to the camera sample rather than to the points' (material-family, flat/smooth)
    sorted order makes an image independent of how the points were grouped: the fast paths for built-in
    materials and the plain per-material path give the same image to the bit.
    """
    return np.take(rng.random((n_rays, dims)), sp.index, axis=0)


def any_positive(rgb: np.ndarray) -> np.ndarray:
    """True where any of the three channels is > 0 (column-wise: faster than a reduction over axis 1)."""
    return (rgb[:, 0] > 0) | (rgb[:, 1] > 0) | (rgb[:, 2] > 0)


def eval_bsdfs(scene, sp: ShadingPoints, wo: np.ndarray, with_pdf: bool = False):
    """f(wi, wo) (M, 3) for local ``wo``; with ``with_pdf`` also the BSDF sampling density (M,)."""
    m = len(wo)
    if _one_family(sp, m):
        bsdf, _ = next(bound_bsdfs(scene, sp))
        return bsdf.eval_pdf(sp.wi, wo, sp.uv) if with_pdf else bsdf.eval(sp.wi, wo, sp.uv)
    f = np.zeros((m, 3), order="F")
    pdf = np.zeros(m) if with_pdf else None
    for bsdf, sel in bound_bsdfs(scene, sp):
        wi_b, wo_b, uv_b = sp.wi[sel], wo[sel], rows(sp.uv, sel)
        if with_pdf:
            f[sel], pdf[sel] = bsdf.eval_pdf(wi_b, wo_b, uv_b)
        else:
            f[sel] = bsdf.eval(wi_b, wo_b, uv_b)
    return (f, pdf) if with_pdf else f


def _one_family(sp: ShadingPoints, m: int) -> bool:
    """True when one material family holds all ``m`` points (its results need no assembling)."""
    return len(sp.groups) == 1 and sp.groups[0][1] == slice(0, m)


def sample_bsdfs(scene, sp: ShadingPoints, u: np.ndarray, with_delta: bool = False):
    """One BSDF sample per point: (local wo, weight f·cos/pdf, pdf), and with ``with_delta`` also the (M,) bool
    mask of samples from delta lobes (``BSDFSample.delta``; None when no material returned one)."""
    m = len(u)
    if _one_family(sp, m):
        bsdf, _ = next(bound_bsdfs(scene, sp))
        r = bsdf.sample(sp.wi, u, sp.uv)
        return (r.wo, r.weight, r.pdf, _delta_of(r)) if with_delta else (r.wo, r.weight, r.pdf)
    wo = np.zeros((m, 3), order="F")
    weight = np.zeros((m, 3), order="F")
    pdf = np.zeros(m)
    delta = None
    for bsdf, sel in bound_bsdfs(scene, sp):
        r = bsdf.sample(sp.wi[sel], u[sel], rows(sp.uv, sel))
        wo[sel], weight[sel], pdf[sel] = r.wo, r.weight, r.pdf
        if with_delta and _delta_of(r) is not None:
            delta = np.zeros(m, bool) if delta is None else delta
            delta[sel] = r.delta
    return (wo, weight, pdf, delta) if with_delta else (wo, weight, pdf)


def _delta_of(r) -> np.ndarray | None:
    """The ``delta`` field of a BSDF sample (None for the 3-field samples of the original contract)."""
    return getattr(r, "delta", None)


@dataclass
class LightSamples:
    """One emitter sample per shading point, **before** the visibility test (:func:`light_contributions`
    traces shadow rays only for the samples that would contribute)."""

    wi: np.ndarray
    """(M, 3) world direction toward the light."""
    radiance: np.ndarray
    """(M, 3) emitted radiance toward the point, 0 where the sample is invalid."""
    pdf: np.ndarray
    """(M,) solid-angle pdf **including** the selection probability (1·p_sel for delta lights)."""
    delta: np.ndarray
    """(M,) True for delta (point) lights."""
    dist: np.ndarray
    """(M,) distance to the light point (inf for the environment)."""


def choose_emitters(scene, u: np.ndarray) -> np.ndarray:
    """Emitter index per uniform ``u`` by the scene's selection pmf (uniform by default)."""
    k = np.searchsorted(scene.emitter_cdf, u, side="right")
    return np.minimum(k, len(scene.emitters) - 1)


def area_light_set(scene) -> AreaLightSet | None:
    """The scene's fused :class:`AreaLightSet` (built once), or None when it does not apply.

    Only with several emitters: a single area light samples just as fast on its own.
    """
    cached = scene.__dict__.get("_area_light_set", False)
    if cached is False:
        ok = len(scene.emitters) > 1 and AreaLightSet.applies(scene.emitters)
        cached = AreaLightSet(scene.emitters, scene.emitter_pmf) if ok else None
        scene.__dict__["_area_light_set"] = cached
    return cached


def light_dims(scene) -> int:
    """Uniforms per light sample (:func:`sample_lights`): 4 when an emitter is chosen before it is sampled,
    3 for a single emitter or a fused :class:`AreaLightSet`."""
    return 4 if len(scene.emitters) > 1 and area_light_set(scene) is None else 3


def sample_lights(scene, sp: ShadingPoints, u: np.ndarray) -> LightSamples:
    """One emitter sample per point (no shadow rays yet), from :func:`light_dims` uniforms ``u``: with 4,
    ``u[:, 0]`` picks the emitter and ``u[:, 1:4]`` samples it; with 3 they sample the only (or fused)
    emitter."""
    m = len(sp.p)
    fused = area_light_set(scene)
    if m and fused is not None:
        wi, dist, radiance, pdf = fused.sample(sp.p, u)
        return LightSamples(wi, radiance, pdf, np.zeros(m, bool), dist)
    if m and len(scene.emitters) == 1:
        em = scene.emitters[0]
        r = em.sample(sp.p, u)
        pmf = scene.emitter_pmf[0]
        return LightSamples(r.wi, r.radiance, r.pdf if pmf == 1.0 else r.pdf * pmf, np.full(m, em.is_delta), r.dist)
    wi = np.zeros((m, 3), order="F")
    wi[:, 2] = 1.0
    radiance = np.zeros((m, 3), order="F")
    pdf = np.zeros(m)
    dist = np.zeros(m)
    delta = np.zeros(m, bool)
    if m == 0 or not scene.emitters:
        return LightSamples(wi, radiance, pdf, delta, dist)
    for e, sel in by_group(choose_emitters(scene, u[:, 0])):
        em = scene.emitters[e]
        r = em.sample(rows(sp.p, sel), rows(u, sel)[:, 1:4])
        wi[sel], radiance[sel], dist[sel] = r.wi, r.radiance, r.dist
        pdf[sel] = r.pdf * scene.emitter_pmf[e]
        delta[sel] = em.is_delta
    return LightSamples(wi, radiance, pdf, delta, dist)


def light_contributions(scene, sp: ShadingPoints, ls: LightSamples, f: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """(M, 3) ``L_e · f · scale`` of each point's light sample, in shading-point order; 0 where that is not
    positive or the light is occluded.

    Shadow rays are traced only where the product is positive: a light below the surface's horizon
    (cos θ = 0), an invalid sample or a zero BSDF value needs no visibility test.
    """
    c = np.empty(f.shape, order="F")
    for j in range(3):
        np.multiply(ls.radiance[:, j], f[:, j], out=c[:, j])
        c[:, j] *= scale
    keep = any_positive(c)
    live = np.flatnonzero(keep)
    if len(live):
        keep[live[scene.geometry.shadow_occluded(sp.p, sp.ng, ls.wi, ls.dist, live)]] = False
    drop = ~keep
    for j in range(3):
        np.copyto(c[:, j], 0.0, where=drop)
    return c


def light_term(scene, sp: ShadingPoints, u: np.ndarray, mis=None) -> np.ndarray:
    """(M, 3) emitter-sampling estimate per shading point, L_e · f · cos θ / p (· w), in shading-point order.

    One light sample per point from the :func:`light_dims` uniforms ``u``; ``mis(ls, p_bsdf)``, when given,
    returns the samples' MIS weights w from the light samples and the BSDF's density of their directions.
    Invalid samples (pdf 0) give 0: dividing by ∞ instead of p does that in one pass.
    """
    ls = sample_lights(scene, sp, u)
    wo = sp.local(ls.wi)
    if mis is None:
        f, w = eval_bsdfs(scene, sp, wo), None
    else:
        f, p_bsdf = eval_bsdfs(scene, sp, wo, with_pdf=True)
        w = mis(ls, p_bsdf)
    wo = transmitted_cos(scene, sp, wo)
    if compiled():
        return load("direct").light_tail(scene.geometry, sp.p, sp.ng, ls.radiance, f, wo, ls.pdf, w, ls.wi, ls.dist)
    scale = np.maximum(wo[:, 2], 0.0)
    if w is not None:
        scale *= w
    scale /= np.where(ls.pdf > 0, ls.pdf, np.inf)
    return light_contributions(scene, sp, ls, f, scale)


def set_rows(L: np.ndarray, idx: np.ndarray, values: np.ndarray) -> None:
    """``L[idx] = values`` channel by channel (1-D scatters into the Fortran-ordered ``L``)."""
    if compiled() and L.dtype == values.dtype == np.float64 and idx.dtype == np.int64:
        return load("direct").set_rows(L, idx, values)
    for j in range(3):
        L[:, j][idx] = values[:, j]


def emission_along(scene, o: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Trace rays (o, d); return the emitted radiance they find (area light or environment) and the
    solid-angle density with which *light sampling* would have produced that direction (selection
    probability included), for MIS."""
    env = scene.environment  # without one, only the lights matter: Geometry.trace_to_lights is cheaper
    g, tri_emitter = scene.geometry, scene_tables(scene).tri_emitter
    rh = g.trace(o, d) if env is not None else g.trace_to_lights(o, d, tri_emitter)
    return emission_of(scene, rh, d)


def emission_of(scene, rh, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(L_e, light-sampling pdf) found by the rays ``d`` of the trace ``rh``: area lights hit on their front
    side, the environment for misses, 0 elsewhere (see :func:`emission_along`)."""
    env, g = scene.environment, scene.geometry
    fused = area_light_set(scene)
    if fused is not None and compiled() and len(d):
        Le, pdf = load("direct").light_set_emission(g, rh, d, scene_tables(scene).tri_emitter, fused)
    else:
        Le, pdf = _area_emission(scene, rh, d, fused)
    if env is not None:
        miss = np.flatnonzero(~rh.valid)
        if len(miss):
            Le[miss], pdf_env = env.eval_pdf(take_rows(d, miss))
            pdf[miss] = pdf_env * scene.emitter_pmf[scene.emitters.index(env)]
    return Le, pdf


def _area_emission(scene, rh, d: np.ndarray, fused: AreaLightSet | None) -> tuple[np.ndarray, np.ndarray]:
    """(L_e, light-sampling pdf) of the area lights hit in the trace ``rh`` of rays ``d`` (0 elsewhere)."""
    Le, pdf = np.zeros((len(d), 3), order="F"), np.zeros(len(d))
    em = np.take(scene_tables(scene).tri_emitter, rh.prim)
    hit = np.flatnonzero(em >= 0)
    if len(hit):
        # Only the rays that found an emitter need their hit's normal (and uv, for textured emitters).
        h = scene.geometry.surface(rh, hit, positions=False, uv=fused is None)
        em_hit, d_hit = np.take(em, hit), take_rows(d, hit)
        if fused is not None:
            Le[hit], pdf[hit] = fused.eval_pdf_hit(em_hit, h.t, h.ns, d_hit)
        else:
            for e, sel in by_group(em_hit):
                emitter, at = scene.emitters[e], rows(hit, sel)
                ns, d_e = rows(h.ns, sel), rows(d_hit, sel)
                Le[at] = emitter.eval_hit(ns, rows(h.uv, sel), d_e)
                pdf[at] = emitter.pdf_hit(rows(h.t, sel), ns, d_e) * scene.emitter_pmf[e]
    return Le, pdf


__all__ = ["Integrator", "ShadingPoints", "LightSamples", "SceneTables", "CODE_EMITTER", "CODE_MISS", "background",
           "trace_camera", "shading_points", "make_shading_points", "scene_tables", "sort_by_code", "by_group",
           "accumulate", "any_positive", "rows", "eval_bsdfs", "sample_bsdfs", "light_dims", "sample_lights",
           "light_contributions", "light_term", "set_rows", "emission_along", "emission_of", "choose_emitters",
           "surface_points"]
