"""Binning for the chi-square tests: equal-probability bins on the sphere placed by an independent pilot sample of the
sampler (θ strips at quantiles, then φ quantiles inside each strip, mixed with uniform directions), histogramming
and the bins' rectangles in (θ, φ) for the quadrature. Used by :mod:`brdflab.judges.material.chi2`.
"""

from __future__ import annotations

import numpy as np

#: Edges below the horizon (radians past π/2) of every reflection test's bins: a reflection lobe sends a thin band
#: of samples just below the surface at grazing incidence (α = 1, θ_i = 89°: 108 of 200 000 within 1° of it), and
#: in one strip from 91° to 180° the quadrature's nodes all missed that band: 0 expected, p = 4e-27 for a correct
#: sampler. The fine strips there hold the band; the expected counts of the empty ones are pooled.
GRAZING_EDGES = np.array([0.0, 0.005, 0.02, 0.06, 0.2, 0.6])


def pilot_bins(theta: np.ndarray, phi: np.ndarray, n_theta: int, n_phi: int,
               split_horizon: bool = False, grazing: bool = False,
               support: tuple[float, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Bin edges from pilot angles: θ strips at quantiles, then φ edges at quantiles inside each strip.

    Returns ``theta_edges`` (m + 1,) from 0 to π and ``phi_edges`` (m, n_phi + 1) from 0 to 2π, both
    non-decreasing (a repeated edge is an empty bin of zero width); m is ``n_theta``, plus with ``grazing`` the
    thin strips of :data:`GRAZING_EDGES` below the horizon (not with ``split_horizon``, whose strips there follow
    the pilot). The tests' automatic binning asks for them; an explicit shape gets exactly that shape.
    ``split_horizon`` (transmissive BSDFs,
    :func:`sphere_theta_edges`): the horizon θ = π/2 is an edge and each hemisphere gets its own quantile
    strips, at least 4 each, so a lobe holding a few per cent of the mass (reflection off glass) never shares
    one wide strip with the rest of its hemisphere. ``support``: the smallest and largest θ of the sampler's
    own pilot directions, added as edges: a density that ends with a jump along a circle of constant θ (a GGX
    reflection lobe stops at cos θ_o = −cos θ_i with D > 0 there) then has the jump at a bin edge, not inside a
    cell whose refinement the quadrature's cell budget cuts short (it lost 5·10⁻⁴ of ∫ p there: GGX, α_u 1,
    α_v 0.25, θ_i 80°, with the grazing strips below the horizon).
    """
    if split_horizon:
        te = sphere_theta_edges(theta, n_theta)
    elif len(theta) < 2 * n_theta:
        te = np.linspace(0.0, np.pi, n_theta + 1)
    else:
        te = np.quantile(theta, np.linspace(0, 1, n_theta + 1))
    te[0], te[-1] = 0.0, np.pi
    te = np.maximum.accumulate(np.clip(te, 0.0, np.pi))
    if grazing and not split_horizon:  # thin strips just below the horizon (see GRAZING_EDGES)
        low = te[te < np.pi / 2]
        te = np.concatenate([low, np.pi / 2 + GRAZING_EDGES, te[te > np.pi / 2 + GRAZING_EDGES[-1]]])
        n_theta = len(te) - 1
    if support is not None:
        extra = [t for t in support if 0.0 < t < np.pi and not np.isclose(te, t, rtol=0, atol=1e-9).any()]
        te = np.sort(np.concatenate([te, extra]))
        n_theta = len(te) - 1
    strip = np.clip(np.searchsorted(te, theta, side="right") - 1, 0, n_theta - 1)
    pe = np.empty((n_theta, n_phi + 1))
    for i in range(n_theta):
        ph = phi[strip == i]
        pe[i] = np.quantile(ph, np.linspace(0, 1, n_phi + 1)) if len(ph) >= 2 * n_phi \
            else np.linspace(0.0, 2 * np.pi, n_phi + 1)
    pe[:, 0], pe[:, -1] = 0.0, 2 * np.pi
    return te, np.maximum.accumulate(np.clip(pe, 0.0, 2 * np.pi), axis=1)


def sphere_theta_edges(theta: np.ndarray, n_theta: int) -> np.ndarray:
    """θ edges over the whole sphere with the horizon as an edge: k strips above at the quantiles of the pilot's
    upper θ, n_theta − k below at those of its lower θ, k ∝ the upper share of the pilot (4 ≤ k ≤ n_theta − 4)."""
    up = theta[theta < np.pi / 2]
    dn = theta[theta >= np.pi / 2]
    k = int(np.clip(round(n_theta * len(up) / max(len(theta), 1)), 4, max(n_theta - 4, 4)))

    def edges(x, a, b, m):
        if len(x) < 2 * m:
            return np.linspace(a, b, m + 1)
        e = np.quantile(x, np.linspace(0, 1, m + 1))
        e[0], e[-1] = a, b
        return e

    return np.concatenate([edges(up, 0.0, np.pi / 2, k)[:-1], edges(dn, np.pi / 2, np.pi, n_theta - k)])


def theta_edges_from_pilot(theta: np.ndarray, n_theta: int) -> np.ndarray:
    """θ edges at the quantiles of pilot angles, covering [0, π] (see :func:`pilot_bins`)."""
    return pilot_bins(theta, np.zeros(len(theta)), n_theta, 1)[0]


def bin_counts(theta: np.ndarray, phi: np.ndarray, theta_edges: np.ndarray, phi_edges: np.ndarray) -> np.ndarray:
    """Histogram (n_theta, n_phi) of angles in the bins of :func:`pilot_bins`."""
    nt, nph = phi_edges.shape[0], phi_edges.shape[1] - 1
    i = np.clip(np.searchsorted(theta_edges, theta, side="right") - 1, 0, nt - 1)
    # One sorted key per bin: strip index · 10 + φ edge (φ < 2π < 10), so one searchsorted finds both.
    keys = (np.arange(nt)[:, None] * 10.0 + phi_edges[:, :-1]).ravel()
    flat = np.searchsorted(keys, i * 10.0 + np.clip(phi, 0.0, 2 * np.pi), side="right") - 1
    flat = np.clip(flat, i * nph, i * nph + nph - 1)
    return np.bincount(flat, minlength=nt * nph).reshape(nt, nph).astype(float)


def bin_rects(theta_edges: np.ndarray, phi_edges: np.ndarray) -> tuple[np.ndarray, ...]:
    """(θ_a, θ_b, φ_a, φ_b) of every bin, flattened in (strip, φ) order."""
    nph = phi_edges.shape[1] - 1
    ta = np.repeat(theta_edges[:-1], nph)
    tb = np.repeat(theta_edges[1:], nph)
    return ta, tb, phi_edges[:, :-1].ravel(), phi_edges[:, 1:].ravel()


def bin_shape(n: int) -> tuple[int, int]:
    """(n_theta, n_phi) for n samples: 20 × 40 from 20 000 samples, fewer bins (≥ 25 expected each) below."""
    k = int(np.clip(n // 25, 8, 800))
    nt = max(2, int(round(np.sqrt(k / 2))))
    return nt, max(4, k // nt)
