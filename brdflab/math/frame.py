"""Orthonormal shading frames, vectorised (spec §7.2).

Arrays of 3-vectors are (N, 3). Hot paths keep them in **Fortran order** (each component contiguous):
NumPy then runs broadcasts, masked selections and row sums on them several times faster than on C-ordered
(N, 3) arrays, while the (N, 3) interface stays the same. :func:`take_rows` and :func:`stack_cols` build
such arrays; element-wise operations between them preserve the layout.

The frame of a unit normal n is (s, t, n) with the branch-free construction of Duff et al., "Building an
Orthonormal Basis, Revisited" (JCGT 6(1), 2017, listing 3): σ = sign(n_z), a = −1/(σ + n_z),
b = n_x n_y a, s = (1 + σ n_x² a, σ b, −σ n_x), t = (b, σ + n_y² a, −n_y). Nori builds its tangents
differently (spec §7.2), but only the normal matters for the isotropic BSDFs in brdflab, and this form
needs no square roots or branches.
"""

from __future__ import annotations

import numpy as np


def stack_cols(*cols: np.ndarray) -> np.ndarray:
    """Stack 1-D columns into an (N, k) Fortran-ordered array."""
    out = np.empty((len(cols[0]), len(cols)), order="F")
    for j, c in enumerate(cols):
        out[:, j] = c
    return out


def take_rows(a: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """``a[idx]`` for a 2-D array, returned in Fortran order (one contiguous gather per column)."""
    out = np.empty((len(idx), a.shape[1]), dtype=a.dtype, order="F")
    for j in range(a.shape[1]):
        np.take(a[:, j], idx, out=out[:, j])
    return out


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot product of two (N, 3) arrays (column products: faster than einsum here)."""
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


def normalize(v: np.ndarray) -> np.ndarray:
    """Return the rows of ``v`` scaled to unit length (zero rows stay zero)."""
    n = np.sqrt(dot(v, v))
    n[~(n > 0)] = 1.0
    return v / n[:, None]


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of two (N, 3) arrays (Fortran-ordered result)."""
    return stack_cols(
        a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1],
        a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
        a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0],
    )


def frame_from_normal(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return tangents (s, t) completing unit normals ``n`` (N, 3) to right-handed frames (s, t, n)."""
    nx, ny, nz = n[:, 0], n[:, 1], n[:, 2]
    sign = np.copysign(1.0, nz)
    a = -1.0 / (sign + nz)
    b = nx * ny * a
    s = np.empty(n.shape, order="F")
    t = np.empty(n.shape, order="F")
    sa = sign * a
    np.multiply(sa, nx * nx, out=s[:, 0])
    s[:, 0] += 1.0
    np.multiply(sign, b, out=s[:, 1])
    np.multiply(-sign, nx, out=s[:, 2])
    t[:, 0] = b
    np.multiply(a, ny * ny, out=t[:, 1])
    t[:, 1] += sign
    np.negative(ny, out=t[:, 2])
    return s, t


def to_local(v: np.ndarray, s: np.ndarray, t: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Express world vectors ``v`` in the frames (s, t, n), all of shape (N, 3)."""
    return stack_cols(dot(v, s), dot(v, t), dot(v, n))


def to_world(v: np.ndarray, s: np.ndarray, t: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Map local vectors ``v`` (N, 3) in frames (s, t, n) back to world space."""
    out = np.empty(v.shape, order="F")
    x, y, z = v[:, 0], v[:, 1], v[:, 2]
    for j in range(3):
        out[:, j] = x * s[:, j] + y * t[:, j] + z * n[:, j]
    return out
