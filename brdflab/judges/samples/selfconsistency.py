"""Method-agnostic self-consistency of sampled directions and their reported pdf.

A sampler is correct when the density of the directions it draws equals the pdf it reports, whatever the
sampling *method* (Beckmann normals, visible normals, another lobe-selection probability, ...). This module
tests exactly that, from a file of samples ω_k with reported densities p_k alone — no pdf *function* of the
user's sampler is needed — using a reference density r (brdflab's pdf of the named BSDF or warp, a function
it can integrate) only to shape the test.

The identity (importance sampling)
----------------------------------
If ω has density q and the sampler reports p = q, then for every bin B (N samples, failed ones included,
ω_k ↦ 0 for a failed sample)

    T_B = (1/N) Σ_k 1_B(ω_k) r(ω_k) / p_k      has mean      μ_B = ∫_B r dω                        (1)

over the part of B where p > 0 (Veach 1997, eq. 2.8 with integrand 1_B·r). μ_B comes from adaptive
quadrature of r (:func:`brdflab.judges.material.chi2.integrate_sphere_bins`), never from the data. A wrong pdf
column (p ≠ q) biases T_B by the factor q/p averaged over B with weight r; a sampler that fails more often
than its pdf admits lowers every T_B; a sampler that never reaches part of r's support leaves μ_B > 0
there with T_B = 0. With p = r (brdflab's own method) T_B is the bin's count / N, and the test below is
Pearson's chi-square; with another method the weights r/p_k vary and the same test stays calibrated.

Why r and not the bare solid angle (1_B/p_k)
---------------------------------------------
The plain estimator of |B| has weights 1/p_k: unbounded in the tails of a sharp lobe (α = 10⁻³: 1/p is
10⁻⁶ at the peak and ~10⁴⁰⁰ a few degrees away), so its variance is infinite for practical purposes and a
correct sampler would be rejected at random. With r in the numerator the weights r/p_k are the ratio of
two densities of the *same* BSDF: bounded wherever both samplers follow f·cos θ (for Beckmann normals vs
visible normals, r/p = cos θ_h cos θ_i / (G1(ω_i) |ω_i·ω_h|) ≤ ~2/G1 over the upper hemisphere), and it
tests coverage where it matters (where the named BSDF has mass). The effective sample size
(Σ w)²/Σ w² is reported; below 2 % of the valid samples the test declares itself blind (the file's
method is too far from brdflab's for this test; nothing is claimed) instead of guessing. Identity (1)
holds for any known r, so :func:`rescue` repeats the test with r = cos θ/π and r = 1/(2π) on the
hemisphere for such a sampler (cosine-weighted directions for a sharp conductor: correct, if wasteful).

Bins and statistic
------------------
Bins are placed by a pilot sample of brdflab's own sampler (equal r-probability, plus 10 % uniform
directions), as in :mod:`brdflab.judges.material.chi2`; bins with N·μ_B < 5 are pooled into one cell. Per cell
c, with M_c = (1/N) Σ_{k∈c} w_k² and the variance of one term under H0 estimated by
V_c = μ_c · (M_c / T_c) − μ_c² (the r-weighted mean of w in the cell times μ_c; for w ≡ 1 it is
μ_c(1 − μ_c), Pearson's), the statistic X² = Σ_c N (T_c − μ_c)² / V_c is referred to χ² with one degree
of freedom per cell (cells are nearly independent: their covariance is −μ_c μ_d; ignoring it is
conservative by about one degree of freedom). A constant factor in the pdf column (or a failure rate the
pdf does not admit) shifts every cell a little; the total Σ_c T_c against ∫ r dω is therefore tested on
its own too (a z-test with the same variance estimate) and the two p-values are Šidák-combined,
p = 1 − (1 − min(p_cells, p_total))². Rejection at the (Šidák-corrected) threshold. Measured
false-alarm rates and power are in ``tests/test_selfconsistency.py`` and docs/external-samples.md.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from brdflab.judges.core.precision import rounding_variance
from brdflab.judges.material import chi2 as c2

#: Cells with fewer expected r-weighted samples than this are pooled.
MIN_EXPECTED = 5.0
#: Below this effective sample size fraction the test is blind (see the module docstring).
MIN_ESS_FRACTION = 0.02


@dataclass
class Binning:
    """Bins of one test: edges, r-mass per bin, and the cell of every valid sample (pooled bins → one cell)."""

    theta_edges: np.ndarray
    phi_edges: np.ndarray
    mu: np.ndarray
    """(n_cells,) μ_c = ∫_c r dω."""
    cell: np.ndarray
    """(k,) cell index of each valid sample."""
    r: np.ndarray
    """(k,) r(ω_k)."""
    n: int
    integral: float
    integration_error: float
    bin_cell: np.ndarray = field(repr=False, default=None)
    """(n_theta * n_phi,) cell of every bin."""
    flat: np.ndarray = field(repr=False, default=None)
    """(k,) bin of each valid sample."""
    mass: np.ndarray = field(repr=False, default=None)
    """(n_theta * n_phi,) ∫_B r dω per bin."""


@dataclass
class SelfConsistency:
    """Outcome of the self-consistency test of one sampler (one ω_i).

    Attributes
    ----------
    statistic, dof, p_value, threshold
        X², its degrees of freedom (cells), the p-value and the rejection threshold.
    mass_ratio
        (1/N) Σ r/p_k divided by ∫ r dω: 1 when the pdf column is right on average (2 means the column is
        half the true density, or the sampler fails less often than it admits).
    ess
        Effective sample size (Σ w)² / Σ w² of the weights w = r/p_k.
    n, valid
        Samples (failed included) and valid ones.
    observed, expected
        N·T_B and N·μ_B per bin, (n_theta, n_phi), for reports.
    fault
        Why the test could not give a verdict (blind), or None.
    """

    statistic: float
    dof: int
    p_value: float
    threshold: float
    mass_ratio: float
    ess: float
    n: int
    valid: int
    observed: np.ndarray = field(default=None, repr=False)
    expected: np.ndarray = field(default=None, repr=False)
    theta_edges: np.ndarray = field(default=None, repr=False)
    phi_edges: np.ndarray = field(default=None, repr=False)
    fault: str | None = None
    #: The density r that shaped the test (brdflab's pdf of the reference, or a fallback, see :func:`rescue`).
    shape: str = "brdflab's pdf"

    @property
    def blind(self) -> bool:
        """True when the test could not judge (see ``fault``)."""
        return self.fault is not None

    @property
    def passed(self) -> bool:
        """Self-consistent at the threshold (never for a blind test)."""
        return self.fault is None and self.dof > 0 and bool(np.isfinite(self.p_value)) and \
            bool(self.p_value > self.threshold)

    def summary(self) -> str:
        """One line: p-value, X²/dof, the mass ratio and the effective sample size."""
        if self.fault:
            return f"self-consistency: {self.fault}"
        shaped = "" if self.shape == "brdflab's pdf" else f", r = {self.shape}"
        return (f"self-consistency p = {self.p_value:.4g} (X² = {self.statistic:.1f}, {self.dof} dof{shaped}), "
                f"Σ r/p / N∫r = {self.mass_ratio:.4f}, effective samples {self.ess:.0f} of {self.valid}")


def make_binning(wo: np.ndarray, n_total: int, ref_pdf: Callable[[np.ndarray], np.ndarray], pilot: np.ndarray,
                 mix_rng: np.random.Generator, shape: tuple[int, int] | None = None,
                 split_horizon: bool = False) -> Binning:
    """Bins from the reference pilot, r-mass per bin by quadrature, and the cell of each valid sample.

    Parameters
    ----------
    wo
        (k, 3) valid sampled directions (unit vectors); the other ``n_total − k`` samples failed.
    ref_pdf
        The reference density r, (M, 3) → (M,).
    pilot
        (m, 3) directions from r's own sampler (independent of ``wo``): they place the bins only.
    shape
        (n_theta, n_phi); default about N/100 bins (:func:`brdflab.judges.material.chi2.bin_shape` of N/4).
    split_horizon
        Each hemisphere its own strips (a transmissive reference, :func:`brdflab.judges.core.binning.pilot_bins`).
    """
    from brdflab.math.warps import square_to_uniform_sphere

    nt, nph = shape or c2.bin_shape(max(n_total // 4, 1))
    z = np.array([0.0, 0.0, 1.0])
    extra = square_to_uniform_sphere(mix_rng.random((max(len(pilot) // 9, 200), 2)))
    pt, pp = c2.to_angles(np.concatenate([np.asarray(pilot, dtype=float).reshape(-1, 3), extra]), z)
    te, pe = c2.pilot_bins(pt, pp, nt, nph, split_horizon, grazing=shape is None)
    mass, merr = c2.integrate_sphere_bins(ref_pdf, te, pe, n_total)
    mass = mass.ravel()
    th, ph = c2.to_angles(np.asarray(wo, dtype=float).reshape(-1, 3), z)
    nb = mass.size  # the strips of pilot_bins (its thin grazing strips included) × n_phi
    flat = _bin_index(th, ph, te, pe)
    small = mass * n_total < MIN_EXPECTED
    bin_cell = np.empty(nb, dtype=np.int64)
    n_big = int((~small).sum())
    bin_cell[~small] = np.arange(n_big)
    bin_cell[small] = n_big
    mu = np.append(mass[~small], mass[small].sum())
    if mu[-1] * n_total < MIN_EXPECTED and n_big > 0:  # the pooled cell is too small itself: merge it
        largest = int(np.argmax(np.where(small, -1.0, mass)))
        bin_cell[small] = bin_cell[largest]
        mu = mu[:-1].copy()
        mu[bin_cell[largest]] += mass[small].sum()
    r = np.asarray(ref_pdf(np.asarray(wo, dtype=float).reshape(-1, 3)), dtype=np.float64)
    return Binning(te, pe, mu, bin_cell[flat], r, n_total, float(mass.sum()), float(merr.sum()), bin_cell,
                   flat, mass)


def _bin_index(theta: np.ndarray, phi: np.ndarray, te: np.ndarray, pe: np.ndarray) -> np.ndarray:
    """Flat bin index (strip · n_phi + φ bin) of every direction (as
    :func:`brdflab.judges.material.chi2.bin_counts`)."""
    nt, nph = pe.shape[0], pe.shape[1] - 1
    i = np.clip(np.searchsorted(te, theta, side="right") - 1, 0, nt - 1)
    keys = (np.arange(nt)[:, None] * 10.0 + pe[:, :-1]).ravel()
    flat = np.searchsorted(keys, i * 10.0 + np.clip(phi, 0.0, 2 * np.pi), side="right") - 1
    return np.clip(flat, i * nph, i * nph + nph - 1)


#: Half-width (in φ bins of the same θ strip) of the window over which the weights' second moment is pooled.
SMOOTH = 2


def _smoothed_rho(b: Binning, w: np.ndarray, t: np.ndarray, m2: np.ndarray, rho_all: float) -> np.ndarray:
    """ρ_c = Σ w² / Σ w per cell, each bin's sums pooled over its φ neighbours (±:data:`SMOOTH` bins).

    A cell's own Σ w²/Σ w is a ratio of skewed sums: low exactly when the cell happened to miss the rare
    large weights (and then T_c is low too), which would make the test anti-conservative. r/p is smooth
    in direction, so pooling the neighbours' sums estimates the same ρ with ~5× less noise.
    """
    nt, nph = b.phi_edges.shape[0], b.phi_edges.shape[1] - 1
    s1 = np.bincount(b.flat, w, minlength=nt * nph).reshape(nt, nph)
    s2 = np.bincount(b.flat, w * w, minlength=nt * nph).reshape(nt, nph)
    k = min(SMOOTH, (nph - 1) // 2)
    s1s = sum(np.roll(s1, j, axis=1) for j in range(-k, k + 1)).ravel()
    s2s = sum(np.roll(s2, j, axis=1) for j in range(-k, k + 1)).ravel()
    nc = len(b.mu)
    num = np.bincount(b.bin_cell, s2s, minlength=nc)
    den = np.bincount(b.bin_cell, s1s, minlength=nc)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(den > 0, num / np.where(den > 0, den, 1.0), rho_all)


def statistic(b: Binning, pdf_column: np.ndarray) -> tuple[float, int, float, np.ndarray, float, float]:
    """X², cells, p-value, per-cell T_c, the mass ratio and the effective sample size for a pdf column.

    ``pdf_column`` (k,) holds the reported densities of the valid samples (> 0). Vectorised; cheap enough to
    re-evaluate for many hypothetical corrections of the column (hints).
    """
    from scipy import stats

    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        w = np.where(pdf_column > 0, b.r / pdf_column, 0.0)
        w = np.where(np.isfinite(w), w, 0.0)
        n = max(b.n, 1)
        nc = len(b.mu)
        t = np.bincount(b.cell, w, minlength=nc) / n
        m2 = np.bincount(b.cell, w * w, minlength=nc) / n
        sw, sw2 = np.float64(w.sum()), np.float64((w * w).sum())
        rho_all = sw2 / sw if sw > 0 else 1.0
        rho = _smoothed_rho(b, w, t, m2, rho_all)
        var = np.maximum(b.mu * rho - b.mu**2, 1e-300)
        keep = b.mu > 0
        stat = float((n * (t - b.mu) ** 2 / var)[keep].sum())
        dof = int(keep.sum())
        # Weights overflowing (a reported pdf of 1e-300 where r is not small) are an absurd column: p = 0.
        p_cells = (float(stats.chi2.sf(stat, dof)) if np.isfinite(stat) else 0.0) if dof > 0 else float("nan")
        # The total Σ_c T_c against ∫ r (a constant factor in the column, a wrong failure rate): a z-test with
        # the sample variance of the per-sample terms (w, 0 for a failed sample), whose mean is the total.
        # (The cells' μ·ρ − μ² form cancels catastrophically here: μ ≈ 1 and w ≈ 1 for similar methods.)
        # With w ≡ 1 and no failure (brdflab's own method) the total is exact: only the quadrature error remains.
        mu_t = float(b.mu.sum())
        # The larger of the sample variance and E[w²] − μ² (H0's: it stays positive when no sample happened
        # to fail although ∫ r < 1 by 10⁻⁵, where the sample variance is 0).
        # + the rounding floor of float32 columns (judges.core.precision): 10⁻⁷ of rounding is never a bug.
        var_t = max(sw2 / n - (sw / n) ** 2, sw2 / n - mu_t**2, 0.0) / n + (3 * b.integration_error) ** 2 + \
            rounding_variance(mu_t)
        z_t = (sw / n - mu_t) / np.sqrt(max(var_t, 1e-300))
        p_total = float(2 * stats.norm.sf(abs(z_t))) if np.isfinite(z_t) else 0.0
        # Two tests of one hypothesis, Šidák-combined: p = 1 − (1 − min p)².
        p = 1.0 - (1.0 - min(p_cells, p_total)) ** 2 if np.isfinite(p_cells) and np.isfinite(p_total) else p_cells
    ratio = (sw / n) / b.integral if b.integral > 0 else float("nan")
    ess = sw * sw / sw2 if sw2 > 0 else 0.0
    return stat, dof, p, t, ratio, ess


def self_consistency_test(wo: np.ndarray, pdf_column: np.ndarray, n_total: int,
                          ref_pdf: Callable[[np.ndarray], np.ndarray], pilot: np.ndarray, *,
                          threshold: float = c2.SIGNIFICANCE, mix_rng: np.random.Generator | None = None,
                          binning: Binning | None = None) -> SelfConsistency:
    """Test that directions follow the pdf reported beside them, whatever the sampling method.

    Parameters
    ----------
    wo
        (k, 3) valid sampled directions; ``n_total − k`` samples failed.
    pdf_column
        (k,) the densities the sampler reported for them (> 0).
    n_total
        Samples drawn, failed ones included.
    ref_pdf, pilot
        A reference density r (brdflab's pdf of the same BSDF) and a pilot sample of r's own sampler,
        independent of ``wo`` (places the bins).
    threshold
        Rejection threshold of the p-value.
    binning
        Precomputed :func:`make_binning` (to test several columns of the same samples).

    Returns
    -------
    SelfConsistency
        ``passed`` when the samples are consistent with their pdf column (module docstring).

    Examples
    --------
    Cosine-weighted directions with their own pdf, judged with a uniform-hemisphere reference (another
    method: the test does not care):

    >>> import numpy as np
    >>> from brdflab.math import warps
    >>> rng = np.random.default_rng(1)
    >>> wo = warps.square_to_cosine_hemisphere(rng.random((20_000, 2)))
    >>> pilot = warps.square_to_uniform_hemisphere(rng.random((5_000, 2)))
    >>> ok = self_consistency_test(wo, wo[:, 2] / np.pi, 20_000, warps.square_to_uniform_hemisphere_pdf, pilot,
    ...                            mix_rng=rng)
    >>> bad = self_consistency_test(wo, np.full(20_000, 1 / (2 * np.pi)), 20_000,
    ...                             warps.square_to_uniform_hemisphere_pdf, pilot, mix_rng=rng)
    >>> ok.passed, bad.passed
    (True, False)
    """
    wo = np.asarray(wo, dtype=float).reshape(-1, 3)
    b = binning or make_binning(wo, n_total, ref_pdf, pilot, mix_rng or np.random.default_rng(0))
    stat, dof, p, t, ratio, ess = statistic(b, np.asarray(pdf_column, dtype=float))
    nt, nph = b.phi_edges.shape[0], b.phi_edges.shape[1] - 1
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        w = np.where(pdf_column > 0, b.r / np.asarray(pdf_column, dtype=float), 0.0)
    obs = np.bincount(b.flat, np.where(np.isfinite(w), w, 0.0), minlength=nt * nph).reshape(nt, nph)
    exp = (b.mass * b.n).reshape(nt, nph)
    fault = None
    if len(wo) == 0:
        fault = "no valid sample: nothing to test"
    elif ess < MIN_ESS_FRACTION * len(wo):
        fault = (f"blind: the file's sampling method is too far from brdflab's for this test (effective samples "
                 f"{ess:.0f} of {len(wo)})")
    elif dof < 4:
        fault = f"blind: only {dof} populated cells"
    return SelfConsistency(stat, dof, p, threshold, ratio, ess, n_total, len(wo), obs, exp, b.theta_edges,
                           b.phi_edges, fault)


#: Fallback shaping densities for :func:`rescue`: (name, warp, pdf), hemisphere only (BSDF reflection).
def _fallback_shapes():
    from brdflab.math import warps

    return [("the cosine-weighted hemisphere", warps.square_to_cosine_hemisphere,
             warps.square_to_cosine_hemisphere_pdf),
            ("the uniform hemisphere", warps.square_to_uniform_hemisphere, warps.square_to_uniform_hemisphere_pdf)]


def rescue(wo: np.ndarray, pdf_column: np.ndarray, n_total: int, threshold: float, rng: np.random.Generator,
           n_pilot: int = 10_000) -> tuple[SelfConsistency, Binning] | None:
    """The self-consistency test shaped by a simple density instead, when brdflab's pdf left it blind.

    A correct sampler far from brdflab's (cosine-weighted directions for a sharp conductor: inefficient but
    unbiased) gives weights r/p spanning orders of magnitude. Identity (1) holds for *any* known density r,
    so the test is repeated with r = cos θ/π, then r = 1/(2π) on the hemisphere, and the first that is not
    blind is returned (or None). The price: these r cover the whole upper hemisphere, so the sampler must
    reach all of it (a correct sampler of a BSDF that is zero on part of the hemisphere would be rejected:
    this is used only where brdflab's own shaping could not judge and its own sampler's chi-square fails).
    """
    for name, warp, pdf in _fallback_shapes():
        pilot = warp(rng.random((n_pilot, 2)))
        b = make_binning(wo, n_total, pdf, pilot, rng)
        r = self_consistency_test(wo, pdf_column, n_total, pdf, pilot, threshold=threshold, binning=b)
        r.shape = name
        if not r.blind:
            return r, b
    return None
