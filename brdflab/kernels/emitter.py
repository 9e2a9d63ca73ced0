"""Kernel of area-light sampling (compiled engine): :meth:`AreaEmitter.sample <brdflab.emitter.area.AreaEmitter.sample>`
and :meth:`AreaLightSet.sample <brdflab.emitter.area.AreaLightSet.sample>` for constant radiance.

Per shading point: the light point (folding warp on the chosen triangle, or c + ξ1 e1 + ξ2 e2 on a
parallelogram), the unit direction and distance to it, the light's normal there (one plane normal, the
triangle's face normal, or interpolated and renormalised vertex normals), the solid-angle pdf
‖y − x‖² / (A |n_l·ω|) (times the selection probability) and the radiance, 0 for back faces (spec §9.1,
see :mod:`brdflab.emitter.area`). The discrete choice of the triangle: :func:`choose` for a short CDF (the
count of CDF entries ≤ ξ, :func:`~brdflab.emitter.area.invert_cdf`, in one pass instead of one per entry); the
alias table's stays in NumPy. Each value is formed with the operations of the NumPy code in its order: the
engines agree to the bit.
"""

from __future__ import annotations

import math

import numpy as np

from brdflab.emitter.base import EmitterSample
from brdflab.kernels.buffers import columns
from brdflab.kernels.jit import BOOL, F8, I8, IDX, IN1, IN2, OUT1, OUT2, OUT_IDX, kernel

TINY = np.finfo(np.float64).tiny
#: Normal sources: one plane normal, face normal per triangle, interpolated vertex normals.
PLANE, FACE, VERTEX = 0, 1, 2


@kernel(BOOL, IDX, IN2, I8, IN2, IN2, IN2, I8, IN2, BOOL, IN1, F8, IN2, OUT2, OUT1, OUT2, OUT1)
def light_points(quad, k, u, c0, ref_p, pos, normals, nmode, nrm, fused, pdf_scale, area, rad, wi, dist, radiance,
                 pdf):
    """Fill ω, distance, radiance and pdf of one light sample per point (module docstring). ``u`` holds
    ξ1, ξ2 in columns ``c0``, ``c0 + 1``; ``quad`` samples the parallelogram ``pos`` = rows (c, e1, e2)."""
    for i in range(ref_p.shape[0]):
        u0, u1 = u[i, c0], u[i, c0 + 1]
        t = 0
        if quad:
            yx = u0 * pos[1, 0] + u1 * pos[2, 0] + pos[0, 0]
            yy = u0 * pos[1, 1] + u1 * pos[2, 1] + pos[0, 1]
            yz = u0 * pos[1, 2] + u1 * pos[2, 2] + pos[0, 2]
            bu = bv = 0.0
        else:
            t = k[i]
            if u0 + u1 > 1.0:
                b0, bu = 1.0 - u0, 1.0 - u1
            else:
                b0, bu = u0, u1
            bv = 1.0 - b0 - bu
            yx = pos[0, t] + pos[3, t] * bu + pos[6, t] * bv
            yy = pos[1, t] + pos[4, t] * bu + pos[7, t] * bv
            yz = pos[2, t] + pos[5, t] * bu + pos[8, t] * bv
        dx, dy, dz = yx - ref_p[i, 0], yy - ref_p[i, 1], yz - ref_p[i, 2]
        d2 = dx * dx + dy * dy + dz * dz
        dd = math.sqrt(d2)
        inv = 1.0 / max(dd, TINY)
        wx, wy, wz = dx * inv, dy * inv, dz * inv
        wi[i, 0], wi[i, 1], wi[i, 2] = wx, wy, wz
        dist[i] = dd
        if nmode == PLANE:
            cos_l = wx * -normals[0, 0] + wy * -normals[0, 1] + wz * -normals[0, 2]
        elif nmode == FACE:
            cos_l = -(normals[t, 0] * wx + normals[t, 1] * wy + normals[t, 2] * wz)
        else:
            nx = nrm[0, t] + nrm[3, t] * bu + nrm[6, t] * bv
            ny = nrm[1, t] + nrm[4, t] * bu + nrm[7, t] * bv
            nz = nrm[2, t] + nrm[5, t] * bu + nrm[8, t] * bv
            ln = math.sqrt(nx * nx + ny * ny + nz * nz)
            if not ln > 0:
                ln = 1.0
            cos_l = -(nx / ln * wx + ny / ln * wy + nz / ln * wz)
        if fused:
            p = d2 * pdf_scale[t] / cos_l
        else:
            p = d2 / (area * cos_l)
        ok = p > 0 and p < np.inf
        pdf[i] = p if ok else 0.0
        for j in range(3):
            radiance[i, j] = (rad[j, t] if fused else rad[j, 0]) * (1.0 if ok else 0.0)


def _run(quad: bool, k, u, c0, ref_p, pos, normal, nrm, fused, pdf_scale, area, rad) -> EmitterSample:
    n = len(ref_p)
    wi, radiance, dist, pdf = columns(n, [3, 3, None, None])
    normals = np.atleast_2d(normal)
    nmode = VERTEX if nrm is not None else (PLANE if np.ndim(normal) == 1 else FACE)
    light_points(quad, np.zeros(0, np.int64) if k is None else np.asarray(k, np.int64), np.asarray(u, np.float64), c0,
                 np.asarray(ref_p, np.float64), pos, normals, nmode,
                 np.zeros((9, 0)) if nrm is None else nrm, fused, pdf_scale, area, rad, wi, dist, radiance, pdf)
    return EmitterSample(wi, dist, radiance, pdf)


def sample_emitter(em, ref_p: np.ndarray, u: np.ndarray):
    """:meth:`AreaEmitter.sample`, compiled; NotImplemented (the NumPy path) for textured radiance."""
    if not em.radiance.constant:
        return NotImplemented
    value = (em.radiance.value * em.scale).reshape(3, 1)
    if em._quad is not None:
        return _run(True, None, u, 0, ref_p, np.array(em._quad), em._normal, None, False, _NO_SCALE, em.area,
                    value)
    k = em._choose_triangles(u[:, 2])
    return _run(False, k, u, 0, ref_p, em._pos, em._normal, em._nrm, False, _NO_SCALE, em.area, value)


@kernel(IN1, IN1, OUT_IDX)
def count_below(cdf, u, k):
    """k[i] = the number of entries cdf[0 … n−2] ≤ u[i] (:func:`brdflab.emitter.area.invert_cdf`)."""
    for i in range(u.shape[0]):
        c = 0
        for j in range(cdf.shape[0] - 1):
            if u[i] >= cdf[j]:
                c += 1
        k[i] = c


def choose(chooser, u: np.ndarray):
    """:meth:`DiscreteChooser.sample <brdflab.emitter.area.DiscreteChooser.sample>`, compiled for a short CDF
    (``NotImplemented`` for an alias table)."""
    if chooser.alias is not None:
        return NotImplemented
    k = np.empty(len(u), np.int64)
    count_below(chooser.cdf, np.asarray(u, np.float64), k)
    return k


def sample_light_set(lights, ref_p: np.ndarray, u: np.ndarray) -> EmitterSample:
    """:meth:`AreaLightSet.sample`, compiled."""
    k = lights.chooser.sample(u[:, 0])
    return _run(False, k, u, 1, ref_p, lights._pos, lights._face_n, lights._nrm, True, lights._pdf_scale, 1.0,
                lights._radiance)


_NO_SCALE = np.zeros(0)
