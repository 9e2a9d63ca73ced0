"""The validation battery: every warp and BSDF through chi-square, consistency, furnace and stability.

:func:`run_battery` returns a :class:`Battery` that the CLI prints and
:mod:`brdflab.pages.validation` turns into an HTML report. It runs on the built-in BSDFs or on any
BSDFs given to it (a user's plugin): names (built-in, or resolved by the plugin registry
``brdflab.plugins.make_bsdf``), BSDF instances, classes, ``(name, factory(alpha, params))`` pairs,
:class:`BSDFEntry` objects, or names with a ``make(name, alpha, params)`` callable. A BSDF without an
``alpha`` parameter is swept over θ only; a class attribute ``sweep = {"exponent": [5, 20, 100]}`` adds
its grid to the sweep (parameters given explicitly are not swept). The chi-square tests share one family-wise
significance of 0.01 (Šidák-corrected for their number). The **negative controls** — the rough conductor
with its pdf missing the 1/(4|ω_o·ω_h|) Jacobian, the GGX visible-normal pdf without G1(ω_i), samplers with
α_u and α_v swapped — must be rejected, or the harness itself is broken.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from brdflab.judges.core.seeding import test_seed
from brdflab.judges.material import chi2 as c2
from brdflab.judges.material import consistency, furnace, stability
from brdflab.judges.material.entries import (  # noqa: F401 (re-exported: the module's former contents)
    BSDFS,
    CONDUCTOR_CONTROLS,
    FURNACE_ALPHAS,
    POINT_WARPS,
    WARPS,
    BSDFEntry,
    NoJacobianConductor,
    _builtin,
    _class_entry,
    _from_class,
    _from_registry,
    _takes_alpha,
    furnace_name,
    furnace_parameters,
    has_alpha,
    make_named_bsdf,
    resolve_bsdfs,
)

ALPHAS = (1e-3, 0.005, 0.05, 0.1, 0.3, 0.5, 1.0)
THETAS = (0.0, 30.0, 60.0, 80.0, 89.0)
FURNACE_THETAS = tuple(float(t) for t in range(0, 90, 5))
#: Incident angles from inside for the furnace of two-sided (transmissive) BSDFs.
INSIDE_FURNACE_THETAS = (100.0, 120.0, 150.0, 175.0)


def _why(r) -> str:
    """A control's p-value, and the fault that rejected it whatever the p-value (e.g. ∫ p dω > 1)."""
    return f"p = {r.p_value:.3g}" + (f" ({r.fault})" if r.fault else "")


def _seed(*parts) -> int:
    """A distinct, reproducible seed per test (so tests do not share their random numbers)."""
    return zlib.crc32(repr(parts).encode())


@dataclass
class Battery:
    """All results of a validation run."""

    chi2: list[c2.Chi2Result] = field(default_factory=list)
    negative_control: list[c2.Chi2Result] = field(default_factory=list)
    consistency: list[consistency.ConsistencyResult] = field(default_factory=list)
    albedo: list[furnace.AlbedoPoint] = field(default_factory=list)
    stability: list[stability.StabilityRow] = field(default_factory=list)
    threshold: float = c2.SIGNIFICANCE
    # -- light transport (brdflab.judges.lights.samplers / agreement) --
    emitter_chi2: list[c2.Chi2Result] = field(default_factory=list)
    emitter_pdf: list = field(default_factory=list)
    """:class:`brdflab.judges.lights.samplers.PdfCheck` per emitter sampler."""
    emitter_negative: list[tuple[str, bool, str]] = field(default_factory=list)
    """(what, rejected, detail) of the emitter negative controls."""
    agreement: list = field(default_factory=list)
    """:class:`brdflab.judges.estimators.agreement.AgreementResult` per canonical scene and selection rule."""
    agreement_negative: list = field(default_factory=list)
    white_furnace: object = None
    """:class:`brdflab.viz.white_furnace.FurnaceRun`: the path-traced white furnace ``validate`` adds for its
    page (display only: not part of :attr:`passed`)."""

    @property
    def passed(self) -> bool:
        """Everything passed and the negative control was rejected."""
        return (all(r.passed for r in self.chi2) and all(not r.passed for r in self.negative_control)
                and all(r.passed for r in self.consistency) and all(p.passed for p in self.albedo)
                and all(r.passed for r in self.stability) and self.light_transport_passed)

    @property
    def light_transport_passed(self) -> bool:
        """Emitter checks and estimator agreement passed, and their negative controls were rejected."""
        return (all(r.passed for r in self.emitter_chi2) and all(r.passed for r in self.emitter_pdf)
                and all(rejected for _, rejected, _ in self.emitter_negative) and all(r.passed for r in self.agreement)
                and all(not r.passed for r in self.agreement_negative))

    def failures(self) -> list[str]:
        """Human-readable list of what failed."""
        out = [r.message or f"chi2 {r.name} {r.params}: p = {r.p_value:.3g} ≤ {r.threshold:.2g}"
               for r in self.chi2 if not r.passed]
        out += [f"negative control {r.name} {r.params} was NOT rejected (p = {r.p_value:.3g})"
                for r in self.negative_control if r.passed]
        out += [r.message or f"consistency {r.name} θ={r.theta}: {r}" for r in self.consistency if not r.passed]
        out += [p.message or f"albedo {p.name}{'' if p.alpha is None else f' α={p.alpha:g}'} θ={p.theta}: quad "
                f"{p.quadrature:.4f} MC {p.monte_carlo:.4f}"
                for p in self.albedo if not p.passed]
        out += [r.message for r in self.stability if not r.passed]
        out += [f"emitter chi2 {r.name}: p = {r.p_value:.3g} ≤ {r.threshold:.2g}" for r in self.emitter_chi2
                if not r.passed]
        out += [f"emitter pdf {r.name}: {r.compared} samples, max rel. error {r.max_rel_error:.3g}"
                for r in self.emitter_pdf if not r.passed]
        out += [f"emitter negative control {n} was NOT rejected ({d})" for n, ok, d in self.emitter_negative if not ok]
        out += [f"agreement {r.name}: p = {r.p_value:.3g}; {r.worst}" for r in self.agreement if not r.passed]
        out += [f"agreement negative control {r.name} was NOT rejected (p = {r.p_value:.3g})"
                for r in self.agreement_negative if r.passed]
        return out


def plan(bsdfs=None, warp_names: list[str] | None = None, alphas=ALPHAS, thetas=THETAS,
         params: dict | None = None, make: Callable | None = None) -> list[tuple]:
    """The chi-square tests to run: ('bsdf', name, α, θ[, sweep params]) and ('warp', name, α, None).

    ``bsdfs`` as for :func:`resolve_bsdfs`; α is None for a BSDF without roughness; a fifth element holds
    the point of the BSDF's declared ``sweep`` grid, when it has one.
    """
    tests: list[tuple] = []
    for entry in resolve_bsdfs(bsdfs, make):
        for point in entry.grid(params):
            for a in (alphas if entry.takes_alpha else (None,)):
                for t in entry.angles(thetas):
                    tests.append(("bsdf", entry.name, a, t, point) if point else ("bsdf", entry.name, a, t))
    for name in warp_names if warp_names is not None else list(WARPS) + list(POINT_WARPS):
        if name in WARPS and WARPS[name][2]:
            tests.extend(("warp", name, a, None) for a in alphas)
        else:
            tests.append(("warp", name, None, None))
    return tests


def _entries_by_name(bsdfs, make) -> dict[str, BSDFEntry]:
    return {e.name: e for e in resolve_bsdfs(bsdfs, make)}


def run_chi2(tests: list[tuple], n: int, threshold: float, params: dict | None = None,
             progress: Callable[[str], None] | None = None, cluster=None, bsdfs=None,
             make: Callable | None = None) -> list[c2.Chi2Result]:
    """Run the planned chi-square tests at the given per-test threshold, here or on ``cluster``.

    ``bsdfs``/``make`` resolve the names of the plan (default: built-ins, then the plugin registry). On a
    cluster each test is one job (its own seeded stream, so the results do not depend on placement); BSDFs
    given as objects or factories (not by name) cannot travel and run here.
    """
    from brdflab.cluster import iter_jobs, user_bsdf_classes

    params = params or {}
    entries = _entries_by_name(bsdfs, make) if bsdfs is not None else {}
    jobs = [(kind, name, a, t, n, threshold, {**params, **(rest[0] if rest else {})})
            for kind, name, a, t, *rest in tests]
    if cluster is not None and make is None and all(e.by_name for e in entries.values()):
        shipped = user_bsdf_classes()
        results = iter_jobs(chi2_job, [(*j, shipped) for j in jobs], cluster)
    else:
        results = (_chi2_one(*j, entries.get(j[1]), make) for j in jobs)
    out = []
    for r in results:
        out.append(r)
        if progress:
            progress(f"{'PASS' if r.passed else 'FAIL'}  chi2 {r.name:24s} {_fmt(r.params):28s} p = {r.p_value:.4f}"
                     + (f"  {r.fault}" if r.fault else ""))
    return out


def _chi2_one(kind: str, name: str, a, t, n: int, threshold: float, prm: dict, entry: BSDFEntry | None = None,
              make: Callable | None = None) -> c2.Chi2Result:
    """One planned chi-square test (``prm``: parameters with the sweep point), with its own seed."""
    if kind == "bsdf":
        entry = entry or resolve_bsdfs([name], make)[0]
        seed = test_seed("chi2", name, a, t, prm, n)  # the sample count is part of the identity
        shown = {"alpha": a, "theta": t, **prm} if a is not None else {"theta": t, **prm}
        try:
            bsdf = entry.make(a, prm)
        except Exception as exc:  # a plugin's constructor: a verdict, not a traceback
            return c2.faulted(name, shown, f"{name}({_fmt(prm)}) raised {type(exc).__name__}: {exc}", seed,
                              threshold, n)
        if getattr(bsdf, "all_delta", False):  # no density to test: lobe frequencies, directions, weights
            from brdflab.judges.material.delta import delta_test

            return delta_test(bsdf, t, n, seed=seed, name=name, params=shown, threshold=threshold)
        return c2.bsdf_test(name, bsdf, t, n, seed=seed, params=shown, threshold=threshold)
    if name in POINT_WARPS:
        w, p, bounds = POINT_WARPS[name]
        return c2.point_warp_test(name, w, p, bounds, n, seed=_seed(kind, name, a, t), params={}, threshold=threshold)
    w, p, takes_alpha = WARPS[name]
    if takes_alpha:
        w_, p_ = (lambda u, a=a, w=w: w(u, a)), (lambda d, a=a, p=p: p(d, a))
    else:
        w_, p_ = w, p
    return c2.warp_test(name, w_, p_, n, seed=_seed(kind, name, a, t), params={"alpha": a} if takes_alpha else {},
                        threshold=threshold)


def chi2_job(job: tuple) -> c2.Chi2Result:
    """One chi-square test from its descriptor (kind, name, α, θ, samples, threshold, params, user BSDF
    classes to register first): what :func:`run_chi2` maps over on cluster workers (BSDFs by name)."""
    from brdflab.cluster import register_user_bsdfs

    kind, name, a, t, n, threshold, params, shipped = job
    register_user_bsdfs(shipped)
    return _chi2_one(kind, name, a, t, n, threshold, params)


def _consistency_one(name: str, a, t, n: int, prm: dict, entry: BSDFEntry | None = None):
    """One consistency check of a battery entry, with its own seed (a constructor error is a verdict)."""
    entry = entry or resolve_bsdfs([name])[0]
    label = _label(name, a, {k: v for k, v in prm.items() if k in entry.sweep})
    try:
        b = entry.make(a, prm)
    except Exception as exc:
        b = _Raising(f"{label} raised {type(exc).__name__}: {exc}")
    return consistency.consistency_test(b, theta=t, samples=n, name=label,
                                        params={"alpha": a, **prm} if a is not None else dict(prm),
                                        seed=test_seed("consistency", name, a, t, prm))


def consistency_job(job: tuple) -> consistency.ConsistencyResult:
    """One consistency check (name, α, θ, samples, params, user BSDF classes) with its own seed."""
    from brdflab.cluster import register_user_bsdfs

    name, a, t, n, params, shipped = job
    register_user_bsdfs(shipped)
    return _consistency_one(name, a, t, n, params)


def _fmt(params: dict) -> str:
    return " ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in params.items() if v is not None)


def _label(name: str, a: float | None, point: dict) -> str:
    bits = ([f"α={a:g}"] if a is not None else []) + [f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}"
                                                      for k, v in point.items()]
    return " ".join([name, *bits])


def _stability_materials(entries: list[BSDFEntry], params: dict) -> dict[str, object]:
    builtin = stability.materials()
    out = {}
    for e in entries:
        if not e.checks:
            continue
        if e.name in BSDFS:
            out.update({k: v for k, v in builtin.items() if k.split()[0] == e.name})
            continue
        for point in e.grid(params):
            for a in ((1e-4, 1e-3, 0.5, 1.0) if e.takes_alpha else (None,)):
                label = _label(e.name, a, point)
                try:
                    out[label] = e.make(a, {**params, **point})
                except Exception as exc:  # reported as a failed stability row
                    out[label] = _Raising(f"{label} raised {type(exc).__name__}: {exc}")
    return out


class _Raising:
    """Stand-in for a BSDF whose constructor raised: every method raises the same error."""

    type_name = "unconstructible"

    def __init__(self, msg: str) -> None:
        self.msg = msg

    def _raise(self, *args):
        raise RuntimeError(self.msg)

    eval = pdf = sample = _raise


def run_battery(n: int = 200_000, bsdfs=None, warp_names: list[str] | None = None,
                alphas=ALPHAS, thetas=THETAS, params: dict | None = None, full: bool = True,
                progress: Callable[[str], None] | None = None, light_transport: bool | None = None,
                cluster=None, make: Callable | None = None,
                consistency_thetas=(0.0, 45.0, 85.0), consistency_alphas=(1e-3, 0.1, 1.0),
                furnace_alphas=FURNACE_ALPHAS, furnace_thetas=FURNACE_THETAS) -> Battery:
    """Run the battery on the built-in BSDFs or on any BSDFs given (a user's plugin).

    Parameters
    ----------
    n
        Samples per chi-square test (consistency uses min(n, 200 000), furnace min(n, 100 000)/2).
    bsdfs
        None (every built-in BSDF and lobe variant), or a list of names (built-in or registered plugin
        types), BSDF instances, BSDF classes, ``(name, factory(alpha, params))`` pairs or
        :class:`BSDFEntry` objects (see :func:`resolve_bsdfs`).
    warp_names
        Which warps (default: all; ``[]`` for none).
    alphas, thetas
        Roughness values (for BSDFs with an ``alpha`` parameter) and incident angles (degrees).
    params
        Material parameters given to every BSDF (e.g. ``{"R0": 0.9}``); keys given here are not swept.
    full
        Also run the consistency, furnace and stability checks and the negative control.
    light_transport
        Also check the emitters' samplers and the estimators' agreement on the generated light scenes
        (:func:`run_light_transport`); default: for the whole battery (``full``, all BSDFs and warps).
    cluster
        A :class:`brdflab.cluster.Cluster` (or address) to run the chi-square tests and consistency checks
        on, one job each (same verdicts and p-values as here: every test has its own random stream).
    progress
        Called with one line per result.
    make
        ``make(name, alpha, params) -> BSDF`` to build BSDFs given by name (default: built-ins, then the
        plugin registry).
    consistency_thetas, consistency_alphas, furnace_alphas, furnace_thetas
        Grids of the consistency and furnace checks.

    Returns
    -------
    Battery
        ``passed`` when everything passed and the negative control was rejected; ``failures()`` says what not.

    Examples
    --------
    >>> import brdflab.judges as v
    >>> from brdflab.bsdf.diffuse import Diffuse
    >>> bat = v.run_battery(n=5_000, bsdfs=[Diffuse(0.5)], warp_names=[], thetas=(0.0, 60.0), full=False)
    >>> len(bat.chi2), bat.passed
    (2, True)
    """
    from brdflab.limits import check_memory

    # Each test holds its n samples (directions, pdfs, weights, binning temporaries): ~200 bytes per sample.
    check_memory(200 * n, f"{n:,} samples per test")
    params = dict(params or {})
    entries = resolve_bsdfs(bsdfs, make)
    tests = plan(entries, warp_names, alphas, thetas, params)
    threshold = c2.sidak(c2.SIGNIFICANCE, len(tests))
    bat = Battery(threshold=threshold)
    bat.chi2 = run_chi2(tests, n, threshold, params, progress, cluster, bsdfs=entries, make=make)
    if not full:
        return bat
    for t in (30.0, 60.0):
        r = c2.bsdf_test("roughconductor without Jacobian", NoJacobianConductor(0.5, 0.3), t, n,
                         seed=_seed("neg", t), params={"alpha": 0.3, "theta": t}, threshold=threshold)
        bat.negative_control.append(r)
        if progress:
            progress(f"{'REJECTED (good)' if not r.passed else 'NOT REJECTED (bad)'}  negative control θ={t:g}: "
                     + _why(r))
    for k, (what, make_control) in enumerate(CONDUCTOR_CONTROLS):
        t = (30.0, 60.0)[k % 2]
        r = c2.bsdf_test(what, make_control(), t, n, seed=_seed("neg-conductor", k, t), params={"theta": t},
                         threshold=threshold)
        bat.negative_control.append(r)
        if progress:
            progress(f"{'REJECTED (good)' if not r.passed else 'NOT REJECTED (bad)'}  negative control {what} "
                     f"θ={t:g}: " + _why(r))
    if any(e.flag("has_transmission") for e in entries):
        from brdflab.judges.material.transmission_controls import run_controls

        bat.negative_control += run_controls(n, threshold, progress)
    # Delta BSDFs have no density, f or albedo to integrate: their chi-square entry is the delta judge.
    checked_entries = [e for e in entries if e.checks and not e.flag("all_delta")]
    cjobs = [(e.name, a, t, min(n, 200_000), {**params, **point}) for e in checked_entries for point in e.grid(params)
             for a in (consistency_alphas if e.takes_alpha else (None,)) for t in e.angles(consistency_thetas)]
    if cluster is not None and make is None and all(e.by_name for e in checked_entries):
        from brdflab.cluster import iter_jobs, user_bsdf_classes

        shipped = user_bsdf_classes()
        cres = iter_jobs(consistency_job, [(*j, shipped) for j in cjobs], cluster)
    else:
        by_name = {e.name: e for e in checked_entries}
        cres = (_consistency_one(*j, by_name[j[0]]) for j in cjobs)
    for r in cres:
        bat.consistency.append(r)
        if progress:
            progress(r.message)
    for e in checked_entries:
        for point in e.grid(params):
            prm = furnace_parameters(e, params, point)
            fname = furnace_name(e, point)
            for a in (furnace_alphas if e.takes_alpha else (None,)):
                try:
                    e.make(a, prm)
                    inside = [t for t in INSIDE_FURNACE_THETAS if e.flag("two_sided")]
                    pts = furnace.albedo_curve(fname, lambda a, e=e, prm=prm: e.make(a, prm), a,
                                               list(furnace_thetas) + inside, n=min(n, 100_000) // 2, params=prm)
                except Exception as exc:
                    pts = [furnace.AlbedoPoint(fname, a, 0.0, float("nan"), float("nan"), float("nan"),
                                               fault=f"{fname} raised {type(exc).__name__}: {exc}")]
                    pts[0].message = pts[0].summary()
                bat.albedo.extend(pts)
    if progress and bat.albedo:
        finite = [p for p in bat.albedo if np.isfinite(p.quadrature)] or bat.albedo
        worst = min(finite, key=lambda p: p.quadrature)
        progress(f"{'PASS' if all(p.passed for p in bat.albedo) else 'FAIL'}  furnace: {len(bat.albedo)} albedo "
                 f"points, max ρ {max(p.quadrature for p in finite):.4f}, min ρ {worst.quadrature:.4f} "
                 f"({worst.name}{'' if worst.alpha is None else f', α={worst.alpha:g}'}, θ={worst.theta:g})")
        bad = [p for p in bat.albedo if not p.passed]
        if bad:  # the points themselves are listed once, grouped, by brdflab.judges.core.failures
            progress(f"      {len(bad)} failing albedo points (first: {bad[0].message})")
    bat.stability = stability.run() if bsdfs is None else stability.run(bsdfs=_stability_materials(entries, params))
    if progress:
        bad = [r for r in bat.stability if not r.passed]
        progress(f"{'PASS' if not bad else 'FAIL'}  stability: {len(bat.stability)} extreme cases, {len(bad)} with "
                 "NaN/inf/negative values or errors")
        for r in bad[:10]:
            progress(r.message)
    if light_transport or (light_transport is None and bsdfs is None and warp_names is None):
        run_light_transport(bat, min(n, 100_000), progress)
    return bat


def run_light_transport(bat: Battery, n: int = 100_000, progress: Callable[[str], None] | None = None) -> Battery:
    """Add the emitter checks (:mod:`brdflab.judges.lights.samplers`) and the estimator agreement
    (:mod:`brdflab.judges.estimators.agreement`) with their negative controls to ``bat``."""
    from brdflab.judges.estimators import agreement
    from brdflab.judges.lights import samplers as emitters

    bat.emitter_chi2, bat.emitter_pdf = emitters.run(n, progress)
    bat.emitter_negative = emitters.negative_controls(n, progress)
    bat.agreement, bat.agreement_negative = agreement.run(progress)
    return bat
