"""Kernels of the shading points (compiled engine): hit records, shading frames and local ω_i in one pass;
directions into the shading frames (:func:`to_local`).

The NumPy specification is :meth:`brdflab.scene.geometry.Geometry.surface` (positions p = p0 + u e1 + v e2,
face normals, interpolated and renormalised vertex normals where the mesh has them, uvs; spec §7.2)
followed by :func:`brdflab.integrator.common.make_shading_points` (the frame of the shading normal kept as
(σ, a), Duff et al. 2017, and ω_i = −d in it), with, at the points of anisotropic materials on meshes with
uvs, the uv tangent's frame (:meth:`~brdflab.math.frame.NormalFrames.with_uv_tangents`: s = normalize(dp/du −
n (n·dp/du)), t = n × s; ω_i's x and y are then dot products with s and t). Each point's values are formed
with the same operations in the same order, so the two engines agree to the bit.
"""

from __future__ import annotations

import math

import numpy as np

from brdflab.kernels.buffers import columns
from brdflab.kernels.jit import BOOL, FLAGS, IDX, IN1, IN1_F4, IN2, OUT1, OUT2, OUT_FLAGS, OUT_IDX, inline, kernel

#: :data:`brdflab.math.frame.TANGENT_TOL` (a literal here: the prebuilt kernels' key hashes this folder's sources
#: only; ``tests/test_tangent_frames.py`` checks that the two are equal).
TANGENT_TOL = 1e-6


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


@inline
def uv_tangent(nx, ny, nz, dx, dy, dz):
    """(ok, s, t) of :func:`brdflab.math.frame.uv_tangents` for one normal and dp/du, in its order."""
    c = nx * dx + ny * dy + nz * dz
    sx, sy, sz = dx - nx * c, dy - ny * c, dz - nz * c
    ln = math.sqrt(sx * sx + sy * sy + sz * sz)
    if not ln > TANGENT_TOL * math.sqrt(dx * dx + dy * dy + dz * dz):
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    sx, sy, sz = sx / ln, sy / ln, sz / ln
    return True, sx, sy, sz, ny * sz - nz * sy, nz * sx - nx * sz, nx * sy - ny * sx


@kernel(IDX, IDX, IN1_F4, IN1_F4, FLAGS, IN2, IN2, IN2, IN2, IN2, BOOL, IDX, BOOL, FLAGS, IN2, BOOL, OUT2, OUT2, OUT2,
        OUT2, OUT1, OUT1, OUT2, OUT_IDX, OUT_FLAGS, OUT2, OUT2)
def shade(idx, prim, bu32, bv32, smooth, d, tri_pos, face_n, tri_nrm, tri_uv, want_uv, tri_member, want_member,
          tri_tangent, dpdu, want_tangent, p, ng, ns, uv, sign, a, wi, member, tmask, ts, tt):
    """Fill p, n_g, n_s, uv, σ, a, ω_i, (with ``want_member``) the material within its family and (with
    ``want_tangent``) the uv tangent's frame (mask, s, t) of the camera hits ``idx`` (see the module
    docstring)."""
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
        if want_tangent:
            ok, sx, sy, sz, tx, ty, tz = False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
            if tri_tangent[k]:
                ok, sx, sy, sz, tx, ty, tz = uv_tangent(nx, ny, nz, dpdu[0, k], dpdu[1, k], dpdu[2, k])
            tmask[i] = ok
            ts[i, 0], ts[i, 1], ts[i, 2] = sx, sy, sz
            tt[i, 0], tt[i, 1], tt[i, 2] = tx, ty, tz
            if ok:
                x = d[r, 0] * sx + d[r, 1] * sy + d[r, 2] * sz
                y = d[r, 0] * tx + d[r, 1] * ty + d[r, 2] * tz
        wi[i, 0], wi[i, 1], wi[i, 2] = -x, -y, -z


@kernel(IN2, IN1, IN1, IN2, BOOL, FLAGS, IN2, IN2, BOOL, OUT2)
def frame_to_local(n, sign, a, v, negate, tmask, ts, tt, has_tangent, out):
    """(v·s, v·t, v·n) per row in the frames (n, σ, a), with ``has_tangent`` the explicit (s, t) where
    ``tmask``, negated with ``negate``: the operations of :meth:`brdflab.math.frame.NormalFrames.to_local` in
    its order."""
    for i in range(v.shape[0]):
        x, y, z = in_frame(n[i, 0], n[i, 1], n[i, 2], sign[i], a[i], v[i, 0], v[i, 1], v[i, 2])
        if has_tangent and tmask[i]:
            x = v[i, 0] * ts[i, 0] + v[i, 1] * ts[i, 1] + v[i, 2] * ts[i, 2]
            y = v[i, 0] * tt[i, 0] + v[i, 1] * tt[i, 1] + v[i, 2] * tt[i, 2]
        if negate:
            x, y, z = -x, -y, -z
        out[i, 0], out[i, 1], out[i, 2] = x, y, z


def to_local(frames, v: np.ndarray, negate: bool = False) -> np.ndarray:
    """:meth:`brdflab.math.frame.NormalFrames.to_local`, compiled."""
    out = np.empty(v.shape, order="F")
    tmask, ts, tt = tangent_args(frames)
    frame_to_local(frames.n, frames.sign, frames.a, v, bool(negate), tmask, ts, tt, frames.tangent is not None, out)
    return out


def tangent_args(frames) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(mask, s, t) of the frames' uv tangents, or empty arrays when they have none."""
    return frames.tangent if frames.tangent is not None else _NO_TANGENT


_NO_TANGENT = (np.zeros(0, np.bool_), np.zeros((0, 3)), np.zeros((0, 3)))


def shading_arrays(g, rh, d: np.ndarray, idx: np.ndarray, want_uv: bool, smooth: list[slice] | None,
                   tri_member: np.ndarray | None = None, tables=None):
    """(p, n_g, n_s, uv or None, σ, a, ω_i, member or None, tangent or None) of the hits ``idx`` of a trace ``rh``
    of rays ``d``, as ``g.surface(rh, idx, uv=want_uv, smooth=smooth)`` and :class:`~brdflab.math.frame.NormalFrames`
    give them; ``member`` = ``tri_member`` at the hits' triangles, ``tangent`` the frames' uv tangents where
    ``tables`` (:class:`~brdflab.integrator.tables.SceneTables`) has a ``tri_tangent``."""
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
    want_tangent = tables is not None and tables.tri_tangent is not None
    if want_tangent:
        tan = (np.empty(m, np.bool_), *columns(m, [3, 3]))
        tri_tangent, dpdu = tables.tri_tangent, tables.dpdu
    else:
        tan, tri_tangent, dpdu = _NO_TANGENT, _NO_TANGENT[0], _NO_TANGENT[1]
    shade(idx, rh.prim, rh.u, rh.v, flags, d, g.tri_pos, g.face_normal_cols, tri_nrm, tri_uv, want_uv,
          tri_member if want_member else member, want_member, tri_tangent, dpdu, want_tangent,
          p, ng, ns, uv, sign, a, wi, member, *tan)
    return (p, ng, ns, uv if want_uv else None, sign, a, wi, member if want_member else None,
            tan if want_tangent else None)
