"""Where the light goes: reflected (R) and transmitted (T) albedo, and the delta lobes, for the BRDF views.

* :func:`albedo_quadrature` — ρ(θ_i) = R + T by quadrature: the built-in microfacet conductors by the furnace
  check's half-vector quadrature, a **measured** table by a fixed-order rule at the table's own resolution
  (:func:`measured_albedo`), anything else by the adaptive (cos θ_o, φ_o) rule over the upper hemisphere and,
  for a ``has_transmission`` BSDF, over the lower one too (:func:`albedo_parts`).
* T counts energy, not radiance: T = ∫_{z<0} f |cos θ_o| (η_o/η_i)² dω_o (the white furnace's weighting,
  :func:`brdflab.judges.material.furnace.energy_scale`), so R + T ≤ 1 and = 1 for a lossless interface.
* A delta BSDF (``all_delta``: mirror, dielectric) has f = 0 everywhere; its R and T are the mean sample
  weight over a stratified grid of the sampler's uniforms (:func:`delta_lobes`: exact up to 1/4096 in the
  lobe choice) and its lobes are drawn as spikes at their directions, of length their energy.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from brdflab.texture import LUMINANCE
from brdflab.viz import coords

#: Stratified uniforms of the delta lobes' expectation (per axis: u1, u2 are unused by the built-in deltas).
DELTA_GRID = 4096


def _lum(rgb) -> np.ndarray:
    """Y of (…, 3) linear RGB (as :func:`brdflab.viz.views.luminance`)."""
    return np.asarray(rgb) @ LUMINANCE


def transmits(bsdf) -> bool:
    """Does ``bsdf`` (or the plugin inside a checking wrapper) declare ``has_transmission``?"""
    inner = getattr(bsdf, "inner", bsdf)
    return bool(getattr(inner, "has_transmission", False) or getattr(bsdf, "has_transmission", False))


def all_delta(bsdf) -> bool:
    """Is every lobe of ``bsdf`` a Dirac delta (f = 0 everywhere: nothing to integrate)?"""
    inner = getattr(bsdf, "inner", bsdf)
    return bool(getattr(inner, "all_delta", False) or getattr(bsdf, "all_delta", False))


@dataclass
class DeltaLobe:
    """One delta lobe for an incidence: its direction and the energy it carries."""

    direction: np.ndarray
    """(3,) ω_o."""
    energy: float
    """Probability × weight × (η_o/η_i)² (luminance): R of the reflection, T of the refraction."""

    @property
    def transmitted(self) -> bool:
        """Below the surface (ω_o.z < 0)?"""
        return bool(self.direction[2] < 0)


def delta_lobes(bsdf, theta_i: float, phi_i: float = 0.0) -> list[DeltaLobe]:
    """The delta lobes of ``bsdf`` at an incidence: samples of a stratified grid of lobe-choice uniforms,
    grouped by direction (rounded to 10⁻⁹), each with its mean energy over the grid."""
    from brdflab.judges.material.furnace import energy_scale

    n = DELTA_GRID
    u = np.column_stack([np.full(n, 0.5), np.full(n, 0.5), (np.arange(n) + 0.5) / n])
    wi = np.ascontiguousarray(np.broadcast_to(coords.incident(theta_i, phi_i), (n, 3)))
    s = bsdf.sample(wi, u)
    ok = (s.pdf > 0) & np.all(np.isfinite(s.wo), axis=1)
    if s.delta is not None:
        ok &= np.asarray(s.delta, bool)
    e = np.where(ok, _lum(s.weight) * energy_scale(bsdf, wi, s.wo), 0.0)
    keys = np.round(s.wo[ok], 9)
    out = []
    for key in np.unique(keys, axis=0):
        same = np.all(keys == key, axis=1)
        out.append(DeltaLobe(s.wo[ok][same][0], float(e[ok][same].sum() / n)))
    return sorted(out, key=lambda d: -d.direction[2])


def measured_albedo(bsdf, theta_i: float, order: int = 2, phi_cells: int = 180) -> float:
    """ρ(θ_i) of a :class:`~brdflab.bsdf.measured.Measured` table by a fixed-order rule at its resolution.

    The adaptive rule chased a measured table's noise (every node is a new wiggle: 3–6 s per angle, 2 minutes
    for ``plot``'s albedo). Here the integral is taken over the half vector, where the table lives:
    ρ = ∫ Y f(ω_i, ω_o) max(cos θ_o, 0) 4 (ω_i·ω_h) dω_h with ω_o = reflect(ω_i, ω_h) (dω_o = 4|ω_i·ω_h| dω_h,
    PBR 4th ed. eq. 9.33) and θ_h = u² π/2 (MERL's grading: u = x_θh / 90 is the table's θ_h coordinate), so
    dω_h = π u sin θ_h du dφ_h. Each of the table's 90 θ_h cells (u from i/90 to (i+1)/90, where the trilinear
    interpolation is linear in u) times ``phi_cells`` cells in φ_h gets an ``order``-point Gauss–Legendre rule
    per axis; the horizon (cos θ_o = 0) is where its error lives (see ``tests/test_viz.py``).
    """
    from brdflab.bsdf.measured import N_TH
    from brdflab.bsdf.microfacet import reflect

    x, w = np.polynomial.legendre.leggauss(order)
    ue = np.arange(N_TH + 1) / N_TH
    pe = np.linspace(0.0, 2 * np.pi, phi_cells + 1)
    u = (0.5 * (ue[:-1] + ue[1:])[:, None] + 0.5 * np.diff(ue)[:, None] * x[None, :]).ravel()
    wu = (0.5 * np.diff(ue)[:, None] * w[None, :]).ravel()
    p = (0.5 * (pe[:-1] + pe[1:])[:, None] + 0.5 * np.diff(pe)[:, None] * x[None, :]).ravel()
    wp = (0.5 * np.diff(pe)[:, None] * w[None, :]).ravel()
    U, P = np.meshgrid(u, p, indexing="ij")
    th = U.ravel() ** 2 * (np.pi / 2)
    wh = coords.spherical(th, P.ravel())
    wi = np.ascontiguousarray(np.broadcast_to(coords.incident(theta_i), wh.shape))
    wo = reflect(wi, wh)
    up = wo[:, 2] > 0
    dot = np.sum(wi * wh, axis=1)
    g = np.zeros(len(wh))
    if up.any():
        g[up] = _lum(bsdf.eval(np.ascontiguousarray(wi[up]), np.ascontiguousarray(wo[up]))) * wo[up, 2]
    g *= 4 * dot * np.pi * U.ravel() * np.sin(th)
    return float(np.sum(g * np.outer(wu, wp).ravel()))


def _adaptive(bsdf, theta_i: float, lower: bool) -> float:
    """∫ Y f |cos θ_o| (× (η_o/η_i)² below) over one hemisphere, adaptive in (cos θ_o, φ_o)."""
    from brdflab import effort
    from brdflab.judges.core.quadrature import adaptive_integrate
    from brdflab.judges.material.furnace import energy_scale

    wi = coords.incident(theta_i)

    def integrand(mu, phi):
        wo = coords.spherical(np.arccos(np.clip(mu, -1.0, 1.0)), phi)
        wis = np.ascontiguousarray(np.broadcast_to(wi, wo.shape))
        y = _lum(bsdf.eval(wis, wo))
        y = np.where(np.isfinite(y), y, 0.0) * np.abs(mu)
        return y * energy_scale(bsdf, wis, wo) if lower else y

    mu = np.linspace(-1.0, 0.0, 9) if lower else np.linspace(0.0, 1.0, 9)
    cells = adaptive_integrate(integrand, mu, np.linspace(0.0, 2 * np.pi, 17), n=10**6,
                               max_depth=effort.current().view_depth)
    return float(cells.sum())


def albedo_parts(bsdf, theta_i: float) -> tuple[float, float]:
    """(R, T) of ``bsdf`` at θ_i (φ_i = 0) by quadrature (module docstring); T = 0 without transmission."""
    from brdflab.bsdf.measured import Measured
    from brdflab.bsdf.roughconductor import RoughConductor
    from brdflab.bsdf.roughsubstrate import RoughSubstrate
    from brdflab.judges.material import furnace

    if all_delta(bsdf):
        lobes = delta_lobes(bsdf, theta_i)
        return (sum(d.energy for d in lobes if not d.transmitted), sum(d.energy for d in lobes if d.transmitted))
    if type(bsdf) in (RoughConductor, RoughSubstrate) and bsdf.alpha.constant:
        return furnace.albedo_quadrature(bsdf, theta_i, bsdf.alpha_value), 0.0
    if type(bsdf) is Measured:
        return measured_albedo(bsdf, theta_i), 0.0
    return _adaptive(bsdf, theta_i, False), (_adaptive(bsdf, theta_i, True) if transmits(bsdf) else 0.0)


def albedo_quadrature(bsdf, theta_i: float) -> float:
    """ρ(θ_i) = R + T (luminance) by quadrature (module docstring)."""
    r, t = albedo_parts(bsdf, theta_i)
    return r + t


def monte_carlo_parts(bsdf, theta_i: float, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard error of the BSDF's own sample weights (energy, luminance) split into
    (R, T, R + T): two arrays of 3."""
    from brdflab.judges.material.furnace import energy_scale

    rng = np.random.default_rng(seed)
    wi = np.ascontiguousarray(np.broadcast_to(coords.incident(theta_i), (n, 3)))
    s = bsdf.sample(wi, rng.random((n, 3)))
    w = _lum(s.weight)
    w = np.where(np.isfinite(w), w, 0.0)
    if transmits(bsdf):
        w = w * energy_scale(bsdf, wi, s.wo)
    below = s.wo[:, 2] < 0
    parts = np.stack([np.where(below, 0.0, w), np.where(below, w, 0.0), w])
    return parts.mean(axis=1), parts.std(axis=1, ddof=1) / np.sqrt(n)
