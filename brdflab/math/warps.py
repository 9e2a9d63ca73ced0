"""Warps from the unit square to sampling domains, each a ``sample``/``pdf`` pair (spec §11.2).

==============================  ================================================  =====================
warp                            mapping of (ξ1, ξ2)                               pdf
==============================  ================================================  =====================
``square_to_uniform_disk``      r = √ξ1, φ = 2πξ2                                 1/π in the unit disk
``square_to_uniform_triangle``  fold ξ1+ξ2>1 to (1−ξ1, 1−ξ2); barycentrics         2 in the triangle
``square_to_uniform_sphere``    z = 1−2ξ2, φ = 2πξ1                               1/4π
``square_to_uniform_hemisphere``z = 1−ξ2, φ = 2πξ1                                1/2π for z ≥ 0
``square_to_cosine_hemisphere`` r = √ξ1, φ = 2πξ2, z = √(1−ξ1)                    z/π for z ≥ 0
``square_to_beckmann``          tan²θ = −α² ln(1−ξ1), φ = 2πξ2                    D(ω)·cos θ (PBR 8.4)
==============================  ================================================  =====================

All functions take arrays: ``u`` of shape (N, 2) and return (N, 3) directions (or (N, 2) points) in
Fortran order (see :mod:`brdflab.math.frame`); pdfs take (N, 3) directions and return (N,). Computation
is in float64.
"""

from __future__ import annotations

import numpy as np

from brdflab.math.frame import stack_cols

INV_PI = 1.0 / np.pi
INV_2PI = 0.5 / np.pi
INV_4PI = 0.25 / np.pi


def _sphere_dir(z: np.ndarray, phi: np.ndarray) -> np.ndarray:
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    return stack_cols(r * np.cos(phi), r * np.sin(phi), z)


def square_to_uniform_disk(u: np.ndarray) -> np.ndarray:
    """Map (N, 2) uniforms to uniform points (N, 2) in the unit disk."""
    r = np.sqrt(u[:, 0])
    phi = 2.0 * np.pi * u[:, 1]
    return stack_cols(r * np.cos(phi), r * np.sin(phi))


def square_to_uniform_disk_pdf(p: np.ndarray) -> np.ndarray:
    """Density 1/π inside the unit disk, 0 outside."""
    return np.where(np.sum(p * p, axis=1) <= 1.0, INV_PI, 0.0)


def square_to_uniform_triangle(u: np.ndarray) -> np.ndarray:
    """Map (N, 2) uniforms to uniform barycentrics (b0, b1) (N, 2) by folding the square."""
    fold = u[:, 0] + u[:, 1] > 1.0
    b0 = np.where(fold, 1.0 - u[:, 0], u[:, 0])
    b1 = np.where(fold, 1.0 - u[:, 1], u[:, 1])
    return stack_cols(b0, b1)


def square_to_uniform_triangle_pdf(b: np.ndarray) -> np.ndarray:
    """Density 2 over the reference triangle b0, b1 ≥ 0, b0 + b1 ≤ 1."""
    inside = (b[:, 0] >= 0) & (b[:, 1] >= 0) & (b[:, 0] + b[:, 1] <= 1.0)
    return np.where(inside, 2.0, 0.0)


def square_to_uniform_sphere(u: np.ndarray) -> np.ndarray:
    """Map (N, 2) uniforms to uniform directions on the unit sphere."""
    return _sphere_dir(1.0 - 2.0 * u[:, 1], 2.0 * np.pi * u[:, 0])


def square_to_uniform_sphere_pdf(w: np.ndarray) -> np.ndarray:
    """Density 1/(4π) everywhere on the sphere."""
    return np.full(len(w), INV_4PI)


def square_to_uniform_hemisphere(u: np.ndarray) -> np.ndarray:
    """Map (N, 2) uniforms to uniform directions on the upper (z ≥ 0) hemisphere."""
    return _sphere_dir(1.0 - u[:, 1], 2.0 * np.pi * u[:, 0])


def square_to_uniform_hemisphere_pdf(w: np.ndarray) -> np.ndarray:
    """Density 1/(2π) for z ≥ 0, else 0."""
    return np.where(w[:, 2] >= 0, INV_2PI, 0.0)


def square_to_cosine_hemisphere(u: np.ndarray) -> np.ndarray:
    """Map (N, 2) uniforms to cosine-distributed directions (Malley's method, PBR 13.6.3)."""
    r = np.sqrt(u[:, 0])
    phi = 2.0 * np.pi * u[:, 1]
    z = np.sqrt(np.maximum(0.0, 1.0 - u[:, 0]))
    return stack_cols(r * np.cos(phi), r * np.sin(phi), z)


def square_to_cosine_hemisphere_pdf(w: np.ndarray) -> np.ndarray:
    """Density cos θ / π for z ≥ 0, else 0."""
    return np.where(w[:, 2] >= 0, w[:, 2] * INV_PI, 0.0)


def square_to_beckmann(u: np.ndarray, alpha: np.ndarray | float) -> np.ndarray:
    """Sample microfacet normals with density D(ω)·cos θ for the Beckmann NDF (PBR eq. 8.12).

    tan²θ = −α² ln(1 − ξ1), φ = 2πξ2. cos θ is formed as 1/√(1 + tan²θ), which stays accurate for
    tiny α (no cancellation). The closed end ξ1 = 1 maps to a finite horizon direction instead of NaN.
    """
    alpha = np.asarray(alpha, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        tan2 = -(alpha * alpha) * np.log1p(-u[:, 0])  # ξ1 = 1 gives tan²θ = ∞: the horizon
        cos_t = 1.0 / np.sqrt(1.0 + tan2)
        sin_t = np.where(np.isfinite(tan2), np.sqrt(tan2) * cos_t, 1.0)
    phi = 2.0 * np.pi * u[:, 1]
    return stack_cols(sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t)


def square_to_beckmann_pdf(w: np.ndarray, alpha: np.ndarray | float) -> np.ndarray:
    """Density D(ω)·cos θ of :func:`square_to_beckmann` (0 for cos θ ≤ 0)."""
    from brdflab.bsdf.microfacet import beckmann_d

    cos_t = w[:, 2]
    return np.where(cos_t > 0, beckmann_d(cos_t, alpha) * np.maximum(cos_t, 0.0), 0.0)
