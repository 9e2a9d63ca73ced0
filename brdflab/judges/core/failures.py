"""The failures of a validation battery, grouped: one line per cause, with the α/θ points it covers.

A BSDF with one bug fails dozens of tests (every α and θ of the chi-square sweep, consistency, furnace);
listing each is noise that hides the cause. :func:`grouped_failures` groups them:

* the chi-square failures of one BSDF are **diagnosed** (:func:`diagnose`): for one failing test per α,
  the BSDF's own samples (directions and the pdf ``sample()`` reports) are put through the method-agnostic
  self-consistency test with the usual pdf bugs corrected (:func:`brdflab.judges.samples.bsdf_hints.pdf_corrections`:
  the 1/(4|ω_o·ω_h|) Jacobian missing or twice, a cos θ_o, a constant); a correction that makes them
  consistent names the cause. Failures with the same cause form one line; otherwise they are grouped by
  their symptom (the fault text with its numbers removed);
* consistency and furnace failures are grouped per BSDF and symptom the same way, each furnace point with
  its α;
* everything else is listed as before (:meth:`brdflab.judges.material.battery.Battery.failures`).
"""

from __future__ import annotations

import re
from collections import OrderedDict

import numpy as np

from brdflab.judges.material import chi2 as c2

_NUM = re.compile(r"[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?σ?")


def _symptom(text: str | None) -> str:
    """A fault text with its numbers replaced by '#' (the key of a group)."""
    return _NUM.sub("#", text or "").strip()


def _fmt(v) -> str:
    return "?" if v is None else (f"{v:g}" if isinstance(v, float | int) else str(v))


def _points(points: list[tuple]) -> str:
    """'α=0.1: θ=0,30; α=0.3: θ=60' from (α, θ) pairs (α None: 'θ=0,30'; α may be a label string)."""
    by_a: OrderedDict = OrderedDict()
    for a, t in points:
        by_a.setdefault(a, []).append(t)
    parts = []
    for a, ts in by_a.items():
        th = "θ=" + ",".join(_fmt(t) for t in ts)
        parts.append(th if a is None or a == "" else (f"{a}: {th}" if isinstance(a, str) else f"α={_fmt(a)}: {th}"))
    return "; ".join(parts)


def _label(params: dict) -> str:
    """α and the other parameters of a test (not θ), e.g. 'α=0.1' or 'exponent=20'."""
    bits = [f"α={_fmt(params['alpha'])}"] if params.get("alpha") is not None else []
    bits += [f"{k}={_fmt(v)}" for k, v in params.items() if k not in ("alpha", "theta", "phi") and v is not None]
    return " ".join(bits)


def diagnose(result: c2.Chi2Result, n: int = 20_000, seed: int = 0, entry=None) -> str:
    """The pdf bug that explains a failed BSDF chi-square test, or ``""`` (see the module docstring).

    The directions drawn by ``sample()`` are tested against ``pdf()`` evaluated at them (what the chi-square
    test compares), corrected for each usual bug. ``entry`` (a battery entry) rebuilds a BSDF that is not
    known by name.
    """
    from brdflab.judges.samples import bsdf_hints as hints
    from brdflab.judges.samples import selfconsistency as sc
    from brdflab.pages.chi2_views import Sampler, sampler_of

    prm = dict(result.params or {})
    theta = prm.pop("theta", None)
    phi = float(prm.pop("phi", 0.0) or 0.0)
    if theta is None:
        return ""
    wi1 = c2.incident(float(theta), phi)
    s = sampler_of(result) if entry is None else None
    if s is None and entry is not None:
        try:
            bsdf = entry.make(prm.pop("alpha", None), prm)
        except Exception:  # noqa: BLE001 - its constructor's error is a verdict already
            return ""

        def smp(u, b=bsdf):
            r = b.sample(np.ascontiguousarray(np.broadcast_to(wi1, (len(u), 3))), u)
            return r.wo, r.pdf

        s = Sampler(smp, lambda d, b=bsdf: b.pdf(np.ascontiguousarray(np.broadcast_to(wi1, (len(d), 3))), d),
                    np.array([0.0, 0.0, 1.0]))
    if s is None or s.axis is None:
        return ""
    try:
        rng = np.random.default_rng(seed)
        pw, pp = s.sample(rng.random((n, 3)))
        w, p = s.sample(rng.random((n, 3)))
        ok = (p > 0) & (w[:, 2] > 0)
        if ok.sum() < 100:
            return ""

        def ref(d):
            return np.where(d[:, 2] > 0, s.pdf(d), 0.0)

        b = sc.make_binning(w[ok], n, ref, pw[(pp > 0) & (pw[:, 2] > 0)], rng)
        col = np.asarray(s.pdf(w[ok]), dtype=float)
        stat, dof, pv, _, ratio, _ = sc.statistic(b, col)
        if pv > c2.SIGNIFICANCE:
            return ""
        fixes = hints.pdf_corrections(b, col, wi1, w[ok], True, ratio, c2.SIGNIFICANCE)
    except Exception:  # noqa: BLE001 - a plugin that raises has its verdict already
        return ""
    if not fixes:
        return ""
    text = fixes[0][0].replace("the pdf column", "pdf()").replace("the file's values", "pdf()'s values")
    return f"{text} — with it corrected, sample() and pdf() agree"


def grouped_failures(bat, diagnose_chi2: bool = True, bsdfs=None) -> list[str]:
    """One line per cause: chi-square, consistency and furnace failures grouped (module docstring), then the
    remaining failures of :meth:`~brdflab.judges.material.battery.Battery.failures`.

    ``bsdfs`` (as for :func:`~brdflab.judges.material.battery.resolve_bsdfs`) rebuilds BSDFs not known by name for
    the diagnosis.
    """
    out: list[str] = []
    causes: dict[str, str] = {}
    entries = {}
    if bsdfs is not None:
        from brdflab.judges.material.battery import resolve_bsdfs

        entries = {e.name: e for e in resolve_bsdfs(bsdfs)}
    fails = [r for r in bat.chi2 if not r.passed]
    if diagnose_chi2:
        seen: set = set()
        for r in fails:
            a = (r.params or {}).get("alpha")
            if (r.name, a) in seen or r.name in causes and causes[r.name]:
                continue
            seen.add((r.name, a))
            d = diagnose(r, entry=entries.get(r.name))
            if d:
                causes[r.name] = d
    groups: OrderedDict = OrderedDict()
    for r in fails:
        cause = causes.get(r.name) or _symptom(r.fault) or "p ≤ threshold"
        groups.setdefault((r.name, cause), []).append(r)
    for (name, cause), rs in groups.items():
        pts = _points([(_label(r.params or {}), (r.params or {}).get("theta")) for r in rs])
        integ = [r.integral for r in rs if np.isfinite(r.integral)]
        sym = "" if not integ or max(abs(x - 1) for x in integ) < 2e-3 else \
            (f"; ∫ p dω = {integ[0]:.4g}" if len(integ) == 1 else f"; ∫ p dω from {min(integ):.4g} to {max(integ):.4g}")
        if name in causes:
            line = f"FAIL chi2 {name}: {cause} ({len(rs)} tests: {pts}{sym})"
        elif cause == "p ≤ threshold":
            line = f"FAIL chi2 {name}: the samples do not follow pdf() (p ≤ {rs[0].threshold:.2g}; {len(rs)} tests: " \
                   f"{pts}{sym})"
        else:
            line = f"FAIL chi2 {name}: {rs[0].fault} ({len(rs)} tests: {pts}{sym})"
        out.append(line + _jacobian_note(rs, name in causes))
    cons: OrderedDict = OrderedDict()
    for r in bat.consistency:
        if not r.passed:
            base = r.name.split(" α=")[0]
            cons.setdefault((base, causes.get(base) or _symptom(_consistency_what(r))), []).append(r)
    for (base, _), rs in cons.items():
        pts = _points([(_label(r.params or {}), r.theta) for r in rs])
        what = _consistency_what(rs[0])
        if base in causes:
            out.append(f"FAIL consistency {base}: {causes[base]} ({len(rs)} checks: {pts}; e.g. {what})")
        else:
            out.append(f"FAIL consistency {base}: {what} ({len(rs)} checks: {pts})")
    furn: OrderedDict = OrderedDict()
    for p in bat.albedo:
        if not p.passed:
            base = p.name.split()[0]
            why = p.fault or ("eval, pdf and sample disagree" if not p.agree else "") + \
                ("; ρ > 1: energy created" if not p.energy_ok else "")
            furn.setdefault((p.name, causes.get(base) or _symptom(why)), []).append(p)
    for (name, _), ps in furn.items():
        pts = _points([(p.alpha, p.theta) for p in ps])
        base = name.split()[0]
        first = ps[0]
        why = first.fault or (f"quadrature ρ {first.quadrature:.4g} vs Monte Carlo {first.monte_carlo:.4g} at "
                              f"α={_fmt(first.alpha)}, θ={first.theta:g} (eval, pdf and sample do not describe the "
                              "same BSDF)" if not first.agree else f"ρ = {first.quadrature:.4g} > 1 at "
                              f"α={_fmt(first.alpha)}, θ={first.theta:g}")
        if base in causes:
            out.append(f"FAIL furnace {name}: {causes[base]} ({len(ps)} points: {pts}; e.g. {why})")
        else:
            out.append(f"FAIL furnace {name}: {why} ({len(ps)} points: {pts})")
    import dataclasses

    out.extend(dataclasses.replace(bat, chi2=[], consistency=[], albedo=[]).failures())
    return out


def _consistency_what(r) -> str:
    return "; ".join(r.problems) if getattr(r, "problems", None) else (r.fault or r.message)


def _jacobian_note(rs: list[c2.Chi2Result], named: bool) -> str:
    """∫ p dω ≈ 4 at normal incidence is the signature of the missing Jacobian (4|ω_o·ω_h| = 4 there)."""
    if named:
        return ""
    for r in rs:
        if (r.params or {}).get("theta") == 0 and np.isfinite(r.integral) and abs(r.integral - 4) < 0.1:
            return " — ∫ p dω ≈ 4 at normal incidence: pdf() likely lacks the 1/(4|ωo·ωh|) Jacobian"
    return ""
