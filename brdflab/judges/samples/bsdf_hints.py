"""Hints for a file of samples that failed: which bug explains the pdf and weight columns, tested jointly.

Every hint is a *hypothesis tested on the data*, never a guess from one symptom:

* **Pdf column, method-agnostic** (:func:`pdf_corrections`): for each usual bug c(ω) (the 1/(4|ω_o·ω_h|)
  Jacobian missing or applied twice, an extra or a missing cos θ_o, a constant factor), the corrected
  column p_file · c is put through the self-consistency test (:mod:`brdflab.judges.samples.selfconsistency`):
  the hint is given only when the corrected column is consistent with the sampled directions. It does not
  assume brdflab's sampling method.
* **Pdf column, identified against the named BSDF** (:func:`pdf_identity`): the column is compared
  sample by sample with variants of brdflab's pdf: the whole pdf with one of the bugs above, and, for a
  mixture (``roughsubstrate``), each lobe's term alone with a bug (the specular lobe's Jacobian), the
  lobes mixed with another selection probability (fitted), or only the sampled lobe's pdf.
* **Weight column** (:func:`weight_hint`): the ratio to f·cos θ_o / p is matched against products of
  one weight bug (cos θ_i instead of cos θ_o, a missing cos θ_o) and one pdf bug (the weight computed
  with the file's wrong pdf column, or with the right density while the column is wrong): two bugs at
  once are named together.
* **Parameters left at their default** (:func:`fit_defaults`): when the weights fail, each parameter the
  user did not give is fitted to the weights (a grid then golden-section search on the median relative
  error); a fit that makes the weights pass is reported as a warning naming ``--param K=V``.

A candidate matches when the median relative deviation is below 1 % (per-sample tolerance of the
column checks).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from brdflab.judges.samples import selfconsistency as sc

#: Median relative deviation below which a candidate explains a column.
MATCH = 1e-2
LUMINANCE = np.array([0.212671, 0.715160, 0.072169])
#: Samples used to fit a parameter left at its default (an evenly spaced subset).
FIT_SAMPLES = 5_000


def half_terms(wi1: np.ndarray, wo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(ω_h, 4|ω_o·ω_h|) of reflection for unit ω_i and sampled ω_o (N, 3)."""
    h = wi1 + wo
    h = h / np.maximum(np.linalg.norm(h, axis=1), 1e-300)[:, None]
    return h, 4 * np.abs((wo * h).sum(axis=1))


def _median_dev(ratio: np.ndarray, expect: np.ndarray) -> float:
    ok = np.isfinite(ratio) & (ratio > 0) & np.isfinite(expect) & (expect > 0)
    if ok.sum() < 10:
        return np.inf
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        return float(np.median(np.abs(ratio[ok] / expect[ok] - 1)))


def pdf_corrections(binning: sc.Binning, column: np.ndarray, wi1: np.ndarray, wo: np.ndarray, is_bsdf: bool,
                    mass_ratio: float, threshold: float) -> list[tuple[str, np.ndarray]]:
    """Corrections c with which ``column · c`` is self-consistent: [(text, c)], the best first.

    ``wo`` (k, 3) and ``column`` (k,) are the valid samples of ``binning``.
    """
    cands: list[tuple[str, np.ndarray]] = []
    cos_o = np.maximum(wo[:, 2], 1e-12)
    if is_bsdf:
        _, oh4 = half_terms(wi1, wo)
        cands += [("the pdf column lacks the 1/(4|ωo·ωh|) Jacobian (it is the density of ωh, not of ωo)",
                   1 / np.maximum(oh4, 1e-300)),
                  ("the pdf column has the 1/(4|ωo·ωh|) Jacobian twice", oh4)]
    cands += [("the pdf column has an extra factor cos θo", 1 / cos_o),
              ("the pdf column lacks a factor cos θo", cos_o)]
    if np.isfinite(mass_ratio) and mass_ratio > 0 and abs(mass_ratio - 1) > 1e-3:
        cands.append((f"the pdf column is off by a constant factor {1 / mass_ratio:.4g} (a missing normalisation "
                      f"constant, or failed samples not written/counted)", np.full(len(column), mass_ratio)))
    found = []
    for text, c in cands:
        stat, dof, p, *_ = sc.statistic(binning, column * c)
        if dof > 0 and np.isfinite(p) and p > threshold:
            found.append((p, text, c))
    found.sort(key=lambda x: ("constant" in x[1], -x[0]))  # a named cause before a fitted constant
    return [(t, c) for _, t, c in found]


def pdf_identity(column: np.ndarray, ours: np.ndarray, wi1: np.ndarray, wo: np.ndarray, bsdf, is_bsdf: bool
                 ) -> str:
    """What the file's pdf column *is*, in terms of brdflab's pdf of the named BSDF (or ``""``).

    ``bsdf`` is the reference BSDF (for a mixture's lobes), or None for a warp.
    """
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        ratio = column / np.where(ours > 0, ours, np.nan)
    cands: list[tuple[str, np.ndarray]] = []
    cos_o = np.maximum(wo[:, 2], 1e-12)
    if is_bsdf:
        _, oh4 = half_terms(wi1, wo)
        cands += [("the pdf column lacks the 1/(4|ωo·ωh|) Jacobian (it is the density of ωh, not of ωo)", oh4),
                  ("the pdf column has the 1/(4|ωo·ωh|) Jacobian twice", 1 / oh4)]
    cands += [("the pdf column has an extra factor cos θo", cos_o)]
    devs = [(_median_dev(ratio, expect), text) for text, expect in cands]
    lobes = _lobe_terms(bsdf, wi1, wo) if is_bsdf else None
    if lobes is not None:
        devs.append(_lobe_identity(column, lobes, wi1, wo))
    best = min(devs, default=(np.inf, ""))
    # A named bug only where it explains the column decisively better than no bug: a sampler of another method
    # whose density differs from brdflab's by ~1 % (visible normals near normal incidence) matched "an extra
    # cos θo" (cos θo ≈ 0.99 there) and was called wrong.
    ok = np.isfinite(ratio) & (ratio > 0)
    off = float(np.percentile(np.abs(ratio[ok] - 1.0), 90)) if ok.sum() >= 10 else np.inf
    if best[0] < MATCH and off > 3 * MATCH:  # 90 % of the column within 3 % of brdflab's: no bug to name
        return best[1]
    if ok.sum() >= 10:
        med = float(np.median(ratio[ok]))
        # A "constant" of 1 is no explanation: the column agrees on most samples and differs somewhere else.
        if np.median(np.abs(ratio[ok] / med - 1)) < 1e-3 and abs(med - 1) > 1e-2:
            return f"the file's values are brdflab's times a constant {med:.6g} (a missing normalisation factor?)"
    return ""


def _lobe_terms(bsdf, wi1: np.ndarray, wo: np.ndarray):
    """(p_s, p_specular, p_diffuse) of a two-lobe mixture with brdflab's interface, else None."""
    inner = getattr(bsdf, "inner", bsdf)
    if not (hasattr(inner, "lobe") and hasattr(inner, "_p_specular")) or getattr(inner, "lobe", "both") != "both":
        return None
    wi = np.ascontiguousarray(np.broadcast_to(wi1, (len(wo), 3)))
    saved = inner.lobe
    try:
        inner.lobe = "specular"
        p_spec = inner.pdf(wi, wo)
        inner.lobe = "diffuse"
        p_diff = inner.pdf(wi, wo)
    finally:
        inner.lobe = saved
    ps = float(np.asarray(inner._p_specular(np.array([wi1[2]])))[0])
    return ps, p_spec, p_diff


def _lobe_identity(column: np.ndarray, lobes, wi1: np.ndarray, wo: np.ndarray) -> tuple[float, str]:
    """(median relative deviation, text) of the mixture variant that best explains the column."""
    ps, p_spec, p_diff = lobes
    _, oh4 = half_terms(wi1, wo)
    one = np.ones(len(column))
    cands = [("the specular lobe's pdf term lacks the 1/(4|ωo·ωh|) Jacobian (the diffuse term is right)",
              ps * p_spec * oh4 + (1 - ps) * p_diff),
             ("the specular lobe's pdf term has the 1/(4|ωo·ωh|) Jacobian twice",
              ps * p_spec / oh4 + (1 - ps) * p_diff),
             ("the diffuse lobe's pdf term has an extra factor cos θo", ps * p_spec + (1 - ps) * p_diff * wo[:, 2]),
             ("the lobe pdfs are added without their selection probabilities", p_spec + p_diff)]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        out = [(_median_dev(column / col, one), text) for text, col in cands]
        # Another selection probability s′: column = s′ p_spec + (1 − s′) p_diff, fitted where the lobes differ.
        d = p_spec - p_diff
        big = np.abs(d) > 0.1 * np.maximum(p_spec, p_diff)
        if big.sum() >= 10:
            s_fit = float(np.median(((column - p_diff) / np.where(big, d, 1.0))[big]))
            if 0 <= s_fit <= 1 and abs(s_fit - ps) > 1e-3:
                col = s_fit * p_spec + (1 - s_fit) * p_diff
                out.append((_median_dev(column / col, one),
                            f"the pdf column mixes the lobes with specular probability {s_fit:.4g} (brdflab's "
                            f"sampler uses {ps:.4g})"))
        # Only the sampled lobe's pdf (not the mixture): every sample matches one lobe's pdf.
        dev = np.minimum(np.abs(column / p_spec - 1), np.abs(column / p_diff - 1))
    dev = np.where(np.isfinite(dev), dev, np.inf)
    if len(dev) >= 10 and np.mean(dev < MATCH) > 0.99:
        out.append((0.0, "the pdf column is the pdf of the sampled lobe alone, not of the mixture (weight it by the "
                         "selection probabilities and add the other lobe's)"))
    return min(out)


def microfacet_weight_bugs(bsdf, wi1: np.ndarray, wo: np.ndarray) -> list[tuple[str, np.ndarray]]:
    """The usual bugs of a microfacet conductor's f, as factors f_bug / f at each ω_o (luminance): Fresnel at
    n·ω_i instead of ω_h·ω_i, a missing G1(ω_o) or G1(ω_i), G1(ω_i) twice. Empty for other BSDFs (their f has
    no such terms, or they are not brdflab's conductor)."""
    from brdflab.bsdf.fresnel import fresnel_schlick
    from brdflab.bsdf.microfacet import half_vector, smith_g1
    from brdflab.bsdf.roughconductor import RoughConductor

    if type(bsdf) is not RoughConductor or not (bsdf.R0.constant and bsdf.alpha.constant):
        return []
    a, r0 = float(bsdf.alpha.luminance()), np.broadcast_to(np.asarray(bsdf.R0.mean(), dtype=np.float64), (3,))
    wi = np.ascontiguousarray(np.broadcast_to(wi1, (len(wo), 3)))
    wh, _ = half_vector(wi, wo)
    hi = np.abs(np.sum(wi * wh, axis=1))
    with np.errstate(divide="ignore", invalid="ignore"):
        fres = (fresnel_schlick(np.full(len(wo), wi1[2]), r0) @ LUMINANCE) / (fresnel_schlick(hi, r0) @ LUMINANCE)
        g_o, g_i = smith_g1(wo, wh, a), smith_g1(wi, wh, a)
        return [("the Fresnel term uses cos θi (n·ωi) instead of ωh·ωi", fres),
                ("a G1(ωo) factor is missing", 1.0 / g_o), ("a G1(ωi) factor is missing", 1.0 / g_i),
                ("G1(ωi) appears twice", g_i)]


def weight_hint(ratio: np.ndarray, wi1: np.ndarray, wo: np.ndarray, pdf_fix: np.ndarray | None,
                pdf_text: str = "", model_bugs: list[tuple[str, np.ndarray]] | None = None) -> str:
    """Name the weight bug(s) from w_file / (f·cos/p) — one weight bug and one pdf bug, jointly.

    ``pdf_fix`` is p_true / p_file when the pdf column is wrong and the true density is known (else None);
    ``model_bugs`` adds the usual bugs of the BSDF's own terms (:func:`microfacet_weight_bugs`), tried alone and
    with the cosine bugs and the pdf bug (two bugs at once must not hide one). When no combination explains
    the ratio, the hint says so instead of staying silent.
    """
    cos_o = np.maximum(wo[:, 2], 1e-12)
    wbugs = [("", np.ones(len(wo))), ("the weight uses cos θi instead of cos θo", wi1[2] / cos_o),
             ("the weight lacks the cos θo factor", 1 / cos_o), ("the weight has cos θo twice", cos_o)]
    for mt, mf in model_bugs or []:
        wbugs += [(mt if not t else f"{mt} and {t}", mf * f) for t, f in wbugs[:4]]
    pbugs = [("", None)]
    if pdf_fix is not None:
        pbugs += [("the weight is f·cos/pdf with the file's wrong pdf column", pdf_fix)]
    for pt, pf in pbugs:
        for wt, wf in wbugs:
            if not wt and not pt:
                continue
            expect = wf * (pf if pf is not None else 1.0)
            if _median_dev(ratio, expect) < MATCH:
                return " and ".join(t for t in (wt, pt) if t)
    ok = np.isfinite(ratio) & (ratio > 0)
    if ok.sum() >= 10:
        med = float(np.median(ratio[ok]))
        if np.median(np.abs(ratio[ok] / med - 1)) < 1e-3 and abs(med - 1) > 1e-2:
            return f"the weights are the expected ones times a constant {med:.6g} (a parameter left at its default, " \
                   "or a missing factor?)"
        if np.median(np.abs(ratio[ok] - 1)) > 1e-3:
            q = np.percentile(ratio[ok], [10, 50, 90])
            return (f"unexplained: weight / (f·cos θo/p) varies ({q[0]:.3g} … {q[1]:.3g} … {q[2]:.3g}, 10/50/90 %) "
                    "and none of the usual bugs (cosines, Fresnel's cosine, G1 factors, the pdf) fits it alone or in "
                    "pairs: compare f itself with the model's formula")
    return ""


def fit_defaults(make: Callable[[dict], object], defaults: dict, given: dict, wi1: np.ndarray, wo: np.ndarray,
                 pdf_ref: np.ndarray, weights: np.ndarray, column: str = "weight") -> list[str]:
    """Parameters left at their default that the weights (or the pdf column) fit at another value: warnings
    naming ``--param``.

    Parameters
    ----------
    make
        ``make(params) → BSDF`` (α fixed).
    defaults
        Parameter name → default value (floats or colours are fitted; others skipped).
    given
        Parameters the user gave (not fitted).
    pdf_ref
        (k,) the density the weights should divide by.
    weights
        (k, 3) the file's weights of the same samples; with ``column="pdf"``, (k,) the file's pdf column
        (fitted against the BSDF's pdf; ``pdf_ref`` unused).
    """
    from scipy.optimize import minimize_scalar

    if len(wo) > FIT_SAMPLES:  # a median needs no more; keeps ~100 evaluations per parameter cheap
        keep = np.linspace(0, len(wo) - 1, FIT_SAMPLES).astype(int)
        wo, pdf_ref, weights = wo[keep], pdf_ref[keep], weights[keep]
    wi = np.ascontiguousarray(np.broadcast_to(wi1, (len(wo), 3)))
    cos_o = wo[:, 2]

    pdf_fit = column == "pdf"

    def errs(params, ch):
        try:
            with np.errstate(all="ignore"):
                ours = make(params).pdf(wi, wo) if pdf_fit else make(params).eval(wi, wo)[:, ch] * cos_o / pdf_ref
        except Exception:  # noqa: BLE001 - an out-of-range trial value is just a bad fit
            return np.inf
        good = np.isfinite(ours) & (ours > 0)
        if good.sum() < 10:
            return np.inf
        mine = weights[good] if pdf_fit else weights[good, ch]
        return float(np.median(np.abs(mine / ours[good] - 1)))

    out = []
    for key, dflt in defaults.items():
        if key in given or key == "alpha":
            continue
        arr = np.asarray(dflt, dtype=float) if isinstance(dflt, float | int | list | tuple | np.ndarray) \
            and not isinstance(dflt, bool) else None
        if arr is None or arr.size not in (1, 3):
            continue
        fitted = []
        for ch in range(3):
            base = float(np.ravel(arr)[ch if arr.size == 3 else 0])

            def err(v, ch=ch, key=key, arr=arr):
                return errs({**given, key: (np.full(3, v) if arr.size == 3 else v)}, ch)

            e0 = err(base)
            if e0 < MATCH or abs(err(base + 0.1 * (1 + abs(base))) - e0) < 1e-12:  # fits already, or no effect
                fitted.append(None)
                if arr.size == 1 or pdf_fit:
                    break
                continue
            lo, hi = (0.0, 1.0) if 0 <= base <= 1 else (base / 4, base * 4)
            grid = np.linspace(lo, hi, 41)
            errs_g = np.array([err(v) for v in grid])
            fits = []
            for i in np.argsort(errs_g)[:3]:  # refine the three best grid points (the error can have several basins)
                a, b = grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)]
                res = minimize_scalar(err, bounds=(a, b), method="bounded", options={"xatol": 1e-6})
                if res.fun < MATCH:
                    fits.append((float(res.fun), float(res.x)))
            # The best fit; among exact ones (a Fresnel term at normal incidence is the same for η and 1/η) the
            # nearest to the default, the likelier intent.
            exact = [x for f, x in fits if f < 1e-4]
            fitted.append(min(exact, key=lambda x: abs(x - base)) if exact else (min(fits)[1] if fits else np.nan))
            if arr.size == 1 or pdf_fit:
                break
        if not fitted or any(v is not None and np.isnan(v) for v in fitted) or all(v is None for v in fitted):
            continue
        vals = [v if v is not None else float(np.ravel(arr)[i if arr.size == 3 else 0]) for i, v in enumerate(fitted)]
        shown = f"{vals[0]:.4g}" if len(vals) == 1 or np.ptp(vals) < 1e-3 else ",".join(f"{v:.4g}" for v in vals)
        dshown = f"{float(np.ravel(arr)[0]):g}" if np.ptp(np.ravel(arr)) == 0 else \
            ",".join(f"{v:g}" for v in np.ravel(arr))
        what = "the pdf column fits" if pdf_fit else "the weights fit"
        out.append(f"WARNING: {key} was left at its default {dshown}, but {what} {key} = {shown}: "
                   f"pass --param {key}={shown}")
        break  # one explanation (parameters can be interchangeable: only η_int/η_ext matters to a Fresnel term)
    return out
