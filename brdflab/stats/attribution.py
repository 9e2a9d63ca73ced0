"""Where and what: attributing the regions ``brdflab check`` flags to materials, emitters and a sampling strategy.

A check says *where* a render differs from brdflab's estimate; this module says *what* is there. It renders
cheap auxiliary images of the scene at the check's resolution (:func:`render_aux`, a few samples per pixel):

* the **material** each pixel's camera ray hits (pixel centres; emitters seen directly and misses apart);
* the **emitter-sampled part E and the BSDF-sampled part B** of the direct illumination: the two
  MIS-weighted halves of ``direct_mis`` (:func:`brdflab.pages.mis_weights.mis_parts`, same random numbers,
  so E + B is the estimate without camera-visible emission). E dominates on diffuse surfaces lit by small
  lights, B on glossy surfaces reflecting large ones;
* the **direct light of each emitter** alone (emitter sampling with the selection probability set to 1 for
  that emitter), for the brightest :data:`MAX_EMITTERS` emitters;
* for a path-traced scene (``path``, ``path_nee``, ``path_mis``), brdflab's **direct and indirect light** D and I
  (:func:`depth_parts`): two ``path_mis`` renders with one seed, one with ``maxDepth`` 2 (paths of at most two
  segments: emitters seen directly and direct light) and one unlimited; the first bounce draws the same random
  numbers in both, so D is exactly the short paths' part of the full render and I = full − D the longer paths'
  (tested).

For each flagged region (a connected set of too-dark, or too-bright, blocks of the check's map) and for the
whole image, :func:`attribute` then reports the materials covering it (pixel shares, each with its own
relative difference), the emitters lighting it (shares of its direct light), and a least-squares fit of the
user's difference d = x̄ − ȳ (mean of R, G, B) on the two parts,

    d ≈ a·E + b·B                                                                                      (1)

(and, for a path-traced scene, d ≈ a·D + b·I: "your indirect light is 5 % short" is b = −0.05;
:func:`brdflab.stats.findings.depth_finding`) over cells of :data:`CELL` × :data:`CELL` pixels, with
heteroscedasticity-robust (HC3, MacKinnon & White 1985) standard errors and Student's t with n − 2 degrees of
freedom; the direct/indirect fit's p-values come from the restricted wild bootstrap instead
(:mod:`brdflab.stats.wild_bootstrap`: with the ~80 cells of a small image the t-test made 2.5 % false statements
on unbiased renders against a nominal 2 %, the bootstrap 1.9 %). A deficit that *follows emitter-sampled light*
(a < 0 significant at :data:`LEVEL`, b not) points at light sampling or the shadow test; one that follows
BSDF-sampled light (b < 0, a not) at BSDF sampling (its weight or pdf, or the emission found by BSDF rays);
otherwise nothing definite is said — a deficit proportional to all direct light (a ≈ b) is explained by the
integrator the scene asks for (``direct_ems`` samples only emitters, ``direct_mats`` only BSDFs). With several
emitters the same fit on the per-emitter images names an emitter whose light alone is missing.

The fit is descriptive, not part of the check's verdict (which keeps its family-wise level): the regressors
are brdflab's own noisy estimates (errors in variables shrink a and b toward 0, so noise makes the fit
*less* definite, never attributes a deficit wrongly by itself), and the cells of a region are not
independent of the selection that flagged it.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy import ndimage, stats

# The sentences live in findings.py; re-exported here, the module users (and the tests) know.
from brdflab.stats.findings import (  # noqa: F401
    ALL_LIGHT,
    CAUSE,
    DOMINANT,
    ONE_STRATEGY,
    PRINTED,
    _fit_text,
    _formula,
    attribution_lines,
    depth_finding,
    interpret,
)
from brdflab.stats.wild_bootstrap import hc3, t_values, wild_p_values

#: Side of the cells (pixels) that are the observations of the fits (1).
CELL = 8
#: Two-sided level at which a coefficient counts as significant.
LEVEL = 0.01
#: Fewest cells for a fit.
MIN_CELLS = 6
#: Emitters rendered one by one (the brightest by power); the others are left out of the emitter shares and fit.
MAX_EMITTERS = 8
#: Regions reported (largest first); printed on the command line: :data:`~brdflab.stats.findings.PRINTED`.
MAX_REGIONS = 10
#: Samples per pixel of the auxiliary renders.
AUX_SPP = 8
#: Wild bootstrap draws behind the p-values of the direct/indirect fit (:mod:`brdflab.stats.wild_bootstrap`).
WILD_DRAWS = 999


@dataclass
class AuxImages:
    """Per-pixel auxiliary information of a scene at the check's resolution (see module docstring)."""

    material: np.ndarray
    """(H, W) int: material index ≥ 0 of the camera ray's first hit, −1 a miss, −2 − e emitter e seen directly."""
    emitter_part: np.ndarray
    """(H, W) mean of R, G, B of the MIS-weighted emitter samples (E)."""
    bsdf_part: np.ndarray
    """(H, W) mean of R, G, B of the MIS-weighted BSDF samples (B)."""
    per_emitter: np.ndarray
    """(K, H, W) mean of R, G, B of the direct light of emitter ``emitter_ids[k]`` alone."""
    emitter_ids: list[int]
    material_labels: list[str]
    emitter_labels: list[str]
    spp: int = AUX_SPP
    material_short: list[str] = field(default_factory=list)
    """``diffuse #0 white.obj``: type, index and first mesh (for one-line output)."""
    seconds: float = 0.0
    direct_part: np.ndarray | None = None
    """(H, W) mean of R, G, B of brdflab's direct light D (path-traced scenes only, else None)."""
    indirect_part: np.ndarray | None = None
    """(H, W) mean of R, G, B of brdflab's indirect light I (path-traced scenes only, else None)."""


def material_label(scene, i: int, short: bool = False) -> str:
    """``diffuse #0 (albedo 0.5 0.5 0.5; walls.obj)``: type, constant parameters and the meshes using it
    (``short``: ``diffuse #0 walls.obj``, type and first mesh)."""
    b = scene.bsdfs[i]
    parts = []
    for slot in getattr(b, "texture_slots", ()):
        t = getattr(b, slot, None)
        v = getattr(t, "value", None) if getattr(t, "constant", False) else None
        if v is not None:
            parts.append(f"{slot} " + " ".join(f"{float(c):.3g}" for c in np.atleast_1d(v)[:3]))
        elif t is not None:
            parts.append(f"{slot} textured")
    meshes = [Path(str(getattr(m.mesh, "path", "") or "")).name or f"mesh {k}"
              for k, m in enumerate(scene.meshes) if m.bsdf == i and m.emitter < 0]
    if meshes:
        parts.append(", ".join(meshes[:3]) + (f" +{len(meshes) - 3}" if len(meshes) > 3 else ""))
    name = getattr(b, "type_name", "") or type(b).__name__
    if short:
        return f"{name} #{i}" + (f" {meshes[0]}" if meshes else "")
    return f"{name} #{i}" + (f" ({'; '.join(parts)})" if parts else "")


def emitter_label(scene, e: int) -> str:
    """``area #0 (light.obj)``, ``point #1``, ``environment #2``."""
    em = scene.emitters[e]
    name = getattr(em, "type_name", "") or type(em).__name__
    mesh = getattr(em, "mesh_index", -1)
    if mesh is not None and mesh >= 0 and mesh < len(scene.meshes):
        return f"{name} #{e} ({Path(str(getattr(scene.meshes[mesh].mesh, 'path', '') or '')).name or f'mesh {mesh}'})"
    return f"{name} #{e}"


def material_map(scene) -> np.ndarray:
    """(H, W) material of the first hit through each pixel centre (see :attr:`AuxImages.material`)."""
    cam = scene.camera
    yy, xx = np.mgrid[0:cam.height, 0:cam.width]
    o, d, tmax = cam.generate_rays(xx.ravel() + 0.5, yy.ravel() + 0.5)
    rh = scene.geometry.trace(o, d, tmax)
    out = np.full(len(o), -1, np.int64)
    hit = np.flatnonzero(rh.valid)
    mesh = np.take(scene.geometry.tri_mesh, rh.prim[hit])
    bsdf = np.asarray(scene.mesh_bsdf, np.int64)[mesh]
    em = np.asarray(scene.mesh_emitter, np.int64)[mesh]
    out[hit] = np.where(em >= 0, -2 - em, bsdf)
    return out.reshape(cam.height, cam.width)


def depth_parts(scene_path: Path, spp: int = AUX_SPP, seed: int = 0, resolution: tuple[int, int] | None = None,
                workers: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(H, W, 3) direct and indirect light of brdflab's ``path_mis`` estimate (module docstring): the render with
    ``maxDepth`` 2, and the unlimited render with the same seed minus it."""
    from brdflab.renderer import render
    from brdflab.stats.jobs import RenderJob, load_for, run_seed

    job = RenderJob(Path(scene_path), "path_mis", spp, run_seed(seed, 2, "reference") ^ 0xD1, resolution, workers)
    imgs = []
    for max_depth in (2, -1):
        scene = load_for(job)
        scene.integrator.max_depth = max_depth
        img, _ = render(scene, spp=spp, seed=job.seed, workers=workers)
        imgs.append(np.asarray(img, np.float64))
    return imgs[0], imgs[1] - imgs[0]


def render_aux(scene_path: Path, spp: int = AUX_SPP, seed: int = 0, resolution: tuple[int, int] | None = None,
               workers: int | None = None, progress: Callable[[str], None] | None = None,
               depth: bool = False) -> AuxImages:
    """Render the auxiliary images of ``scene_path`` (see module docstring); ``resolution`` (width, height);
    ``depth``: also brdflab's direct and indirect light (:func:`depth_parts`)."""
    from brdflab.pages.mis_weights import mis_parts
    from brdflab.renderer import render
    from brdflab.stats.jobs import RenderJob, load_for, run_seed

    say = progress or (lambda m: None)
    t0 = time.perf_counter()
    em, bs = mis_parts(Path(scene_path), "direct_mis", spp, seed, resolution, workers)
    job = RenderJob(Path(scene_path), "direct_ems", spp, run_seed(seed, 1, "reference") ^ 0xA77, resolution, workers)
    scene = load_for(job)
    mat = material_map(scene)
    n = len(scene.emitters)
    power = np.array([_power(e) for e in scene.emitters])
    ids = sorted(np.argsort(-power, kind="stable")[:MAX_EMITTERS].tolist()) if n > 1 else list(range(n))
    per = []
    for e in ids if n > 1 else []:  # one scene: only the selection (and the fused light set built from it) changes
        pmf = np.zeros(n)
        pmf[e] = 1.0
        scene.emitter_pmf, scene.emitter_cdf = pmf, np.cumsum(pmf)
        scene.__dict__.pop("_area_light_set", None)
        img, _ = render(scene, spp=spp, seed=job.seed + e, workers=workers)
        per.append(_lum(img))
        say(f"where-and-what: light of emitter {e} rendered")
    if n == 1:
        per.append(_lum(em) + _lum(bs))
    parts = (None, None)
    if depth:
        parts = tuple(_lum(p) for p in depth_parts(scene_path, spp, seed, resolution, workers))
        say("where-and-what: direct and indirect light rendered (path_mis)")
    h, w = mat.shape
    return AuxImages(mat, _lum(em), _lum(bs), np.stack(per) if per else np.zeros((0, h, w)), ids,
                     [material_label(scene, i) for i in range(len(scene.bsdfs))],
                     [emitter_label(scene, e) for e in range(n)], spp=spp, seconds=time.perf_counter() - t0,
                     material_short=[material_label(scene, i, short=True) for i in range(len(scene.bsdfs))],
                     direct_part=parts[0], indirect_part=parts[1])


def _power(e) -> float:
    try:
        return float(e.power())
    except (NotImplementedError, AttributeError):
        return 0.0


def _lum(img: np.ndarray) -> np.ndarray:
    a = np.asarray(img, dtype=np.float64)
    return a.mean(axis=-1) if a.ndim == 3 else a


@dataclass
class Fit:
    """Least-squares fit d ≈ Σ c_k X_k over cells, with HC3 standard errors (see module docstring)."""

    coef: list[float]
    se: list[float]
    p: list[float]
    cells: int
    names: list[str] = field(default_factory=list)

    def significant(self, k: int, level: float = LEVEL) -> bool:
        """True when coefficient ``k`` differs from 0 at two-sided ``level``."""
        return bool(self.p[k] <= level)

    def to_dict(self) -> dict:
        """Plain form for check.json."""
        return {"names": self.names, "coef": self.coef, "se": self.se, "p": self.p, "cells": self.cells}


def cell_means(images: list[np.ndarray], mask: np.ndarray, cell: int = CELL) -> tuple[list[np.ndarray], np.ndarray]:
    """Means over the pixels of ``mask`` in each ``cell`` × ``cell`` cell of every (H, W) image; the cell counts."""
    h, w = mask.shape
    ph, pw = -h % cell, -w % cell
    m = np.pad(mask.astype(np.float64), ((0, ph), (0, pw)))
    cnt = m.reshape((h + ph) // cell, cell, (w + pw) // cell, cell).sum(axis=(1, 3))
    out = []
    for a in images:
        s = np.pad(np.where(mask, a, 0.0), ((0, ph), (0, pw))).reshape(cnt.shape[0], cell, cnt.shape[1], cell)
        with np.errstate(invalid="ignore", divide="ignore"):
            out.append(np.where(cnt > 0, s.sum(axis=(1, 3)) / np.maximum(cnt, 1), 0.0))
    return out, cnt


def fit_cells(d: np.ndarray, xs: list[np.ndarray], names: list[str], mask: np.ndarray,
              cell: int = CELL, wild: int = 0) -> Fit | None:
    """Fit (1) of the (H, W) difference ``d`` on the (H, W) regressors ``xs`` over the cells of ``mask``.

    Each cell (its mean over the pixels in ``mask``) is one observation, weighted by its pixel count; the
    standard errors are HC3 (each squared residual divided by (1 − h_ii)², h the leverage), the p-values
    Student's t with n − k degrees of freedom, or with ``wild`` > 0 the restricted wild bootstrap's from that many
    draws (:mod:`brdflab.stats.wild_bootstrap`: calibrated with few cells, the direct/indirect fit's). Returns
    None with fewer than :data:`MIN_CELLS` cells (or more regressors than cells allow) or singular regressors.

    Examples
    --------
    >>> rng = np.random.default_rng(1)
    >>> e, b = rng.random((32, 32)), rng.random((32, 32))
    >>> f = fit_cells(-0.5 * e + 0.01 * rng.standard_normal((32, 32)), [e, b], ["E", "B"], np.ones((32, 32), bool), 4)
    >>> round(f.coef[0], 1), f.significant(0), f.significant(1)
    (-0.5, True, False)
    """
    means, cnt = cell_means([d, *xs], mask, cell)
    keep = cnt > 0
    y = means[0][keep]
    X = np.stack([m[keep] for m in means[1:]], axis=1)
    wt = np.sqrt(cnt[keep])
    n, k = X.shape
    if n < max(MIN_CELLS, k + 2):
        return None
    Xw, yw = X * wt[:, None], y * wt
    xtx = Xw.T @ Xw
    if not np.all(np.isfinite(xtx)) or np.linalg.cond(xtx) > 1e12:
        return None
    inv = np.linalg.inv(xtx)
    beta, se = (c[:, 0] for c in hc3(Xw, yw[:, None], inv))
    p = wild_p_values(Xw, yw, wild, level=LEVEL) if wild > 0 else 2.0 * stats.t.sf(np.abs(t_values(beta, se)), n - k)
    return Fit([float(v) for v in beta], [float(v) for v in se], [float(v) for v in p], int(n), list(names))


def offset_finding(d: np.ndarray, aux: AuxImages, mask: np.ndarray, sign: int, cell: int = CELL) -> str:
    """A constant offset: d ≈ c + a·E + b·B (path-traced scenes: c + a·D + b·I, so that surfaces lit only
    indirectly count as lit) over every pixel of ``mask`` that is not an emitter seen directly (misses and unlit
    surfaces included, where the parts are 0). A significant c with neither part significant — the same
    difference lit or dark — is a constant added to every pixel (radiance initialised to ε, an ambient term),
    which no light-transport cause explains. "" when there is none."""
    keep = mask & (aux.material >= -1)
    parts, names = ([aux.emitter_part, aux.bsdf_part], ["E", "B"]) if aux.indirect_part is None else \
        ([aux.direct_part, aux.indirect_part], ["D", "I"])
    fit = fit_cells(d, [*parts, np.ones(d.shape)], [*names, "1"], keep, cell)
    if fit is None or not fit.significant(2) or np.sign(fit.coef[2]) != sign or fit.significant(0) \
            or fit.significant(1):
        return ""
    dark = keep & (parts[0] + parts[1] <= 0)
    where = f", in unlit pixels too ({int(dark.sum())} of them)" if dark.any() else ""
    return (f"a constant {'excess' if sign > 0 else 'deficit'} of {fit.coef[2]:+.3g} (±{fit.se[2]:.1g}) per pixel"
            f"{where}, unrelated to the light (d ≈ {_formula(fit)}): the radiance starts from a nonzero value or "
            "a constant is added to every sample")


def _shares(labels: list[str], values: np.ndarray, top: int = 4) -> list[dict]:
    tot = float(values.sum())
    if tot <= 0:
        return []
    order = np.argsort(-values, kind="stable")
    return [{"name": labels[i], "share": float(values[i] / tot)} for i in order[:top] if values[i] > 0.01 * tot]


def describe_region(mask: np.ndarray, d: np.ndarray, y: np.ndarray, aux: AuxImages, integrator: str,
                    sign: int, cell: int = CELL) -> dict:
    """Materials (pixel shares, each with its relative difference), emitters (shares of the direct light) and
    fits (1) of one region ``mask`` (H, W) of the difference ``d`` against brdflab's estimate ``y``."""
    mat = aux.material[mask]
    dm, ym = d[mask], y[mask]
    n = max(int(mask.sum()), 1)
    mats = []
    for code in np.unique(mat):
        sel = mat == code
        share = float(sel.sum()) / n
        if share < 0.05:
            continue
        name = ("background (miss)" if code == -1 else
                f"emitter {aux.emitter_labels[-2 - code]} seen directly" if code <= -2 else aux.material_labels[code])
        ys = float(ym[sel].sum())
        short = name if code < 0 else aux.material_short[code]
        mats.append({"name": name, "short": short, "share": share,
                     "relative_difference": float(dm[sel].sum()) / ys if ys > 0 else None})
    mats.sort(key=lambda m: -m["share"])
    lit = mask & (aux.material >= 0)
    ems = _shares([aux.emitter_labels[e] for e in aux.emitter_ids],
                  np.array([float(p[lit].sum()) for p in aux.per_emitter])) if len(aux.emitter_ids) else []
    if int(lit.sum()) < 4 * MIN_CELLS * cell * cell:  # a small region: smaller cells
        cell = max(2, cell // 2)
    fit = fit_cells(d, [aux.emitter_part, aux.bsdf_part], ["E", "B"], lit, cell)
    ys = float(y[mask].sum())
    direct = float(aux.emitter_part[lit].sum() + aux.bsdf_part[lit].sum())
    lit_share = float(d[lit].sum()) / direct if direct > 0 else None
    offset = offset_finding(d, aux, mask, sign, cell)
    out = {"pixels": int(mask.sum()), "relative_difference": float(d[mask].sum()) / ys if ys > 0 else None,
           "materials": mats[:4], "emitters": ems,
           "emitter_part_share": _part_share(aux, lit),
           "cell": cell, "fit": None if fit is None else fit.to_dict(),
           "finding": offset or interpret(fit, sign, integrator, lit_share),
           "relative_to_direct_light": lit_share}
    if aux.indirect_part is not None:
        dfit = fit_cells(d, [aux.direct_part, aux.indirect_part], ["D", "I"], lit, cell, wild=WILD_DRAWS)
        out["depth_fit"] = None if dfit is None else dfit.to_dict()
        text, kind = depth_finding(dfit, sign)
        out["depth_finding"] = text
        if not offset:  # E and B follow I too in a path-traced image: the E/B reading only within direct light
            out["finding"] = text if kind != "direct" else f"{text}; within the direct light: {out['finding']}"
    if len(aux.emitter_ids) >= 2:
        names = [aux.emitter_labels[e] for e in aux.emitter_ids]
        efit = fit_cells(d, list(aux.per_emitter), names, lit, cell)
        if efit is not None:
            out["emitter_fit"] = efit.to_dict()
            k = lone_emitter(efit, sign)
            if k is not None:
                out["finding"] += (f"; by emitter: only the light of {names[k]} is "
                                   f"{'missing' if sign < 0 else 'in excess'}")
    return out


def lone_emitter(fit: Fit, sign: int) -> int | None:
    """The one emitter whose light alone the difference follows: its coefficient significant with ``sign``,
    every other one significantly smaller in magnitude (|c_j| + z·se_j < |c_k|, z at :data:`LEVEL`)."""
    z = stats.norm.isf(LEVEL / 2)
    c, se = np.abs(fit.coef), np.asarray(fit.se)
    cand = [k for k in range(len(c)) if fit.significant(k) and np.sign(fit.coef[k]) == sign]
    for k in cand:
        if all(c[j] + z * se[j] < c[k] for j in range(len(c)) if j != k):
            return k
    return None


def _part_share(aux: AuxImages, lit: np.ndarray) -> float | None:
    e, b = float(aux.emitter_part[lit].sum()), float(aux.bsdf_part[lit].sum())
    return e / (e + b) if e + b > 0 else None


def regions(signed_map: np.ndarray, block: int, shape: tuple[int, int]) -> list[tuple[int, np.ndarray, dict]]:
    """Connected regions (4-neighbourhood) of equally signed flagged blocks, largest first:
    (sign, pixel mask, bounding box in pixels)."""
    h, w = shape
    out = []
    for sign in (-1, 1):
        lab, k = ndimage.label(signed_map == sign)
        for i, sl in enumerate(ndimage.find_objects(lab), 1):
            m = np.repeat(np.repeat(lab == i, block, 0), block, 1)[:h, :w]
            box = {"x": sl[1].start * block, "y": sl[0].start * block,
                   "w": min(sl[1].stop * block, w) - sl[1].start * block,
                   "h": min(sl[0].stop * block, h) - sl[0].start * block}
            out.append((sign, m, box, int((lab == i).sum())))
    out.sort(key=lambda r: -r[3])
    return [(s, m, dict(box, blocks=nb)) for s, m, box, nb in out]


def attribute(result, user: list[np.ndarray], aux: AuxImages, integrator: str = "", cell: int = CELL,
              estimate: np.ndarray | None = None) -> dict:
    """Where and what of a check (``result``, a :class:`~brdflab.stats.render_check.CheckResult`) of the renders
    ``user``: the whole image and each flagged region (see module docstring); plain dict for check.json.
    ``estimate`` is brdflab's (H, W, 3) estimate (default: ``result.estimate``, set by ``run_check``)."""
    x = _lum(np.mean(np.stack([np.asarray(u, np.float64) for u in user]), axis=0))
    y = _lum(result.estimate if estimate is None else estimate)
    finite = np.isfinite(x) & np.isfinite(y)
    d = np.where(finite, x - y, 0.0)
    y = np.where(finite, y, 0.0)
    sign = -1 if (result.bias or 0.0) < 0 else 1
    whole = describe_region(finite, d, y, aux, integrator, sign, cell)
    regs = []
    for s, m, box in regions(result.signed_map, result.block, d.shape)[:MAX_REGIONS]:
        r = describe_region(m & finite, d, y, aux, integrator, s, cell)
        r.update(box)
        r["sign"] = "too dark" if s < 0 else "too bright"
        regs.append(r)
    return {"aux_spp": aux.spp, "aux_seconds": aux.seconds, "cell": cell, "level": LEVEL,
            "whole_image": whole, "regions": regs, "integrator": integrator}


def attribute_check(result, user: list[np.ndarray], scene_path: Path, integrator: str, seed: int = 0,
                    spp: int = AUX_SPP, workers: int | None = None,
                    progress: Callable[[str], None] | None = None) -> dict | None:
    """Render the auxiliary images at the check's resolution and attribute ``result`` (None when it is
    consistent, nothing to attribute, or ``spp`` is 0)."""
    if result.consistent or result.estimate is None or spp < 1:
        return None
    from brdflab.stats.jobs import PATH_TRACERS

    h, w = result.estimate.shape[:2]
    aux = render_aux(scene_path, spp, seed, (w, h), workers, progress,
                     depth=integrator.split(":")[0] in PATH_TRACERS)
    return attribute(result, user, aux, integrator)
