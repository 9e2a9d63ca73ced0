"""White furnace and energy conservation: directional albedo ρ(θ_i) = ∫ f(ω_i, ω_o) cos θ_o dω_o.

With R0 = 1 (conductor) or k_d = 1 (substrate) a physically plausible model must keep ρ ≤ 1; the
single-scattering microfacet models lose energy at high roughness (light that would scatter between
microfacets is dropped), which the report quantifies as 1 − ρ.

Two independent estimates must agree:

* **Quadrature**: the microfacet lobe is integrated over the half-vector domain, where it is smooth,
  with ω_o = reflect(ω_i, ω_h) and dω_o = 4 |ω_o·ω_h| dω_h; ω_h runs over a Gauss–Legendre grid in the
  Beckmann-CDF variable s = 1 − exp(−tan²θ_h/α²) (which concentrates nodes where D is large) and in
  φ_h. The diffuse lobe is integrated over (cos θ_o, φ_o) with Gauss–Legendre.
* **Monte Carlo**: the mean of the BSDF's own sample weights f cos θ_o / p, with its standard error.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from brdflab.bsdf.microfacet import beckmann_d, reflect
from brdflab.validate.chi2 import incident


@dataclass
class AlbedoPoint:
    """Directional albedo of one BSDF at one incident angle."""

    name: str
    alpha: float
    theta: float
    quadrature: float
    monte_carlo: float
    mc_stderr: float

    @property
    def passed(self) -> bool:
        """ρ ≤ 1 (quadrature within 10⁻³, Monte Carlo within 4σ) and the estimates agree within 4σ + 10⁻³."""
        return (self.quadrature <= 1 + 1e-3 and self.monte_carlo <= 1 + 4 * self.mc_stderr + 1e-3
                and abs(self.quadrature - self.monte_carlo) <= 4 * self.mc_stderr + 1e-3)


def _luminance(rgb: np.ndarray) -> np.ndarray:
    return rgb @ np.array([0.212671, 0.715160, 0.072169])


def albedo_quadrature(bsdf, theta_deg: float, alpha: float, order: int = 96) -> float:
    """ρ(θ_i) by quadrature (see module docstring); returns the luminance of the albedo."""
    wi1 = incident(theta_deg)
    x, w = np.polynomial.legendre.leggauss(order)
    total = 0.0
    lobe = getattr(bsdf, "lobe", "both")
    # Microfacet part in half-vector space.
    s = 0.5 * (x + 1)  # (0, 1)
    phi = np.pi * (x + 1)
    S, P = np.meshgrid(s, phi, indexing="ij")
    W = np.outer(w, w).ravel() * 0.5 * np.pi
    tan2 = -(alpha**2) * np.log1p(-S.ravel())
    cos_h = 1.0 / np.sqrt(1.0 + tan2)
    sin_h = np.sqrt(tan2) * cos_h
    wh = np.stack([sin_h * np.cos(P.ravel()), sin_h * np.sin(P.ravel()), cos_h], axis=1)
    # The Beckmann warp maps (s, φ/2π) ∈ [0, 1)² to ω_h with solid-angle density p_h = D cos θ_h, so
    # dω_h = ds (dφ/2π) / p_h and ∫ g dω_h = ∫∫ g / p_h ds dφ / 2π.
    p_h = beckmann_d(cos_h, alpha) * cos_h
    wi = np.broadcast_to(wi1, wh.shape)
    wo = reflect(wi, wh)
    oh = np.abs((wo * wh).sum(axis=1))
    valid = (wo[:, 2] > 0) & ((wi * wh).sum(axis=1) > 0) & (p_h > 0)
    if lobe != "diffuse":
        spec = _spec_only(bsdf)
        f = _luminance(spec.eval(np.ascontiguousarray(wi), wo))
        with np.errstate(divide="ignore", invalid="ignore"):
            g = np.where(valid, f * wo[:, 2] * 4.0 * oh / p_h, 0.0)
        total += float((np.where(np.isfinite(g), g, 0.0) * W).sum() / (2 * np.pi))
    if lobe != "specular" and hasattr(bsdf, "kd"):
        diff = _diffuse_only(bsdf)
        mu = 0.5 * (x + 1)
        M, P2 = np.meshgrid(mu, phi, indexing="ij")
        r = np.sqrt(1 - M.ravel() ** 2)
        wo2 = np.stack([r * np.cos(P2.ravel()), r * np.sin(P2.ravel()), M.ravel()], axis=1)
        f = _luminance(diff.eval(np.ascontiguousarray(np.broadcast_to(wi1, wo2.shape)), wo2))
        total += float((f * M.ravel() * W).sum())
    return total


def _spec_only(bsdf):
    if hasattr(bsdf, "kd"):
        from brdflab.bsdf.roughsubstrate import RoughSubstrate

        return RoughSubstrate(bsdf.kd, bsdf.alpha, bsdf.int_ior, bsdf.ext_ior, lobe="specular")
    return bsdf


def _diffuse_only(bsdf):
    from brdflab.bsdf.roughsubstrate import RoughSubstrate

    return RoughSubstrate(bsdf.kd, bsdf.alpha, bsdf.int_ior, bsdf.ext_ior, lobe="diffuse")


def albedo_monte_carlo(bsdf, theta_deg: float, n: int = 100_000, seed: int = 0) -> tuple[float, float]:
    """ρ(θ_i) as the mean sample weight (luminance) and its standard error."""
    rng = np.random.default_rng(seed)
    wi = np.ascontiguousarray(np.broadcast_to(incident(theta_deg), (n, 3)))
    w = _luminance(bsdf.sample(wi, rng.random((n, 3))).weight)
    return float(w.mean()), float(w.std(ddof=1) / np.sqrt(n))


def albedo_curve(name: str, make_bsdf, alpha: float, thetas: list[float], n: int = 100_000) -> list[AlbedoPoint]:
    """Directional albedo at each incident angle, by quadrature and Monte Carlo."""
    out = []
    for k, th in enumerate(thetas):
        b = make_bsdf(alpha)
        q = albedo_quadrature(b, th, alpha)
        m, se = albedo_monte_carlo(b, th, n, seed=k)
        out.append(AlbedoPoint(name, alpha, th, q, m, se))
    return out
