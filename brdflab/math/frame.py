"""Orthonormal shading frames, vectorised (spec §7.2).

The frame of a unit normal n is (s, t, n) with, following Nori's deterministic construction,
c = (n_z, 0, −n_x)/√(n_x²+n_z²) if |n_x| > |n_y| else (0, n_z, −n_y)/√(n_y²+n_z²), b = c × n, and
(s, t, n) = (b, c, n). Only the normal matters for the isotropic BSDFs in brdflab.
"""

from __future__ import annotations

import numpy as np


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot product of two (N, 3) arrays (column products: faster than einsum here)."""
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


def normalize(v: np.ndarray) -> np.ndarray:
    """Return the rows of ``v`` scaled to unit length (zero rows stay zero)."""
    n = np.sqrt(dot(v, v))
    n = np.where(n > 0, n, 1.0)
    return v / n[:, None]


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of two (N, 3) arrays."""
    return np.stack(
        [
            a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1],
            a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
            a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0],
        ],
        axis=1,
    )


def frame_from_normal(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return tangents (s, t) completing unit normals ``n`` (N, 3) to right-handed frames (s, t, n)."""
    nx, ny, nz = n[:, 0], n[:, 1], n[:, 2]
    use_x = np.abs(nx) > np.abs(ny)
    c = np.empty_like(n)
    inv_x = 1.0 / np.sqrt(np.maximum(nx * nx + nz * nz, 1e-300))
    inv_y = 1.0 / np.sqrt(np.maximum(ny * ny + nz * nz, 1e-300))
    c[:, 0] = np.where(use_x, nz * inv_x, 0.0)
    c[:, 1] = np.where(use_x, 0.0, nz * inv_y)
    c[:, 2] = np.where(use_x, -nx * inv_x, -ny * inv_y)
    b = cross(c, n)
    return b, c


def to_local(v: np.ndarray, s: np.ndarray, t: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Express world vectors ``v`` in the frames (s, t, n), all of shape (N, 3)."""
    return np.stack([dot(v, s), dot(v, t), dot(v, n)], axis=1)


def to_world(v: np.ndarray, s: np.ndarray, t: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Map local vectors ``v`` (N, 3) in frames (s, t, n) back to world space."""
    return v[:, 0:1] * s + v[:, 1:2] * t + v[:, 2:3] * n
