"""Kernels of the shading points (compiled engine): hit records, shading frames and local ω_i in one pass;
directions into the shading frames (:func:`to_local`).

The NumPy specification is :meth:`brdflab.scene.geometry.Geometry.surface` (positions p = p0 + u e1 + v e2,
face normals, interpolated and renormalised vertex normals where the mesh has them, uvs; spec §7.2)
followed by :func:`brdflab.integrator.common.make_shading_points` (the frame of the shading normal kept as
(σ, a), Duff et al. 2017, and ω_i = −d in it). Each point's values are formed with the same operations in
the same order, so the two engines agree to the bit.
"""

from __future__ import annotations

import math

import numpy as np

from brdflab.kernels.buffers import columns
from brdflab.kernels.jit import BOOL, FLAGS, IDX, IN1, IN1_F4, IN2, OUT1, OUT2, OUT_IDX, inline, kernel


@inline
def vertex_normal(tri_nrm, k, u, v):
    """The vertex normals of triangle ``k`` interpolated at barycentrics (u, v) and renormalised, and whether
    that worked (length > 0), as ``Geometry._shading_normals`` computes them."""
    mx = tri_nrm[0, k] + tri_nrm[3, k] * u + tri_nrm[6, k] * v
    my = tri_nrm[1, k] + tri_nrm[4, k] * u + tri_nrm[7, k] * v
    mz = tri_nrm[2, k] + tri_nrm[5, k] * u + tri_nrm[8, k] * v
    ln = math.sqrt(mx * mx + my * my + mz * mz)
    if ln > 0:
        inv = 1.0 / ln
        return mx * inv, my * inv, mz * inv, True
    return mx, my, mz, False


@inline
def in_frame(nx, ny, nz, s, a, vx, vy, vz):
    """(v·s, v·t, v·n) in the frame of n kept as (σ, a), with the operations of
    :meth:`~brdflab.math.frame.NormalFrames.to_local` in its order."""
    w = nx * vx + ny * vy
    q = a * w - vz
    return s * nx * q + vx, s * vy + ny * q, nz * vz + w


@kernel(IDX, IDX, IN1_F4, IN1_F4, FLAGS, IN2, IN2, IN2, IN2, IN2, BOOL, IDX, BOOL, OUT2, OUT2, OUT2, OUT2, OUT1, OUT1,
        OUT2, OUT_IDX)
def shade(idx, prim, bu32, bv32, smooth, d, tri_pos, face_n, tri_nrm, tri_uv, want_uv, tri_member, want_member,
          p, ng, ns, uv, sign, a, wi, member):
    """Fill p, n_g, n_s, uv, σ, a, ω_i and (with ``want_member``) the material within its family of the camera
    hits ``idx`` (see the module docstring)."""
    for i in range(idx.shape[0]):
        r = idx[i]
        k = prim[r]
        if want_member:
            member[i] = tri_member[k]
        u, v = np.float64(bu32[r]), np.float64(bv32[r])
        for j in range(3):
            p[i, j] = tri_pos[j, k] + tri_pos[3 + j, k] * u + tri_pos[6 + j, k] * v
            ng[i, j] = face_n[j, k]
            ns[i, j] = face_n[j, k]
        if smooth[i]:
            mx, my, mz, ok = vertex_normal(tri_nrm, k, u, v)
            if ok:
                ns[i, 0], ns[i, 1], ns[i, 2] = mx, my, mz
        if want_uv:
            if tri_uv.shape[0] == 6:
                uv[i, 0] = tri_uv[0, k] + tri_uv[2, k] * u + tri_uv[4, k] * v
                uv[i, 1] = tri_uv[1, k] + tri_uv[3, k] * u + tri_uv[5, k] * v
            else:
                uv[i, 0], uv[i, 1] = u, v
        nx, ny, nz = ns[i, 0], ns[i, 1], ns[i, 2]
        s = math.copysign(1.0, nz)
        aa = -1.0 / (s + nz)
        sign[i], a[i] = s, aa
        x, y, z = in_frame(nx, ny, nz, s, aa, d[r, 0], d[r, 1], d[r, 2])
        wi[i, 0], wi[i, 1], wi[i, 2] = -x, -y, -z


@kernel(IN2, IN1, IN1, IN2, BOOL, OUT2)
def frame_to_local(n, sign, a, v, negate, out):
    """(v·s, v·t, v·n) per row in the frames (n, σ, a), negated with ``negate``: the operations of
    :meth:`brdflab.math.frame.NormalFrames.to_local` in its order."""
    for i in range(v.shape[0]):
        x, y, z = in_frame(n[i, 0], n[i, 1], n[i, 2], sign[i], a[i], v[i, 0], v[i, 1], v[i, 2])
        if negate:
            x, y, z = -x, -y, -z
        out[i, 0], out[i, 1], out[i, 2] = x, y, z


def to_local(frames, v: np.ndarray, negate: bool = False) -> np.ndarray:
    """:meth:`brdflab.math.frame.NormalFrames.to_local`, compiled."""
    out = np.empty(v.shape, order="F")
    frame_to_local(frames.n, frames.sign, frames.a, v, bool(negate), out)
    return out


def shading_arrays(g, rh, d: np.ndarray, idx: np.ndarray, want_uv: bool, smooth: list[slice] | None,
                   tri_member: np.ndarray | None = None):
    """(p, n_g, n_s, uv or None, σ, a, ω_i, member or None) of the hits ``idx`` of a trace ``rh`` of rays ``d``,
    as ``g.surface(rh, idx, uv=want_uv, smooth=smooth)`` and :class:`~brdflab.math.frame.NormalFrames` give
    them; ``member`` = ``tri_member`` at the hits' triangles (:class:`~brdflab.integrator.tables.SceneTables`)."""
    m = len(idx)
    flags = np.zeros(m, np.bool_)
    if g.tri_nrm is not None:
        if smooth is None:
            flags[:] = True
        for sl in smooth or ():
            flags[sl] = True
    p, ng, ns, wi, sign, a = columns(m, [3, 3, 3, 3, None, None])
    uv = np.empty((m, 2), order="F") if want_uv else np.empty((0, 2), order="F")
    tri_nrm = g.tri_nrm if g.tri_nrm is not None else np.zeros((9, 0))
    tri_uv = g.tri_uv if g.tri_uv is not None else np.zeros((0, 0))
    want_member = tri_member is not None
    member = np.empty(m if want_member else 0, np.int64)
    shade(idx, rh.prim, rh.u, rh.v, flags, d, g.tri_pos, g.face_normal_cols, tri_nrm, tri_uv, want_uv,
          tri_member if want_member else member, want_member, p, ng, ns, uv, sign, a, wi, member)
    return p, ng, ns, uv if want_uv else None, sign, a, wi, member if want_member else None
