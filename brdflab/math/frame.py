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

The tangents are affine in (n_x, n_y) once σ and a are known, so :class:`NormalFrames` keeps a batch of
frames as (n, σ, a) only and applies them directly: with w = n_x v_x + n_y v_y and q = a·w − v_z,

    (v·s, v·t, v·n) = (v_x + σ n_x q,  σ v_y + n_y q,  w + n_z v_z),

and back, with r = σ n_x v_x + n_y v_y and k = a·r + v_z: (v_x + n_x k, σ v_y + n_y k, n_z v_z − r). That
is 12 products per transform and 4 per frame, against 15 and 18 with explicit tangent arrays.

**The uv tangent.** Anisotropic materials (``BSDF.anisotropic``) need the frame's x axis to follow the
surface's parameterisation: at their points on a mesh with uvs, the frame is (s, t, n) with s the tangent dp/du
of the hit's triangle (:func:`brdflab.scene.tangents.triangle_dpdu`) made orthogonal to the shading normal
(Gram–Schmidt, :func:`uv_tangents`): s = normalize(dp/du − n (n·dp/du)), t = n × s. Where dp/du is zero (no
uvs, degenerate uvs) or within :data:`TANGENT_TOL` of parallel to n, and at every point of an isotropic
material, the frame is Duff's. :class:`NormalFrames` keeps those rows as a mask and explicit (s, t) arrays:
their x and y components are dot products with s and t (z stays n's), the other rows are untouched, so
isotropic materials see the same bits as before.
"""

from __future__ import annotations

import numpy as np

from brdflab.kernels import compiled, load


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


def sparse_combination(cols: tuple[np.ndarray, ...], coefs, const: float = 0.0,
                       out: np.ndarray | None = None) -> np.ndarray:
    """Σ_k coefs[k]·cols[k] + const for 1-D arrays ``cols`` and scalar ``coefs``, skipping the zero
    coefficients (an axis-aligned camera or light has mostly zeros); into ``out`` when given."""
    terms = [(c, k) for c, k in zip(cols, coefs, strict=True) if k != 0.0]
    if out is None:
        out = np.empty(len(cols[0]))
    if not terms:
        out[:] = const
        return out
    np.multiply(terms[0][0], terms[0][1], out=out)
    for c, k in terms[1:]:
        out += c * k
    if const != 0.0:
        out += const
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


#: dp/du counts as parallel to the normal when its part orthogonal to n is at most this fraction of its length.
TANGENT_TOL = 1e-6


def uv_tangents(n: np.ndarray, dpdu: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ok, s, t): s = normalize(dp/du − n (n·dp/du)) (Gram–Schmidt against unit normals ``n``), t = n × s,
    per row of (N, 3) arrays; ``ok`` is False (and s = t = 0) where dp/du is zero or within
    :data:`TANGENT_TOL` of parallel to n (module docstring). The compiled twin is in
    :func:`brdflab.kernels.shading.shade`, with the same operations in the same order."""
    c = dot(n, dpdu)
    s = np.empty(n.shape, order="F")
    for j in range(3):
        np.multiply(n[:, j], c, out=s[:, j])
        np.subtract(dpdu[:, j], s[:, j], out=s[:, j])
    ln = np.sqrt(dot(s, s))
    ok = ln > TANGENT_TOL * np.sqrt(dot(dpdu, dpdu))
    ln[~ok] = 1.0
    s /= ln[:, None]
    s[~ok] = 0.0
    return ok, s, cross(n, s)


class NormalFrames:
    """The frames (s, t, n) of a batch of unit normals ``n`` (N, 3), kept as (n, σ, a) (module docstring).

    Parameters
    ----------
    n
        (N, 3) unit normals.
    sign, a
        σ and a of Duff's frame (computed from ``n`` when None).
    tangent
        None, or (mask (N,) bool, s (N, 3), t (N, 3)): the rows where ``mask`` is True use the explicit frame
        (s, t, n) instead of Duff's (the uv tangent, :func:`uv_tangents`).
    """

    def __init__(self, n: np.ndarray, sign: np.ndarray | None = None, a: np.ndarray | None = None,
                 tangent: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> None:
        self.n = n
        if sign is None:
            nz = n[:, 2]
            sign = np.copysign(1.0, nz)
            a = sign + nz
            np.divide(-1.0, a, out=a)
        self.sign, self.a = sign, a
        self.tangent = tangent

    def with_uv_tangents(self, dpdu: np.ndarray, want: np.ndarray) -> NormalFrames:
        """These frames with the uv tangent (:func:`uv_tangents` of ``dpdu`` (N, 3)) at the rows where ``want``
        (N,) is True and the tangent is defined."""
        ok, s, t = uv_tangents(self.n, dpdu)
        ok &= want
        s[~ok] = 0.0
        t[~ok] = 0.0
        return NormalFrames(self.n, self.sign, self.a, (ok, s, t))

    def take(self, sel: np.ndarray) -> NormalFrames:
        """The frames of the rows ``sel``."""
        tan = None
        if self.tangent is not None:
            tan = (np.take(self.tangent[0], sel), take_rows(self.tangent[1], sel), take_rows(self.tangent[2], sel))
        return NormalFrames(take_rows(self.n, sel), np.take(self.sign, sel), np.take(self.a, sel), tan)

    def tangents(self) -> tuple[np.ndarray, np.ndarray]:
        """Explicit (s, t): :func:`frame_from_normal`, and the uv tangents where there are (for tests and reports)."""
        s, t = frame_from_normal(self.n)
        if self.tangent is not None:
            ok = self.tangent[0]
            s[ok], t[ok] = self.tangent[1][ok], self.tangent[2][ok]
        return s, t

    def to_local(self, v: np.ndarray, negate: bool = False) -> np.ndarray:
        """(v·s, v·t, v·n) per row, Fortran-ordered; of −v with ``negate``."""
        if compiled() and v.dtype == np.float64 and v.ndim == 2 and len(v):  # its twin, bit for bit
            return load("shading").to_local(self, v, negate)
        nx, ny, nz = self.n[:, 0], self.n[:, 1], self.n[:, 2]
        vx, vy, vz = v[:, 0], v[:, 1], v[:, 2]
        out = np.empty(v.shape, order="F")
        w = nx * vx
        w += ny * vy
        q = self.a * w
        q -= vz
        x, y, z = out[:, 0], out[:, 1], out[:, 2]
        np.multiply(self.sign, nx, out=x)
        x *= q
        x += vx
        np.multiply(self.sign, vy, out=y)
        y += ny * q
        np.multiply(nz, vz, out=z)
        z += w
        if self.tangent is not None:
            rows = np.flatnonzero(self.tangent[0])
            if len(rows):
                vr = take_rows(v, rows)
                x[rows] = dot(vr, take_rows(self.tangent[1], rows))
                y[rows] = dot(vr, take_rows(self.tangent[2], rows))
        if negate:
            np.negative(out, out=out)
        return out

    def to_world(self, v: np.ndarray) -> np.ndarray:
        """Local vectors ``v`` (N, 3) back to world space, Fortran-ordered."""
        nx, ny, nz = self.n[:, 0], self.n[:, 1], self.n[:, 2]
        vx, vy, vz = v[:, 0], v[:, 1], v[:, 2]
        out = np.empty(v.shape, order="F")
        r = self.sign * nx
        r *= vx
        r += ny * vy
        k = self.a * r
        k += vz
        x, y, z = out[:, 0], out[:, 1], out[:, 2]
        np.multiply(nx, k, out=x)
        x += vx
        np.multiply(self.sign, vy, out=y)
        y += ny * k
        np.multiply(nz, vz, out=z)
        z -= r
        if self.tangent is not None:
            rows = np.flatnonzero(self.tangent[0])
            if len(rows):
                out[rows] = to_world(take_rows(v, rows), take_rows(self.tangent[1], rows),
                                     take_rows(self.tangent[2], rows), take_rows(self.n, rows))
        return out


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
