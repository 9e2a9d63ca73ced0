"""Fresnel reflectance (spec §11.1; PBR §8.2).

* Exact unpolarised dielectric reflectance F_dielectric(cos θ_i; η_ext, η_int) (PBR eqs. 8.1–8.3):
  cos θ_i is measured on the exterior side; a negative cosine swaps the media. With η = η_i/η_t,
  sin²θ_t = η²(1 − cos²θ_i); total internal reflection (sin²θ_t ≥ 1) gives 1; equal indices give 0;
  otherwise r_s = (η_i cos θ_i − η_t cos θ_t)/(η_i cos θ_i + η_t cos θ_t),
  r_p = (η_t cos θ_i − η_i cos θ_t)/(η_t cos θ_i + η_i cos θ_t), F = (r_s² + r_p²)/2.
* :func:`dielectric_refraction`: the same F for cosines on either side, with Snell's cos θ_t and η = η_i/η_t
  (what a refracting material needs: spec §10.4).
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
    return _fresnel(ci, eta_i, eta_t)[0]


def _fresnel(ci: np.ndarray, eta_i, eta_t) -> tuple[np.ndarray, np.ndarray]:
    """(F, cos θ_t) for cosines ci ≥ 0 on the side of index η_i (PBR eqs. 8.1–8.3); TIR: F = 1, cos θ_t = 0."""
    sin2_t = (eta_i / eta_t) ** 2 * np.maximum(0.0, 1.0 - ci * ci)
    tir = sin2_t >= 1.0
    ct = np.sqrt(np.maximum(0.0, 1.0 - sin2_t))
    with np.errstate(divide="ignore", invalid="ignore"):
        rs = (eta_i * ci - eta_t * ct) / (eta_i * ci + eta_t * ct)
        rp = (eta_t * ci - eta_i * ct) / (eta_t * ci + eta_i * ct)
    f = 0.5 * (rs * rs + rp * rp)
    return np.where(tir | ~np.isfinite(f), 1.0, np.clip(f, 0.0, 1.0)), ct


def dielectric_refraction(cos_i: np.ndarray, eta_ext: float,
                          eta_int: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Fresnel reflectance and Snell's law for cosines on either side (spec §10.4, §11.1).

    ``cos_i`` is measured against the exterior normal: cos θ_i ≥ 0 is outside (η_i, η_t) = (ext, int), a
    negative cosine is inside (int, ext). Returns (F, cos θ_t ≥ 0, η = η_i/η_t), each (N,), with
    sin²θ_t = η²(1 − cos²θ_i); total internal reflection gives F = 1 and cos θ_t = 0. Equal indices give F = 0.

    Examples
    --------
    >>> import numpy as np
    >>> f, ct, eta = dielectric_refraction(np.array([1.0, -1.0]), 1.0, 1.5)
    >>> np.round(f, 4).tolist(), ct.tolist(), np.round(eta, 4).tolist()
    ([0.04, 0.04], [1.0, 1.0], [0.6667, 1.5])
    """
    c = np.clip(np.asarray(cos_i, dtype=np.float64), -1.0, 1.0)
    outside = c >= 0
    eta_i = np.where(outside, eta_ext, eta_int)
    eta_t = np.where(outside, eta_int, eta_ext)
    f, ct = _fresnel(np.abs(c), eta_i, eta_t)
    if eta_ext == eta_int:
        f = np.zeros_like(c)
    return f, ct, eta_i / eta_t


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


def fresnel_conductor(cos_i: np.ndarray, eta: np.ndarray, k: np.ndarray) -> np.ndarray:
    """Exact unpolarised reflectance (N, 3) of a conductor of complex index η + ik (relative to the outside
    medium) for cosines (N,) in [0, 1] (PBR-3 §8.2.2, eqs. 8.5–8.6; Born & Wolf §14.2):

    a² + b² = √((η² − k² − sin²θ)² + 4η²k²), a = √((a² + b² + η² − k² − sin²θ)/2),
    R_s = (a² + b² + cos²θ − 2a cos θ)/(a² + b² + cos²θ + 2a cos θ),
    R_p = R_s (cos²θ (a² + b²) + sin⁴θ − 2a cos θ sin²θ)/(cos²θ (a² + b²) + sin⁴θ + 2a cos θ sin²θ),
    F = (R_s + R_p)/2; k = 0 gives the dielectric F of index η.

    Examples
    --------
    >>> import numpy as np
    >>> f = fresnel_conductor(np.array([1.0]), np.array([1.5, 1.5, 1.5]), np.zeros(3))
    >>> np.round(f, 6).tolist()                                  # ((1.5 − 1)/(1.5 + 1))² = 0.04
    [[0.04, 0.04, 0.04]]
    """
    c = np.clip(np.asarray(cos_i, dtype=np.float64), 0.0, 1.0)[:, None]
    eta = np.asarray(eta, dtype=np.float64)
    k = np.asarray(k, dtype=np.float64)
    c2 = c * c
    s2 = 1.0 - c2
    e2, k2 = eta * eta, k * k
    t0 = e2 - k2 - s2
    a2b2 = np.sqrt(t0 * t0 + 4.0 * e2 * k2)
    a = np.sqrt(np.maximum(0.5 * (a2b2 + t0), 0.0))
    t1 = a2b2 + c2
    t2 = 2.0 * c * a
    with np.errstate(divide="ignore", invalid="ignore"):
        rs = (t1 - t2) / (t1 + t2)
        t3 = c2 * a2b2 + s2 * s2
        t4 = t2 * s2
        rp = rs * (t3 - t4) / (t3 + t4)
    f = 0.5 * (rs + rp)
    return np.asfortranarray(np.where(np.isfinite(f), np.clip(f, 0.0, 1.0), 1.0))
