"""The validation battery: every warp and BSDF through chi-square, consistency, furnace and stability.

:func:`run_battery` returns a :class:`Battery` that the CLI prints and
:mod:`brdflab.report.validation` turns into an HTML report. The chi-square tests share one family-wise
significance of 0.01 (Šidák-corrected for their number). A **negative control** — the rough conductor
with its pdf missing the 1/(4|ω_o·ω_h|) Jacobian — must be rejected, or the harness itself is broken.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from brdflab.bsdf.diffuse import Diffuse
from brdflab.bsdf.microfacet import beckmann_d, half_vector
from brdflab.bsdf.roughconductor import RoughConductor, alpha_values
from brdflab.bsdf.roughsubstrate import RoughSubstrate
from brdflab.math import warps
from brdflab.validate import chi2 as c2
from brdflab.validate import consistency, furnace, stability

ALPHAS = (1e-3, 0.005, 0.05, 0.1, 0.3, 0.5, 1.0)
THETAS = (0.0, 30.0, 60.0, 80.0, 89.0)
FURNACE_ALPHAS = (0.05, 0.1, 0.3, 0.5, 1.0)
FURNACE_THETAS = tuple(float(t) for t in range(0, 90, 5))


class NoJacobianConductor(RoughConductor):
    """A deliberately wrong rough conductor: its pdf omits the 1/(4 |ω_o·ω_h|) Jacobian."""

    def pdf(self, wi, wo, uv=None):
        """D(ω_h) cos θ_h — the density of ω_h, wrongly used as the density of ω_o."""
        a = alpha_values(self.alpha, uv, len(wi))
        wh, ok = half_vector(wi, wo)
        return np.where(ok & (wi[:, 2] > 0), beckmann_d(wh[:, 2], a) * np.maximum(wh[:, 2], 0.0), 0.0)


#: BSDF factories by name: (alpha, **params) → BSDF. Lobe variants of the substrate are separate entries.
BSDFS: dict[str, Callable] = {
    "diffuse": lambda alpha, **kw: Diffuse(kw.get("albedo", 0.5)),
    "roughconductor": lambda alpha, **kw: RoughConductor(kw.get("R0", 0.5), alpha),
    "roughsubstrate": lambda alpha, **kw: RoughSubstrate(kw.get("kd", 0.5), alpha, kw.get("intIOR", 1.5046),
                                                         kw.get("extIOR", 1.000277)),
    "roughsubstrate/specular": lambda alpha, **kw: RoughSubstrate(kw.get("kd", 0.5), alpha, kw.get("intIOR", 1.5046),
                                                                  kw.get("extIOR", 1.000277), lobe="specular"),
    "roughsubstrate/diffuse": lambda alpha, **kw: RoughSubstrate(kw.get("kd", 0.5), alpha, kw.get("intIOR", 1.5046),
                                                                 kw.get("extIOR", 1.000277), lobe="diffuse"),
}
#: Direction warps: name → (sample, pdf, takes alpha).
WARPS: dict[str, tuple[Callable, Callable, bool]] = {
    "uniform_sphere": (warps.square_to_uniform_sphere, warps.square_to_uniform_sphere_pdf, False),
    "uniform_hemisphere": (warps.square_to_uniform_hemisphere, warps.square_to_uniform_hemisphere_pdf, False),
    "cosine_hemisphere": (warps.square_to_cosine_hemisphere, warps.square_to_cosine_hemisphere_pdf, False),
    "beckmann": (warps.square_to_beckmann, warps.square_to_beckmann_pdf, True),
}
#: Warps to 2-D points: name → (sample, pdf, bounds).
POINT_WARPS = {
    "uniform_triangle": (warps.square_to_uniform_triangle, warps.square_to_uniform_triangle_pdf, (0, 1, 0, 1)),
    "uniform_disk": (warps.square_to_uniform_disk, warps.square_to_uniform_disk_pdf, (-1, 1, -1, 1)),
}


def make_named_bsdf(name: str, alpha: float | None, params: dict | None = None):
    """The BSDF ``name`` of the battery: a registry type (built-in or plugin, :func:`brdflab.plugins.make_bsdf`),
    or ``type/lobe`` for one lobe of a built-in mixture (``roughsubstrate/specular``); ``alpha`` only for a
    BSDF with an ``alpha`` parameter."""
    from brdflab.plugins import make_bsdf

    base, _, lobe = name.partition("/")
    bsdf = make_bsdf(base, params, alpha=alpha)
    if lobe:
        bsdf.lobe = lobe
    return bsdf


def has_alpha(name: str) -> bool:
    """True when BSDF ``name`` (or its base type) has an ``alpha`` parameter."""
    from brdflab.plugins import bsdf_class, parameter_kinds

    return "alpha" in parameter_kinds(bsdf_class(name.partition("/")[0]))


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
    # -- light transport (brdflab.validate.emitters / agreement) --
    emitter_chi2: list[c2.Chi2Result] = field(default_factory=list)
    emitter_pdf: list = field(default_factory=list)
    """:class:`brdflab.validate.emitters.PdfCheck` per emitter sampler."""
    emitter_negative: list[tuple[str, bool, str]] = field(default_factory=list)
    """(what, rejected, detail) of the emitter negative controls."""
    agreement: list = field(default_factory=list)
    """:class:`brdflab.validate.agreement.AgreementResult` per canonical scene and selection rule."""
    agreement_negative: list = field(default_factory=list)

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
        out = [f"chi2 {r.name} {r.params}: p = {r.p_value:.3g} ≤ {r.threshold:.2g}" for r in self.chi2 if not r.passed]
        out += [f"negative control {r.name} {r.params} was NOT rejected (p = {r.p_value:.3g})"
                for r in self.negative_control if r.passed]
        out += [f"consistency {r.name} θ={r.theta}: {r}" for r in self.consistency if not r.passed]
        out += [f"albedo {p.name} α={p.alpha} θ={p.theta}: quad {p.quadrature:.4f} MC {p.monte_carlo:.4f}"
                for p in self.albedo if not p.passed]
        out += [f"stability {r.material} / {r.case}: {r.nan} NaN, {r.inf} inf, {r.negative} negative"
                for r in self.stability if not r.passed]
        out += [f"emitter chi2 {r.name}: p = {r.p_value:.3g} ≤ {r.threshold:.2g}" for r in self.emitter_chi2
                if not r.passed]
        out += [f"emitter pdf {r.name}: {r.compared} samples, max rel. error {r.max_rel_error:.3g}"
                for r in self.emitter_pdf if not r.passed]
        out += [f"emitter negative control {n} was NOT rejected ({d})" for n, ok, d in self.emitter_negative if not ok]
        out += [f"agreement {r.name}: p = {r.p_value:.3g}; {r.worst}" for r in self.agreement if not r.passed]
        out += [f"agreement negative control {r.name} was NOT rejected (p = {r.p_value:.3g})"
                for r in self.agreement_negative if r.passed]
        return out


def plan(bsdfs: list[str] | None = None, warp_names: list[str] | None = None, alphas=ALPHAS, thetas=THETAS,
         params: dict | None = None) -> list[tuple]:
    """The chi-square tests to run: ('bsdf', name, α, θ) and ('warp', name, α)."""
    tests: list[tuple] = []
    for name in bsdfs if bsdfs is not None else list(BSDFS):
        for a in (alphas if has_alpha(name) else (None,)):
            for t in thetas:
                tests.append(("bsdf", name, a, t))
    for name in warp_names if warp_names is not None else list(WARPS) + list(POINT_WARPS):
        if name in WARPS and WARPS[name][2]:
            tests.extend(("warp", name, a, None) for a in alphas)
        else:
            tests.append(("warp", name, None, None))
    return tests


def run_chi2(tests: list[tuple], n: int, threshold: float, params: dict | None = None,
             progress: Callable[[str], None] | None = None, cluster=None) -> list[c2.Chi2Result]:
    """Run the planned chi-square tests at the given per-test threshold, here or on ``cluster`` (one job
    per test; each test draws from its own seeded stream, so the results do not depend on placement)."""
    from brdflab.cluster import iter_jobs, user_bsdf_classes

    params = params or {}
    shipped = user_bsdf_classes()
    jobs = [(kind, name, a, t, n, threshold, params, shipped) for kind, name, a, t in tests]
    out = []
    for r in iter_jobs(chi2_job, jobs, cluster):
        out.append(r)
        if progress:
            progress(f"{'PASS' if r.passed else 'FAIL'}  chi2 {r.name:24s} {_fmt(r.params):28s} p = {r.p_value:.4f}")
    return out


def chi2_job(job: tuple) -> c2.Chi2Result:
    """One chi-square test from its descriptor (kind, name, α, θ, samples, threshold, params, user BSDF
    classes to register first): what :func:`run_chi2` maps over, in this process or on cluster workers."""
    from brdflab.cluster import register_user_bsdfs

    kind, name, a, t, n, threshold, params, shipped = job
    register_user_bsdfs(shipped)
    # Parameters are part of a test's identity (only when given, so the built-in battery keeps its streams).
    seed = _seed(kind, name, a, t, *sorted((k, repr(v)) for k, v in params.items()))
    if kind == "bsdf":
        bsdf = make_named_bsdf(name, a, params)
        axis = np.array([0.0, 0.0, 1.0]) if name in ("diffuse", "roughsubstrate/diffuse") else None
        r = c2.bsdf_test(name, bsdf, t, n, seed=seed, params={"alpha": a, "theta": t, **params},
                         threshold=threshold, axis=axis)
    elif name in POINT_WARPS:
        w, p, bounds = POINT_WARPS[name]
        r = c2.point_warp_test(name, w, p, bounds, n, seed=seed, params={}, threshold=threshold)
    else:
        w, p, takes_alpha = WARPS[name]
        if takes_alpha:
            w_, p_ = (lambda u, a=a, w=w: w(u, a)), (lambda d, a=a, p=p: p(d, a))
        else:
            w_, p_ = w, p
        r = c2.warp_test(name, w_, p_, n, seed=seed, params={"alpha": a} if takes_alpha else {},
                         threshold=threshold)
    return r


def consistency_job(job: tuple) -> consistency.ConsistencyResult:
    """One consistency check (name, α, θ, samples, params, user BSDF classes) with its own seed."""
    from brdflab.cluster import register_user_bsdfs

    name, a, t, n, params, shipped = job
    register_user_bsdfs(shipped)
    return consistency.check_bsdf(f"{name} α={a}", make_named_bsdf(name, a, params), t, n=n,
                                  seed=_seed("cons", name, a, t))


def _fmt(params: dict) -> str:
    return " ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in params.items() if v is not None)


def run_battery(n: int = 200_000, bsdfs: list[str] | None = None, warp_names: list[str] | None = None,
                alphas=ALPHAS, thetas=THETAS, params: dict | None = None, full: bool = True,
                progress: Callable[[str], None] | None = None, light_transport: bool | None = None,
                cluster=None) -> Battery:
    """Run the battery.

    Parameters
    ----------
    n
        Samples per chi-square test.
    bsdfs, warp_names
        Which BSDFs and warps (default: all).
    alphas, thetas
        Roughness values and incident angles (degrees).
    params
        Extra material parameters (e.g. ``R0``, ``kd``, ``intIOR``).
    full
        Also run the consistency, furnace and stability checks and the negative control.
    light_transport
        Also check the emitters' samplers and the estimators' agreement on the generated light scenes
        (:func:`run_light_transport`); default: for the whole battery (``full``, all BSDFs and warps).
    cluster
        A :class:`brdflab.cluster.Cluster` (or address) to run the chi-square tests and consistency checks
        on, one job each (same verdicts and p-values as here: every test has its own random stream).
    """
    from brdflab.cluster import iter_jobs, user_bsdf_classes

    tests = plan(bsdfs, warp_names, alphas, thetas)
    threshold = c2.sidak(c2.SIGNIFICANCE, len(tests))
    bat = Battery(threshold=threshold)
    bat.chi2 = run_chi2(tests, n, threshold, params, progress, cluster)
    if not full:
        return bat
    for t in (30.0, 60.0):
        r = c2.bsdf_test("roughconductor without Jacobian", NoJacobianConductor(0.5, 0.3), t, n,
                         seed=_seed("neg", t), params={"alpha": 0.3, "theta": t}, threshold=threshold)
        bat.negative_control.append(r)
        if progress:
            progress(f"{'REJECTED (good)' if not r.passed else 'NOT REJECTED (bad)'}  negative control θ={t:g}: "
                     f"p = {r.p_value:.3g}")
    names = bsdfs if bsdfs is not None else ["diffuse", "roughconductor", "roughsubstrate"]
    shipped = user_bsdf_classes()
    jobs = [(name, a, t, min(n, 200_000), params, shipped) for name in names if "/" not in name
            for a in ((1e-3, 0.1, 1.0) if has_alpha(name) else (None,)) for t in (0.0, 45.0, 85.0)]
    for r in iter_jobs(consistency_job, jobs, cluster):
        bat.consistency.append(r)
        if progress:
            progress(f"{'PASS' if r.passed else 'FAIL'}  consistency {r.name} θ={r.theta:g}: weight err "
                     f"{r.max_weight_error:.1e}, ∫pdf {r.pdf_integral:.4f} (valid {r.valid_fraction:.4f}), "
                     f"reciprocity {r.max_reciprocity_error:.1e}")
    for name, make in (("roughconductor R0=1", lambda a: RoughConductor(1.0, a)),
                       ("roughsubstrate kd=1", lambda a: RoughSubstrate(1.0, a))):
        if bsdfs is not None and name.split()[0] not in bsdfs:
            continue
        for a in FURNACE_ALPHAS:
            bat.albedo.extend(furnace.albedo_curve(name, make, a, list(FURNACE_THETAS), n=min(n, 100_000) // 2))
    if progress and bat.albedo:
        worst = min(bat.albedo, key=lambda p: p.quadrature)
        progress(f"{'PASS' if all(p.passed for p in bat.albedo) else 'FAIL'}  furnace: {len(bat.albedo)} albedo "
                 f"points, max ρ {max(p.quadrature for p in bat.albedo):.4f}, min ρ {worst.quadrature:.4f} "
                 f"({worst.name}, α={worst.alpha}, θ={worst.theta:g})")
    bat.stability = stability.run()
    if progress:
        bad = [r for r in bat.stability if not r.passed]
        progress(f"{'PASS' if not bad else 'FAIL'}  stability: {len(bat.stability)} extreme cases, {len(bad)} with "
                 "NaN/inf/negative values")
    if light_transport or (light_transport is None and bsdfs is None and warp_names is None):
        run_light_transport(bat, min(n, 100_000), progress)
    return bat


def run_light_transport(bat: Battery, n: int = 100_000, progress: Callable[[str], None] | None = None) -> Battery:
    """Add the emitter checks (:mod:`brdflab.validate.emitters`) and the estimator agreement
    (:mod:`brdflab.validate.agreement`) with their negative controls to ``bat``."""
    from brdflab.validate import agreement, emitters

    bat.emitter_chi2, bat.emitter_pdf = emitters.run(n, progress)
    bat.emitter_negative = emitters.negative_controls(n, progress)
    bat.agreement, bat.agreement_negative = agreement.run(progress)
    return bat
