"""An independent visible-normal (VNDF) sampler of the Beckmann rough conductor, for tests.

Another *correct* sampling method than brdflab's (which samples D(ω_h) cos θ_h): the microfacet normal is
drawn from the distribution of normals visible from ω_i (Heitz & d'Eon 2014, "Importance sampling
microfacet-based BSDFs using the distribution of visible normals"; Heitz 2018 for GGX),

    D_ωi(ω_h) = G1(ω_i) max(0, ω_i·ω_h) D(ω_h) / cos θ_i,      p(ω_o) = D_ωi(ω_h) / (4 |ω_o·ω_h|),

the default of Mitsuba 3 and pbrt-v4. Written from the formulas, not from any renderer: in the stretched
configuration (α = 1, ω_i at angle θ) the slope along ω_i's azimuth has density ∝ exp(−x²)(cos θ − x sin θ)
for x < cot θ, with CDF c(√π/2)(1 + erf x) + (s/2) exp(−x²) (c = cos θ, s = sin θ), inverted here by
bisection; the other slope is normal with variance 1/2; the slopes are rotated to ω_i's azimuth and
scaled by α, and ω_h = normalize(−x, −y, 1). G1 is Smith's exact Beckmann term (erf form), so the pdf
integrates to 1 over the sphere (part of it below the horizon: those samples fail).
"""

from __future__ import annotations

import numpy as np
from scipy.special import erf


def smith_g1_exact(cos_t: np.ndarray, alpha: float) -> np.ndarray:
    """Smith's G1 for Beckmann: 1 / (1 + Λ), Λ(a) = (erf(a) − 1)/2 + exp(−a²)/(2a√π), a = 1/(α tan θ)."""
    cos_t = np.clip(cos_t, 1e-12, 1.0)
    tan_t = np.sqrt(np.maximum(1.0 - cos_t**2, 0.0)) / cos_t
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        a = 1.0 / (alpha * tan_t)
        lam = np.where(a > 1e6, 0.0, (erf(a) - 1.0) / 2.0 + np.exp(-a * a) / (2.0 * a * np.sqrt(np.pi)))
    return 1.0 / (1.0 + lam)


def beckmann_d(cos_h: np.ndarray, alpha: float) -> np.ndarray:
    """Beckmann D(ω_h) = exp(−tan²θ_h / α²) / (π α² cos⁴θ_h)."""
    c2 = np.clip(cos_h, 1e-12, 1.0) ** 2
    return np.where(cos_h > 0, np.exp(-(1.0 - c2) / (c2 * alpha * alpha)) / (np.pi * alpha * alpha * c2 * c2), 0.0)


def vndf_pdf(wi: np.ndarray, wo: np.ndarray, alpha: float) -> np.ndarray:
    """p(ω_o) = G1(ω_i) max(0, ω_i·ω_h) D(ω_h) / (cos θ_i · 4 |ω_o·ω_h|) (0 below the horizon)."""
    h = wi + wo
    h /= np.maximum(np.linalg.norm(h, axis=1), 1e-300)[:, None]
    ih = np.sum(wi * h, axis=1)
    oh = np.abs(np.sum(wo * h, axis=1))
    with np.errstate(divide="ignore", invalid="ignore"):
        p = smith_g1_exact(wi[:, 2], alpha) * np.maximum(ih, 0.0) * beckmann_d(h[:, 2], alpha) / (
            wi[:, 2] * 4.0 * oh)
    return np.where((wo[:, 2] > 0) & (wi[:, 2] > 0) & np.isfinite(p), p, 0.0)


def _slope_x(u: np.ndarray, theta: float) -> np.ndarray:
    """Invert the CDF of the visible slope along ω_i's azimuth (stretched space) by bisection."""
    c, s = np.cos(theta), np.sin(theta)
    hi = c / s if s > 1e-9 else 10.0
    hi = min(hi, 10.0)

    def cdf(x):
        return c * np.sqrt(np.pi) / 2 * (1 + erf(x)) + s / 2 * np.exp(-x * x)

    target = u * cdf(hi)
    lo_x, hi_x = np.full_like(u, -10.0), np.full_like(u, hi)
    for _ in range(60):
        mid = 0.5 * (lo_x + hi_x)
        below = cdf(mid) < target
        lo_x, hi_x = np.where(below, mid, lo_x), np.where(below, hi_x, mid)
    return 0.5 * (lo_x + hi_x)


def sample_vndf(wi1: np.ndarray, alpha: float, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Reflect ω_i about a visible normal; returns (ω_o (N, 3), pdf (N,), ω_h (N, 3)); failed: ω_o = 0, pdf 0."""
    n = len(u)
    ws = np.array([alpha * wi1[0], alpha * wi1[1], wi1[2]])
    ws /= np.linalg.norm(ws)
    theta = np.arccos(np.clip(ws[2], -1, 1))
    phi = np.arctan2(ws[1], ws[0]) if np.hypot(ws[0], ws[1]) > 0 else 0.0
    x = _slope_x(u[:, 0], theta)
    from scipy.special import erfinv

    y = erfinv(np.clip(2 * u[:, 1] - 1, -1 + 1e-15, 1 - 1e-15))  # density exp(−y²)/√π
    cp, sp = np.cos(phi), np.sin(phi)
    sx, sy = alpha * (cp * x - sp * y), alpha * (sp * x + cp * y)
    h = np.stack([-sx, -sy, np.ones(n)], axis=1)
    h /= np.linalg.norm(h, axis=1)[:, None]
    wi = np.broadcast_to(wi1, (n, 3))
    wo = 2 * np.sum(wi * h, axis=1)[:, None] * h - wi
    p = vndf_pdf(np.ascontiguousarray(wi), wo, alpha)
    failed = p <= 0
    return np.where(failed[:, None], 0.0, wo), np.where(failed, 0.0, p), h


def vndf_rows(theta_deg: float, alpha: float, n: int, rng: np.random.Generator, f=None) -> np.ndarray:
    """Sample-file rows ``wi wo pdf [w_r w_g w_b]`` of the VNDF sampler; ``f(wi, wo) → (N, 3)`` adds weights."""
    t = np.radians(theta_deg)
    wi1 = np.array([np.sin(t), 0.0, np.cos(t)])
    wo, p, _ = sample_vndf(wi1, alpha, rng.random((n, 2)))
    wi = np.tile(wi1, (n, 1))
    cols = [wi, wo, p]
    if f is not None:
        ok = p > 0
        w = np.zeros((n, 3))
        w[ok] = f(wi[ok], wo[ok]) * (wo[ok, 2] / p[ok])[:, None]
        cols.append(w)
    return np.column_stack(cols)
