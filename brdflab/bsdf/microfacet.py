"""Beckmann microfacet distribution and the rational Smith G1 approximation (spec §11.1, PBR §8.4).

Local frame with the normal along z; cos θ = z.

* Beckmann NDF (PBR eq. 8.9 with α_x = α_y = α):
  D(ω_h) = exp(−tan²θ_h / α²) / (π α² cos⁴θ_h), 0 for cos θ_h ≤ 0.
  tan²θ is formed as (1 − cos²θ)/cos²θ = sin²θ/cos²θ from the clamped cosine, which stays finite and
  non-negative at grazing angles (no tan of an angle, no cancellation in 1 − cos² below 1e-16).
* Smith G1, rational approximation of the Beckmann shadowing term (Walter et al. 2007, eq. 27):
  G1(v, ω_h) = χ⁺((v·ω_h)/(v·n)) · { (3.535b + 2.181b²)/(1 + 2.276b + 2.577b²) if b < 1.6; 1 otherwise },
  b = 1/(α tan θ_v); θ_v = 0 gives b = ∞ and G1 = 1.
* Microfacet reflection: ω_o = 2(ω_i·ω_h)ω_h − ω_i, with the half-vector Jacobian
  dω_h/dω_o = 1/(4 |ω_o·ω_h|) (PBR eq. 8.13), so p(ω_o) = D(ω_h) cos θ_h / (4 |ω_o·ω_h|).

All functions are vectorised and computed in float64.
"""

from __future__ import annotations

import numpy as np


def tan2_theta(cos_t: np.ndarray) -> np.ndarray:
    """tan²θ = (1 − cos²θ)/cos²θ for cos θ > 0 (inf for cos θ ≤ 0)."""
    c2 = cos_t * cos_t
    with np.errstate(divide="ignore", invalid="ignore"):
        t2 = np.maximum(1.0 - c2, 0.0) / c2
    return np.where(cos_t > 0, t2, np.inf)


def beckmann_d(cos_theta_h: np.ndarray, alpha: np.ndarray | float) -> np.ndarray:
    """Beckmann NDF D(ω_h) given cos θ_h (PBR eq. 8.9); 0 for cos θ_h ≤ 0."""
    c = np.asarray(cos_theta_h, dtype=np.float64)
    a2 = np.asarray(alpha, dtype=np.float64) ** 2
    ok = c > 0
    cs = np.where(ok, c, 1.0)
    with np.errstate(over="ignore", under="ignore", invalid="ignore", divide="ignore"):
        c2 = cs * cs
        d = np.exp(-tan2_theta(cs) / a2) / (np.pi * a2 * (c2 * c2))  # cos⁴ by products (as the kernel)
    return np.where(ok & np.isfinite(d), d, 0.0)


def smith_g1(v: np.ndarray, wh: np.ndarray, alpha: np.ndarray | float, vh: np.ndarray | None = None) -> np.ndarray:
    """Rational Smith G1(v, ω_h) for the Beckmann NDF (Walter et al. 2007, eq. 27); ``vh`` = v·ω_h if known."""
    cos_v = v[:, 2]
    if vh is None:
        vh = v[:, 0] * wh[:, 0] + v[:, 1] * wh[:, 1] + v[:, 2] * wh[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        chi = (vh / cos_v) > 0
        tan_v = np.sqrt(np.maximum(1.0 - cos_v * cos_v, 0.0)) / np.abs(cos_v)
        b = 1.0 / (np.asarray(alpha, dtype=np.float64) * tan_v)
    b = np.where(np.isnan(b), np.inf, b)
    small = b < 1.6
    bs = np.where(small, b, 0.0)
    g = np.where(small, (3.535 * bs + 2.181 * bs * bs) / (1.0 + 2.276 * bs + 2.577 * bs * bs), 1.0)
    return np.where(chi, g, 0.0)


def half_vector(wi: np.ndarray, wo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """ω_h = normalize(ω_i + ω_o) and a mask of where it is defined (ω_i ≠ −ω_o)."""
    h = wi + wo
    n = np.sqrt(h[:, 0] ** 2 + h[:, 1] ** 2 + h[:, 2] ** 2)
    ok = n > 1e-12
    return h / np.where(ok, n, 1.0)[:, None], ok


def reflect(wi: np.ndarray, wh: np.ndarray) -> np.ndarray:
    """Mirror ω_i about ω_h: 2(ω_i·ω_h)ω_h − ω_i."""
    d = wi[:, 0] * wh[:, 0] + wi[:, 1] * wh[:, 1] + wi[:, 2] * wh[:, 2]
    return 2.0 * d[:, None] * wh - wi


def reflection_pdf(wh: np.ndarray, wo: np.ndarray, alpha: np.ndarray | float,
                   d: np.ndarray | None = None) -> np.ndarray:
    """p(ω_o) = D(ω_h) cos θ_h / (4 |ω_o·ω_h|) for ω_o reflected about a Beckmann-sampled ω_h.

    ``d`` is D(ω_h) when the caller has it already.
    """
    oh = np.abs(wo[:, 0] * wh[:, 0] + wo[:, 1] * wh[:, 1] + wo[:, 2] * wh[:, 2])
    if d is None:
        d = beckmann_d(wh[:, 2], alpha)
    with np.errstate(divide="ignore", invalid="ignore"):
        p = d * np.maximum(wh[:, 2], 0.0) / (4.0 * oh)
    return np.where(np.isfinite(p), p, 0.0)
