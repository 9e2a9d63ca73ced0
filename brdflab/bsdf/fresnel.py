"""Fresnel reflectance (spec §11.1; PBR §8.2).

* Exact unpolarised dielectric reflectance F_dielectric(cos θ_i; η_ext, η_int) (PBR eqs. 8.1–8.3):
  cos θ_i is measured on the exterior side; a negative cosine swaps the media. With η = η_i/η_t,
  sin²θ_t = η²(1 − cos²θ_i); total internal reflection (sin²θ_t ≥ 1) gives 1; equal indices give 0;
  otherwise r_s = (η_i cos θ_i − η_t cos θ_t)/(η_i cos θ_i + η_t cos θ_t),
  r_p = (η_t cos θ_i − η_i cos θ_t)/(η_t cos θ_i + η_i cos θ_t), F = (r_s² + r_p²)/2.
* Schlick's approximation with a colour R0: F = R0 + (1 − R0)(1 − cos θ)⁵ per channel (no clamping of
  cos θ, as the spec says; callers pass cosines in [0, 1]).
"""

from __future__ import annotations

import numpy as np


def fresnel_dielectric(cos_i: np.ndarray, eta_ext: float, eta_int: float) -> np.ndarray:
    """Exact unpolarised Fresnel reflectance (N,) for cosines ``cos_i`` on the exterior side."""
    cos_i = np.clip(np.asarray(cos_i, dtype=np.float64), -1.0, 1.0)
    if eta_ext == eta_int:
        return np.zeros_like(cos_i)
    if cos_i.size and cos_i.min() >= 0:
        eta_i, eta_t, ci = eta_ext, eta_int, cos_i  # all on the exterior side (the common case)
    else:
        entering = cos_i >= 0
        eta_i = np.where(entering, eta_ext, eta_int)
        eta_t = np.where(entering, eta_int, eta_ext)
        ci = np.abs(cos_i)
    sin2_t = (eta_i / eta_t) ** 2 * np.maximum(0.0, 1.0 - ci * ci)
    tir = sin2_t >= 1.0
    ct = np.sqrt(np.maximum(0.0, 1.0 - sin2_t))
    with np.errstate(divide="ignore", invalid="ignore"):
        rs = (eta_i * ci - eta_t * ct) / (eta_i * ci + eta_t * ct)
        rp = (eta_t * ci - eta_i * ct) / (eta_t * ci + eta_i * ct)
    f = 0.5 * (rs * rs + rp * rp)
    return np.where(tir | ~np.isfinite(f), 1.0, np.clip(f, 0.0, 1.0))


def pow5(x: np.ndarray) -> np.ndarray:
    """x⁵ by products (x², x⁴, x⁵): exact IEEE products, so the compiled kernels round the same (np.power
    may differ from the C library's pow in the last bit, and is 3.6× slower)."""
    x2 = x * x
    x2 *= x2
    x2 *= x
    return x2


def fresnel_schlick(cos_t: np.ndarray, r0: np.ndarray, scale: np.ndarray | None = None) -> np.ndarray:
    """Schlick's approximation (N, 3), Fortran-ordered, for cosines (N,) and colours ``r0`` ((3,) or
    (N, 3)); times ``scale`` (N,) per point when given (one pass per channel)."""
    m5 = pow5(1.0 - np.asarray(cos_t, dtype=np.float64))
    r0 = np.asarray(r0, dtype=np.float64)
    out = np.empty((len(m5), 3), order="F")
    for j in range(3):
        r = r0[j] if r0.ndim == 1 else r0[:, j]
        c = out[:, j]
        np.multiply(m5, 1.0 - r, out=c)
        c += r
        if scale is not None:
            c *= scale
    return out
