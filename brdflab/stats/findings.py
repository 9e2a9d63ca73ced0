"""The sentences of ``brdflab check``'s where and what (:mod:`brdflab.stats.attribution` fits, this module says).

Two fits of the difference d = yours − brdflab's over cells of a region (:func:`brdflab.stats.attribution.fit_cells`):

* d ≈ a·E + b·B, the emitter-sampled and BSDF-sampled parts of the direct light (:func:`interpret`);
* for a path-traced scene, d ≈ a·D + b·I, brdflab's own path estimate split by path length
  (:func:`depth_finding`): D the paths of at most two segments (camera → surface → emitter: direct light), I the
  longer ones (indirect light). b is then the relative error of your indirect light: b = −0.05 reads "your
  indirect light is 5 % short", b ≈ −1 "indirect light is missing".

A coefficient counts when significant at the fit's level (two-sided, HC3 standard errors, Student's t); what
the scene's integrator cannot produce is never named as a cause.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
from scipy import stats


class Fit(Protocol):
    """What a sentence reads of a fit (:class:`brdflab.stats.attribution.Fit`)."""

    coef: list[float]
    se: list[float]
    names: list[str]

    def significant(self, k: int) -> bool: ...

#: Regions printed on the command line (the others are in check.json and check.html).
PRINTED = 3
#: Indirect light is "missing" when b ≤ −0.8 or b's two-sided interval at this level holds −1.
LEVEL_MISSING = 0.01

#: What a difference that follows each part points at.
CAUSE = {"E": "emitter-sampled light (light sampling / visibility: the shadow test, the light's pdf or radiance)",
         "B": "BSDF-sampled light (BSDF sampling: its weight or pdf, or the emission found by BSDF rays)"}
#: What a difference proportional to all direct light points at, by the integrator the scene asks for.
ALL_LIGHT = {
    "direct_ems": "the scene's direct_ems samples only emitters, so this points at light sampling / visibility "
                  "(shadow test, light pdf or selection probability) or the BSDF's eval",
    "direct_mats": "the scene's direct_mats samples only BSDFs, so this points at BSDF sampling (weight, pdf) "
                   "or the emission found by BSDF rays",
    "direct_mis": "both strategies lose it alike: look at what they share (the BSDF's eval, the emitted "
                  "radiance) or at a wrong MIS weight sum"}


#: Integrators that produce only one of the two parts: whatever part a difference follows, its cause is there.
ONE_STRATEGY = {"direct_ems": "E", "direct_mats": "B", "path": "B"}
#: One coefficient "dominates" the other when the other is smaller than this share of it.
DOMINANT = 0.2


def _formula(fit: Fit) -> str:
    return " ".join(f"{c:+.2f}(±{e:.2f})·{n}" for c, e, n in zip(fit.coef, fit.se, fit.names or ["E", "B"],
                                                                  strict=False))


def interpret(fit: Fit | None, sign: int, integrator: str = "", lit_share: float | None = None) -> str:
    """One sentence: which part the difference (of ``sign`` −1 deficit, +1 excess) follows, what that points at,
    and the fit it rests on (see module); ``lit_share`` is the difference relative to brdflab's direct light
    E + B there. What the scene's integrator cannot produce is never named as the cause: a BSDF-only
    integrator (``direct_mats``, ``path``) has no emitter-sampled part, an emitter-only one no BSDF-sampled part.
    Both parts significant with opposite signs is the signature of MIS weights that do not add up to 1."""
    if fit is None:
        return "too few cells to fit"
    word = "deficit" if sign < 0 else "excess"
    a, b = fit.coef[0], fit.coef[1]
    sig_a, sig_b = fit.significant(0), fit.significant(1)
    sa, sb = sig_a and np.sign(a) == sign, sig_b and np.sign(b) == sign
    formula = f" (d ≈ {_formula(fit)})"
    if sig_a and sig_b and np.sign(a) != np.sign(b):
        short, more = ("emitter-sampled", "BSDF-sampled") if a < 0 else ("BSDF-sampled", "emitter-sampled")
        return (f"{short} light is short ({100 * min(a, b):+.0f} % of it) while {more} light is in excess "
                f"({100 * max(a, b):+.0f} %){formula}: the two strategies' weights do not add up to 1 — look at the "
                "MIS weights (both densities in solid angle, the emitter-selection probability included in p_light)")
    only = ONE_STRATEGY.get(integrator.split(":")[0])
    if only and (sa or sb):
        size = "" if lit_share is None else f", {100 * lit_share:+.0f} % of it"
        cause = ALL_LIGHT[integrator.split(":")[0]] if integrator.split(":")[0] in ALL_LIGHT else \
            f"the scene's {integrator} samples only BSDFs: this points at BSDF sampling (weight, pdf) or the " \
            "emission found by BSDF rays"
        return f"the {word} follows direct light{size}{formula}: {cause}"
    lo, hi = sorted((abs(a), abs(b)))
    if sa and (not sig_b or (sb and abs(b) < DOMINANT * abs(a))):
        return f"the {word} follows {CAUSE['E']}{formula}"
    if sb and (not sig_a or (sa and abs(a) < DOMINANT * abs(b))):
        return f"the {word} follows {CAUSE['B']}{formula}"
    if sa and sb:
        if hi > 0 and lo / hi > 0.5:
            hint = ALL_LIGHT.get(integrator.split(":")[0], "")
            size = "" if lit_share is None else f" ({100 * lit_share:+.0f} % of it)"
            return (f"the {word} follows all direct light{size}{formula}"
                    + (f": {hint}" if hint else ""))
        return f"the {word} follows both parts unequally{formula}: nothing definite"
    return "nothing definite (neither part, or both with opposite signs)"


#: What a difference in the indirect light alone points at (paths of three or more segments).
INDIRECT = ("look at what only the longer paths do: the throughput update at later vertices (β ← β·f|cos θ|/p), "
            "Russian roulette's compensation (survivors divided by their survival probability), the continuation "
            "ray (origin offset, direction turned to world space) and the emitter-hit rule after the first bounce")
#: What a render without indirect light is.
MISSING = ("the render holds direct light only: a direct integrator, maxDepth 2, or paths that never continue past "
           "their first vertex")
#: What a difference proportional to all light, direct and indirect alike, points at.
EVERY_BOUNCE = ("look at what every bounce shares: the BSDF's eval, the emitted radiance, or a scale of the whole "
                "image (film, exposure)")


def depth_finding(fit: Fit | None, sign: int) -> tuple[str, str | None]:
    """(sentence, kind) from the fit d ≈ a·D + b·I of a path-traced scene (module docstring), for a difference of
    ``sign`` (−1 deficit, +1 excess). ``kind``: ``"indirect"`` (the difference follows indirect light alone:
    short, in excess or missing), ``"direct"`` (direct light alone: the caller adds the E/B finding),
    ``"all"``, ``"mixed"`` (opposite signs), or None (nothing definite).

    Examples
    --------
    >>> from brdflab.stats.attribution import fit_cells
    >>> rng = np.random.default_rng(2)
    >>> D, I = 1 + rng.random((64, 64)), 0.5 * rng.random((64, 64))
    >>> f = fit_cells(-0.05 * I + 1e-3 * rng.standard_normal(I.shape), [D, I], ["D", "I"], np.ones(D.shape, bool), 4)
    >>> text, kind = depth_finding(f, -1)
    >>> kind, text.split(" (")[0]
    ('indirect', 'your indirect light is 5 % short')
    """
    if fit is None:
        return "too few cells to fit", None
    a, b = fit.coef[0], fit.coef[1]
    sig_a, sig_b = fit.significant(0), fit.significant(1)
    sa, sb = sig_a and np.sign(a) == sign, sig_b and np.sign(b) == sign
    formula = f" (d ≈ {_formula(fit)}; D = direct, I = indirect light)"
    if sig_a and sig_b and np.sign(a) != np.sign(b):
        return (f"direct light is {'short' if a < 0 else 'in excess'} ({100 * a:+.0f} % of it) while indirect light "
                f"is {'short' if b < 0 else 'in excess'} ({100 * b:+.0f} %){formula}: look at the weights that "
                "split the light between the first vertex and the later ones (next-event estimation and MIS at "
                "later vertices, emission found by BSDF rays counted twice or not at all)", "mixed")
    if sb and (not sig_a or abs(a) < DOMINANT * abs(b)):
        z = stats.norm.isf(LEVEL_MISSING / 2)
        if sign < 0 and (b <= -0.8 or abs(b + 1.0) <= z * fit.se[1]):
            return f"indirect light is missing ({100 * b:+.0f} % of it){formula}: {MISSING}", "indirect"
        word = "short" if b < 0 else "in excess"
        return (f"your indirect light is {100 * abs(b):.0f} % {word}{formula}: {INDIRECT}", "indirect")
    if sa and (not sig_b or abs(b) < DOMINANT * abs(a)):
        return (f"the {'deficit' if sign < 0 else 'excess'} follows direct light ({100 * a:+.0f} % of it), "
                f"indirect light agrees{formula}", "direct")
    if sa and sb:
        lo, hi = sorted((abs(a), abs(b)))
        if hi > 0 and lo / hi > 0.5:
            return (f"the {'deficit' if sign < 0 else 'excess'} follows all light, direct ({100 * a:+.0f} %) and "
                    f"indirect ({100 * b:+.0f} %) alike{formula}: {EVERY_BOUNCE}", "all")
        return f"the difference follows direct and indirect light unequally{formula}: nothing definite", None
    return f"nothing definite about direct versus indirect light{formula}", None


def _fit_text(f: dict | None) -> str:
    if not f:
        return "no fit"
    terms = " ".join(f"{c:+.2f}(±{s:.2f})·{n}" for c, s, n in zip(f["coef"], f["se"], f.get("names") or ["E", "B"],
                                                                   strict=False))
    return f"d ≈ {terms} over {f['cells']} cells"


def _list_text(items: list[dict]) -> str:
    return ", ".join(f"{i.get('short', i['name'])} {100 * i['share']:.0f} %" for i in items) or "none"


def _fits_text(r: dict) -> str:
    return _fit_text(r["fit"]) + (f"; {_fit_text(r['depth_fit'])}" if r.get("depth_fit") else "")


def attribution_lines(att: dict, printed: int = PRINTED) -> list[str]:
    """A few lines for the command line: the whole image and the largest ``printed`` regions."""
    w = att["whole_image"]
    depth = "; D = direct, I = indirect light (brdflab's path_mis by path length)" if "depth_fit" in w else ""
    lines = [f"where and what (auxiliary renders, {att['aux_spp']} spp, {att['aux_seconds']:.1f} s; E = "
             f"emitter-sampled, B = BSDF-sampled light{depth}): whole image: {_fits_text(w)}: {w['finding']}"]
    for i, r in enumerate(att["regions"][:printed], 1):
        rel = "" if r["relative_difference"] is None else f" {100 * r['relative_difference']:+.1f} %"
        lines.append(f"  region {i} ({r['sign']}{rel}, {r['blocks']} blocks at x {r['x']}…{r['x'] + r['w']}, "
                     f"y {r['y']}…{r['y'] + r['h']}): materials {_list_text(r['materials'])}; emitters "
                     f"{_list_text(r['emitters'])}; {_fits_text(r)}: {r['finding']}")
    if len(att["regions"]) > printed:
        lines.append(f"  … {len(att['regions']) - printed} more region(s) in check.json / check.html")
    return lines
