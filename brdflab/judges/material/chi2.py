"""Chi-square goodness-of-fit tests of sampling routines against their densities, for any lobe shape.

For a sampler of directions with claimed solid-angle density p (a BSDF for one ω_i, or a warp):

1. **Bins from a pilot sample.** A pilot of max(N/4, 2000) directions drawn from the sampler itself on its
   *own* random stream (independent of the observed sample, so the bins cannot adapt to the data they
   test), mixed with 10 % uniform-sphere directions (so regions the sampler never visits still get bins),
   places the bins in spherical coordinates (θ, φ) about the normal: ``n_theta`` strips in θ at the pilot's
   θ quantiles, then in every strip ``n_phi`` bins at the quantiles of the pilot's φ inside that strip.
   Every bin holds about the same probability wherever the lobe is — one lobe, several lobes, a lobe at
   grazing angles, or a very sharp one (α = 10⁻³) — with no assumption about its axis or shape.
2. **Expected counts by integrating p**, never from the pilot: N·∫_bin p dω with dω = sin θ dθ dφ, by adaptive
   tensor Gauss–Legendre quadrature (4- vs 8-point rules; a cell is split 2×2 until the two agree within 10⁻³
   expected counts or 10⁻⁴ relative, see :func:`integrate_rects`). Before refining, every bin is cut into cells
   no larger than π/24 × 2π/24, at the horizon θ = π/2, and geometrically near θ = 0, so no peak hides between
   the nodes of a wide bin; bins below the horizon are also cut at the φ edges of the strip above it, and a bin
   where the pilot found clearly more samples than the result predicts (more than λ + 3√λ + 3 for λ = the pilot's
   draws × mass) is integrated again from a 48 × 48 grid (the larger of the two results is kept): a lobe thinner
   than the node spacing (an anisotropic streak, α_u/α_v = 250; a grazing visible-normal lobe just below the
   horizon) is then resolved. The pilot only guides where to look; the masses are still integrals of p. The
   summed |8-point − 4-point| differences are reported as the integration error. **Other axes**: when the
   bins about the normal still miss mass the pilot saw (∫ p below the pilot's valid fraction by more than
   one binomial σ), bins about x, y and the pilot's mean direction are built the same way and
   the axis whose ∫ p is largest (by more than :data:`FRAME_GAIN`) is used (:func:`best_frame`): a thin streak
   curved across the bins about the normal (α_u = 10⁻³, α_v = 0.25 at θ_i = 85°: ω_o·x = −ω_i·x, 1 % missed)
   runs along a coordinate line about x. The choice sees the pilot and p only, never the tested sample.
3. **The failed samples are a category.** Samples with pdf 0 (failed) are counted in one extra bin whose
   expected count is N·(1 − ∫ p dω): the test checks ∫ p dω = the valid fraction as part of the same
   multinomial. ∫ p dω > 1 (beyond 10⁻³ + 3× the integration error) fails on its own.
4. Bins with expected count < 5 are pooled; Pearson's X² = Σ (O − E)²/E with k − 1 degrees of freedom;
   the p-value comes from ``scipy.stats.chi2``. A test with no valid sample or fewer than 4 degrees of
   freedom left fails as blind (a test that cannot fail is a defect).
5. Reject at significance 0.01, Šidák-corrected for the number m of tests: α_m = 1 − (1 − α)^(1/m).

Limitation: a peak of the *claimed* pdf narrower than about 0.5° in a region the sampler never visits can be
missed by the quadrature (then it is invisible to the test, as it is to every bin-based test).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from brdflab.errors import BrdflabError
from brdflab.judges.core.binning import (  # noqa: F401 (re-exported: the module's former contents)
    bin_counts,
    bin_rects,
    bin_shape,
    pilot_bins,
    theta_edges_from_pilot,
)
from brdflab.judges.core.quadrature import (  # noqa: F401 (re-exported: the module's former contents)
    BASE_CELL,
    _expand,
    _frame,
    _gl_rects,
    _graded_cuts,
    _neighbour_widths,
    _split_cells,
    adaptive_integrate,
    from_angles,
    integrate_bins,
    integrate_bins_finely,
    integrate_rects,
    integrate_sphere_bins,
    sphere_cells,
    sphere_integrand,
    to_angles,
)

SIGNIFICANCE = 0.01


@dataclass
class Chi2Result:
    """Outcome of one chi-square test.

    Attributes
    ----------
    name, params
        What was tested (sampler name; parameters such as α, θ, a plugin's parameters).
    statistic, dof, p_value
        Pearson's X², its degrees of freedom (after pooling) and the p-value.
    threshold
        Per-test significance (Šidák-corrected in a battery); the test passes when p > threshold.
    observed, expected
        Histograms (n_theta, n_phi): rows are θ strips about the normal, columns the φ bins of each strip
        (equal-probability bins from the pilot sample, see the module docstring). For point warps, a
        regular grid.
    theta_edges, phi_edges
        Bin edges: (n_theta + 1,) in θ and (n_theta, n_phi + 1) in φ per strip.
    axis
        The axis the bins' θ, φ are measured about: None or the normal, or another axis where the quadrature
        about the normal missed mass the pilot sample saw (see :func:`best_frame`).
    integral, integration_error
        ∫ p dω over the sphere by adaptive quadrature, and its error estimate.
    valid_fraction
        Fraction of samples that did not fail (pdf > 0); must match ``integral``.
    seed, n
        The test's seed (its own stream) and the number of samples.
    fault
        Why the test failed regardless of the p-value (a plugin broke its contract, ∫ p > 1, a blind
        test), or None.
    message
        One-line verdict.
    """

    name: str
    params: dict
    statistic: float
    dof: int
    p_value: float
    threshold: float = SIGNIFICANCE
    observed: np.ndarray = field(default=None, repr=False)
    expected: np.ndarray = field(default=None, repr=False)
    theta_edges: np.ndarray = field(default=None, repr=False)
    integral: float = float("nan")
    valid_fraction: float = float("nan")
    phi_edges: np.ndarray = field(default=None, repr=False)
    seed: int | None = None
    n: int = 0
    integration_error: float = float("nan")
    fault: str | None = None
    message: str = ""
    axis: np.ndarray | None = field(default=None, repr=False)

    @property
    def passed(self) -> bool:
        """True when there is no fault and the p-value is above the (corrected) threshold; never for a test
        without data (no samples, no degree of freedom, non-finite counts: see :func:`pearson`)."""
        return (self.fault is None and self.dof > 0 and bool(np.isfinite(self.p_value))
                and bool(self.p_value > self.threshold))

    def summary(self) -> str:
        """One line: verdict, p-value, X²/dof, ∫ p dω vs the valid fraction, and the fault if any."""
        head = f"{'PASS' if self.passed else 'FAIL'} chi2 {self.name}"
        if self.params:
            from brdflab.judges.core.guard import format_params

            head += f" ({format_params(self.params)})"
        body = (f": p = {self.p_value:.4g} (threshold {self.threshold:.2g}), X² = {self.statistic:.1f}, "
                f"dof {self.dof}, ∫p dω = {self.integral:.4f}, valid {self.valid_fraction:.4f}")
        if self.axis is not None and not (self.axis[0] == 0 and self.axis[1] == 0):
            body += f", bins about ({self.axis[0]:.3g}, {self.axis[1]:.3g}, {self.axis[2]:.3g})"
        return head + body + (f"; {self.fault}" if self.fault else "")


def faulted(name: str, params: dict, fault: str, seed: int | None = None, threshold: float = SIGNIFICANCE,
            n: int = 0) -> Chi2Result:
    """A failed :class:`Chi2Result` for a test that could not run (e.g. a plugin broke its contract)."""
    r = Chi2Result(name, dict(params), float("nan"), 0, 0.0, threshold, seed=seed, n=n, fault=fault)
    r.message = r.summary()
    return r


def sidak(alpha: float, m: int) -> float:
    """Per-test significance for m tests at family-wise level α (Šidák)."""
    return 1.0 - (1.0 - alpha) ** (1.0 / max(1, m))


def pearson(observed: np.ndarray, expected: np.ndarray) -> tuple[float, int, float]:
    """Pearson's X² after pooling bins with expected count < 5; returns (X², dof, p-value)."""
    obs, exp = observed.ravel(), expected.ravel()
    if not (np.all(np.isfinite(obs)) and np.all(np.isfinite(exp))) or obs.sum() == 0 or exp.sum() <= 0:
        # No samples, or a pdf that is not finite: there is nothing to test; this must never read as a pass.
        return float("nan"), 0, float("nan")
    small = exp < 5
    o = np.append(obs[~small], obs[small].sum())
    e = np.append(exp[~small], exp[small].sum())
    if e[-1] < 5 and len(e) > 1:  # the pooled bin is itself too small: merge it into the last regular bin
        o[-2] += o[-1]
        e[-2] += e[-1]
        o, e = o[:-1], e[:-1]
    with np.errstate(divide="ignore", invalid="ignore"):
        terms = np.where(e > 0, (o - e) ** 2 / e, np.where(o > 0, np.inf, 0.0))
    stat = float(terms.sum())
    dof = len(o) - 1
    if dof < 1:  # everything pooled into one bin: no degree of freedom, no test
        return stat, 0, float("nan")
    from scipy import stats  # here, not at the top: scipy.stats costs ~1 s of start-up for every command

    return stat, dof, (float(stats.chi2.sf(stat, dof)) if np.isfinite(stat) else 0.0)


#: At most this many bins (the pilot's largest excesses first) are integrated again on the fine grid: a lobe thinner
#: than the nodes' spacing fills a few bins, while a claimed pdf that is wrong everywhere (a negative control)
#: makes hundreds suspicious, each ~50 ms to re-integrate, and fails whatever their masses.
FINE_BINS_MAX = 32


def directions_test(name: str, wo: np.ndarray, n_total: int, pdf: Callable[[np.ndarray], np.ndarray],
                    pilot: np.ndarray, *, seed: int | None = None, params: dict | None = None,
                    threshold: float = SIGNIFICANCE, shape: tuple[int, int] | None = None,
                    mix_rng: np.random.Generator | None = None, split_horizon: bool = False,
                    pilot_total: int | None = None) -> Chi2Result:
    """Chi-square test of observed directions against a density, with bins from an independent pilot.

    Parameters
    ----------
    wo
        (k, 3) valid observed directions (the other ``n_total − k`` samples failed).
    n_total
        Number of samples drawn, failed ones included.
    pdf
        Claimed solid-angle density, (M, 3) → (M,).
    pilot
        (m, 3) directions from the same sampler but an independent stream (or from a reference sampler);
        they place the bins only.
    shape
        (n_theta, n_phi); default :func:`bin_shape` of ``n_total``.
    mix_rng
        Stream of the 10 % uniform directions mixed into the pilot.
    split_horizon
        Strips of each hemisphere apart (transmissive BSDFs, :func:`~brdflab.judges.core.binning.pilot_bins`).
    pilot_total
        Number of pilot samples drawn, failed ones included (default ``len(pilot)``): the pilot's valid fraction
        tells :func:`best_frame` whether the quadrature about the normal misses mass.
    """
    nt, nph = shape or bin_shape(n_total)
    mix_rng = mix_rng or np.random.default_rng(seed)
    from brdflab.math.warps import square_to_uniform_sphere

    pilot = np.asarray(pilot, dtype=float).reshape(-1, 3)
    both = np.concatenate([pilot, square_to_uniform_sphere(mix_rng.random((max(len(pilot) // 9, 200), 2)))])
    wo = np.asarray(wo, dtype=float).reshape(-1, 3)
    pilot_valid = len(pilot) / max(pilot_total or len(pilot), 1)
    axis, te, pe, mass, merr, _ = best_frame(both, len(pilot), pilot_valid, pdf, nt, nph, split_horizon,
                                             shape is None, n_total, shape is None)
    th, ph = to_angles(wo, axis)
    obs = bin_counts(th, ph, te, pe)
    integral, ierr = float(mass.sum()), float(merr.sum())
    valid = len(wo) / max(n_total, 1)
    fail_exp = max(n_total * (1.0 - integral), 0.0)
    stat, dof, pval = pearson(np.append(obs.ravel(), n_total - len(wo)), np.append(mass.ravel() * n_total, fail_exp))
    fault = None
    if len(wo) == 0:
        fault = "no valid sample (every sample failed): nothing to test"
    elif integral > 1 + 1e-3 + 3 * ierr:
        fault = f"∫ p dω = {integral:.5f} > 1 (the claimed pdf has more than unit mass)"
    elif dof < 4:
        fault = f"only {dof + 1} populated bins: the test would be blind"
    res = Chi2Result(name, dict(params or {}), stat, dof, pval, threshold, obs, mass * n_total, te,
                     integral=integral, valid_fraction=valid, phi_edges=pe, seed=seed, n=n_total,
                     integration_error=ierr, fault=fault, axis=axis)
    res.message = res.summary()
    return res


#: Least gain of ∫ p dω for which another axis replaces the normal (and the least shortfall of the normal's ∫ p
#: against the pilot's valid fraction that makes the others worth trying): the quadrature's own error on a smooth
#: lobe is ~10⁻⁷; the streak it misses loses 10⁻².
FRAME_GAIN = 5e-4
#: Axes the bins may be placed about besides the normal (the pilot's mean direction is tried too).
_OTHER_AXES = (np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]))


def _frame_bins(angles_of, axis, n_pilot, pdf, nt, nph, split_horizon, grazing, n_total, valid, support=True):
    """Bins about ``axis`` from the pilot (+ uniform mix), their ∫ p (fine re-integration of the bins the pilot
    says are under-predicted, at most :data:`FINE_BINS_MAX`) and the pilot's counts."""
    pt, pp = angles_of(axis)
    support = (float(pt[:n_pilot].min()), float(pt[:n_pilot].max())) if n_pilot and support else None
    te, pe = pilot_bins(pt, pp, nt, nph, split_horizon, grazing=grazing, support=support)
    mass, merr = integrate_sphere_bins(pdf, te, pe, n_total, axis)
    # Bins where the (independent) pilot found clearly more samples than the quadrature's mass predicts are
    # integrated again on a fine grid: a lobe thinner than the Gauss nodes' spacing (see integrate_bins_finely).
    lam = mass * n_pilot / max(valid, 1e-9)  # the pilot holds valid samples only
    pc = bin_counts(pt[:n_pilot], pp[:n_pilot], te, pe)
    suspicious = np.argwhere(pc > lam + 3.0 * np.sqrt(lam) + 3.0)
    if len(suspicious) > FINE_BINS_MAX:  # a thin lobe fills a few bins; hundreds mean p is wrong all over
        excess = [(pc[i, j] - lam[i, j]) / np.sqrt(lam[i, j] + 1.0) for i, j in suspicious]
        suspicious = suspicious[np.argsort(excess, kind="stable")[::-1][:FINE_BINS_MAX]]
    if len(suspicious):
        sel = tuple(suspicious.T)  # a missed peak only lowers a quadrature of p ≥ 0: keep the larger result
        mass[sel] = np.maximum(mass[sel], integrate_bins_finely(pdf, te, pe, suspicious, n_total, axis=axis))
    return te, pe, mass, merr, len(suspicious)


def best_frame(pilot_mix, n_pilot, valid, pdf, nt, nph, split_horizon, grazing, n_total, support=True):
    """The bins' axis: the normal, unless its ∫ p falls short of the pilot's valid fraction by more than one
    binomial σ of the pilot (two of the tested sample, four times the pilot's size; and :data:`FRAME_GAIN`);
    then the axis among the normal, x, y and the pilot's mean direction whose bins' ∫ p is largest.

    A lobe thinner than the Gauss nodes' spacing and curved across the (θ, φ) bins about the normal (an
    anisotropic streak, α_u/α_v = 250: the directions ω_o·x = −ω_i·x) is missed there (∫ p 1 % short, its
    error estimate 1e-5), but runs along one coordinate line about another axis and is integrated exactly.
    The choice uses the pilot and the claimed pdf only, never the tested sample, so it cannot bias the test;
    a quadrature of p ≥ 0 that misses a peak only lowers ∫ p, hence the largest. Returns
    ``(axis, theta_edges, phi_edges, mass, error, n_suspicious)``. ``grazing``: the thin strips below the
    horizon (about the normal); ``support``: the pilot's extreme θ as edges (:func:`pilot_bins`); both only
    with the automatic bin shape (an explicit shape gets exactly that shape).
    """
    def angles_of(axis):
        return to_angles(pilot_mix, axis)

    z = np.array([0.0, 0.0, 1.0])
    te, pe, mass, merr, n_susp = _frame_bins(angles_of, z, n_pilot, pdf, nt, nph, split_horizon, grazing,
                                             n_total, valid, support)
    se = np.sqrt(max(valid * (1.0 - valid), 1e-12) / max(n_pilot / max(valid, 1e-9), 1.0))
    if n_pilot < 100 or mass.sum() >= valid - max(se, FRAME_GAIN):
        return z, te, pe, mass, merr, n_susp
    best = (float(mass.sum()), z, te, pe, mass, merr, n_susp)
    mean = pilot_mix[:n_pilot].mean(axis=0)
    axes = list(_OTHER_AXES) + ([mean / np.linalg.norm(mean)] if np.linalg.norm(mean) > 0.2 else [])
    for axis in axes:
        te, pe, mass, merr, n_susp = _frame_bins(angles_of, axis, n_pilot, pdf, nt, nph, split_horizon, False,
                                                 n_total, valid, support)
        if mass.sum() > best[0] + max(FRAME_GAIN, 3.0 * (best[5].sum() + merr.sum())):
            best = (float(mass.sum()), axis, te, pe, mass, merr, n_susp)
    return best[1:]


def sampler_test(name: str, sample: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
                 pdf: Callable[[np.ndarray], np.ndarray], n: int = 200_000, seed: int = 0,
                 params: dict | None = None, threshold: float = SIGNIFICANCE, uniforms: int = 3,
                 shape: tuple[int, int] | None = None, split_horizon: bool = False) -> Chi2Result:
    """Chi-square test of ``sample`` (uniforms (N, ``uniforms``) → (directions, pdf); pdf 0 = failed) vs ``pdf``.

    Three independent streams spawned from ``seed``: the pilot (bins), the observed sample, the uniform mix.
    """
    if n < 1:
        raise BrdflabError(f"a chi-square test needs at least 1 sample, got {n}")
    s_pilot, s_obs, s_mix = np.random.SeedSequence(seed).spawn(3)
    pw, pp = sample(np.random.default_rng(s_pilot).random((max(n // 4, 2000), uniforms)))
    w, p = sample(np.random.default_rng(s_obs).random((n, uniforms)))
    return directions_test(name, w[p > 0], n, pdf, pw[pp > 0], seed=seed, params=params, threshold=threshold,
                           shape=shape, mix_rng=np.random.default_rng(s_mix), split_horizon=split_horizon,
                           pilot_total=len(pw))


def chi2_test(
    name: str,
    sample: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
    pdf: Callable[[np.ndarray], np.ndarray],
    axis: np.ndarray | None = None,
    n: int = 200_000,
    n_theta: int = 20,
    n_phi: int = 40,
    seed: int = 0,
    params: dict | None = None,
    threshold: float = SIGNIFICANCE,
    uniforms: int = 3,
) -> Chi2Result:
    """Low-level chi-square test of a sampler (kept for callers of the old signature; ``axis`` is unused).

    The BSDF-level function with keyword parameters is :func:`brdflab.judges.chi2_test`.
    """
    return sampler_test(name, sample, pdf, n, seed, params, threshold, uniforms, shape=(n_theta, n_phi))


# -- adapters for BSDFs and warps ----------------------------------------------------------------------
def incident(theta_deg: float, phi_deg: float = 0.0) -> np.ndarray:
    """Unit incident direction at ``theta_deg`` from the normal and azimuth ``phi_deg`` (0: the x–z plane)."""
    t, p = np.radians(theta_deg), np.radians(phi_deg)
    return np.array([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)])


def bsdf_test(name: str, bsdf, theta_deg: float, n: int, seed: int = 0, params: dict | None = None,
              threshold: float = SIGNIFICANCE, axis: np.ndarray | None = None,
              phi_deg: float | None = None) -> Chi2Result:
    """Chi-square test of ``bsdf.sample`` against ``bsdf.pdf`` for incident angle ``theta_deg``.

    The BSDF is called through :class:`~brdflab.judges.core.guard.CheckedBSDF`: a contract violation gives a
    failed result naming the method, the parameters and the first offending directions. ``axis`` is unused
    (the bins adapt to the lobe, see the module docstring). ``phi_deg``: the incident azimuth (default: the
    test's own, from its seed: :func:`~brdflab.judges.core.seeding.test_azimuth`); the result's ``params``
    hold it as ``phi``.
    """
    from brdflab.judges.core.guard import CheckedBSDF, PluginFault
    from brdflab.judges.core.seeding import test_azimuth

    params = {k: v for k, v in (params or {}).items() if k != "phi"}
    checked_bsdf = CheckedBSDF(bsdf, name, {k: v for k, v in params.items() if k != "theta"})
    phi = test_azimuth(seed) if phi_deg is None else float(phi_deg)
    params["phi"] = round(phi, 3)
    wi1 = incident(theta_deg, params["phi"])

    def sample(u):
        wi = np.ascontiguousarray(np.broadcast_to(wi1, (len(u), 3)))
        r = checked_bsdf.sample(wi, u)
        if r.delta is None or not np.any(r.delta):
            return r.wo, r.pdf
        # A BSDF mixing delta and smooth lobes: the delta samples are outside the density (their pdf is a
        # discrete probability), so they count, with the failed samples, in the cell of expectation n(1 − ∫p dω).
        return r.wo, np.where(r.delta, 0.0, r.pdf)

    def pdf(w):
        return checked_bsdf.pdf(np.ascontiguousarray(np.broadcast_to(wi1, (len(w), 3))), w)

    try:
        return sampler_test(name, sample, pdf, n=n, seed=seed, params=params, threshold=threshold,
                            split_horizon=bool(getattr(checked_bsdf.inner, "has_transmission", False)))
    except PluginFault as fault:
        return faulted(name, params, str(fault), seed, threshold, n)


def warp_test(name: str, warp: Callable, warp_pdf: Callable, n: int, seed: int = 0, params: dict | None = None,
              threshold: float = SIGNIFICANCE, axis: np.ndarray | None = None) -> Chi2Result:
    """Chi-square test of a direction warp against its pdf (``axis`` is unused)."""

    def sample(u):
        w = warp(u[:, :2])
        return w, warp_pdf(w)

    return sampler_test(name, sample, warp_pdf, n=n, seed=seed, params=params, threshold=threshold)


def point_warp_test(name: str, warp: Callable, warp_pdf: Callable, bounds: tuple[float, float, float, float],
                    n: int, bins: int = 20, seed: int = 0, params: dict | None = None,
                    threshold: float = SIGNIFICANCE) -> Chi2Result:
    """Chi-square test of a warp to 2-D points (disk, triangle) on a ``bins``² grid over ``bounds``."""
    rng = np.random.default_rng(seed)
    pts = warp(rng.random((n, 2)))
    x0, x1, y0, y1 = bounds
    xe, ye = np.linspace(x0, x1, bins + 1), np.linspace(y0, y1, bins + 1)
    obs, _, _ = np.histogram2d(pts[:, 0], pts[:, 1], bins=[xe, ye])
    expected = adaptive_integrate(lambda x, y: warp_pdf(np.stack([x, y], axis=1)), xe, ye, n) * n
    stat, dof, pval = pearson(obs, expected)
    r = Chi2Result(name, params or {}, stat, dof, pval, threshold, obs, expected, xe,
                   integral=float(expected.sum() / n), valid_fraction=1.0, seed=seed, n=n)
    r.message = r.summary()
    return r
