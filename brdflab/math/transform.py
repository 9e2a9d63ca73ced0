"""Affine/projective 4×4 transforms in Nori's conventions (spec §3).

A ``<transform>`` starts from the identity and every operation is multiplied from the **left**
(M ← Op·M), so the first listed operation is applied first to points. Points are transformed
homogeneously (divide by w), vectors by the upper-left 3×3 block (no renormalisation), normals by the
inverse transpose of that block.

``lookat`` builds the matrix with columns (l, u', d, o): d = normalize(t − o), l = normalize(û × d),
u' = normalize(d × l) (spec §3).
"""

from __future__ import annotations

import numpy as np


class Transform:
    """A 4×4 transform with its inverse.

    Parameters
    ----------
    matrix
        The 4×4 matrix (float64).
    """

    def __init__(self, matrix: np.ndarray | None = None) -> None:
        self.matrix = np.eye(4) if matrix is None else np.asarray(matrix, dtype=np.float64).reshape(4, 4)
        self.inverse = np.linalg.inv(self.matrix)

    def __matmul__(self, other: Transform) -> Transform:
        return Transform(self.matrix @ other.matrix)

    def is_identity(self) -> bool:
        """True when the matrix is exactly the identity."""
        return bool(np.array_equal(self.matrix, np.eye(4)))

    def determinant3(self) -> float:
        """Determinant of the linear 3×3 part (negative for mirroring transforms)."""
        return float(np.linalg.det(self.matrix[:3, :3]))

    def apply_points(self, p: np.ndarray) -> np.ndarray:
        """Transform (N, 3) points homogeneously (divide by w)."""
        m = self.matrix
        out = p @ m[:3, :3].T + m[:3, 3]
        w = p @ m[3, :3] + m[3, 3]
        if not np.all(w == 1.0):
            out = out / w[:, None]
        return out

    def apply_vectors(self, v: np.ndarray) -> np.ndarray:
        """Transform (N, 3) vectors by the 3×3 block (no renormalisation)."""
        return v @ self.matrix[:3, :3].T

    def apply_normals(self, n: np.ndarray) -> np.ndarray:
        """Transform (N, 3) normals by the inverse transpose (not renormalised)."""
        return n @ self.inverse[:3, :3]

    def origin(self) -> np.ndarray:
        """The image of the point (0, 0, 0)."""
        return self.apply_points(np.zeros((1, 3)))[0]


def translate(v: np.ndarray) -> np.ndarray:
    """Translation matrix."""
    m = np.eye(4)
    m[:3, 3] = v
    return m


def scale(v: np.ndarray) -> np.ndarray:
    """Scaling matrix diag(x, y, z, 1)."""
    return np.diag([v[0], v[1], v[2], 1.0])


def rotate(angle_deg: float, axis: np.ndarray) -> np.ndarray:
    """Right-handed rotation about ``axis`` through the origin (Rodrigues' formula, PBR eq. 3.x).

    The axis is used as given (Nori does not normalise it).
    """
    a = np.radians(angle_deg)
    x, y, z = axis
    c, s = np.cos(a), np.sin(a)
    k = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
    r = c * np.eye(3) + s * k + (1 - c) * np.outer(axis, axis)
    m = np.eye(4)
    m[:3, :3] = r
    return m


def lookat(origin: np.ndarray, target: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Camera-to-world matrix with columns (l, u', d, o) (spec §3).

    Raises
    ------
    ValueError
        If origin equals target or up is parallel to the viewing direction.
    """
    d = target - origin
    nd = np.linalg.norm(d)
    nu = np.linalg.norm(up)
    if nd == 0 or nu == 0:
        raise ValueError("lookat: origin and target coincide or up is zero")
    d = d / nd
    left = np.cross(up / nu, d)
    nl = np.linalg.norm(left)
    if nl < 1e-12:
        raise ValueError("lookat: 'up' is parallel to the viewing direction")
    left /= nl
    new_up = np.cross(d, left)
    new_up /= np.linalg.norm(new_up)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = left, new_up, d, origin
    return m
