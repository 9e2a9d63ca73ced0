"""Kernels of the direct integrators' glue between the Embree calls (compiled engine).

The NumPy specification is in :mod:`brdflab.integrator.common` and :mod:`brdflab.integrator.direct_mats`;
each kernel does in one pass what the NumPy code does in a dozen array passes, with the same operations in
the same order, so the two engines agree to the bit:

* :func:`light_rays`: the light term's tail (:func:`~brdflab.integrator.common.light_term` and
  :func:`~brdflab.integrator.common.light_contributions`): scale = max(cos θ_o, 0) (· w_MIS) / p, the
  contribution c = L_e · f · scale per channel, and, for the points whose c has a positive channel, the
  shadow ray in Embree's float32 layout: the origin moved off the surface along ±n_g
  (:meth:`~brdflab.scene.geometry.Geometry.offset_origin`) and the length that stops short of the light
  (:meth:`~brdflab.scene.geometry.Geometry.shadow_tmax`). The other points' c is set to 0.
* :func:`bsdf_rays`: the BSDF rays of :func:`~brdflab.integrator.direct_mats.bsdf_rays`: for the points whose
  sample weight has a positive channel, the direction to world space (:meth:`NormalFrames.to_world
  <brdflab.math.frame.NormalFrames.to_world>`), renormalised, and the ray's origin off the surface, with the
  weight and pdf of those points.
* :func:`emission`: what those rays find when the scene's area lights are one
  :class:`~brdflab.emitter.area.AreaLightSet` (:func:`~brdflab.integrator.common.emission_along`): the light's
  radiance where the ray hit its front side and the density with which light sampling picks that direction,
  from the hit's triangle, barycentrics and distance (the shading normal as
  :meth:`~brdflab.scene.geometry.Geometry.surface` reconstructs it, then
  :meth:`~brdflab.emitter.area.AreaLightSet.eval_pdf_hit`).
* :func:`set_rows` and :func:`accumulate`: the integrators' scatters of per-point values into the camera
  samples' radiance, L[idx] = v and L[idx] += a·b·s (:func:`~brdflab.integrator.common.set_rows`,
  :func:`~brdflab.integrator.common.accumulate`), one pass over the rows instead of a gather, products and a
  scatter per channel.
"""

from __future__ import annotations

import math

import numpy as np

from brdflab.kernels.buffers import columns
from brdflab.kernels.jit import (
    BOOL,
    F8,
    FLAGS,
    IDX,
    IN1,
    IN1_F4,
    IN2,
    OUT1,
    OUT1_F4,
    OUT2,
    OUT2_F4,
    OUT_IDX,
    inline,
    kernel,
)
from brdflab.kernels.shading import tangent_args, vertex_normal

#: Embree's infinity, :data:`brdflab.scene.geometry.T_INF` (a literal here: the prebuilt kernels' key hashes
#: this folder's sources only; ``tests/test_kernels.py`` checks that the two are equal).
T_INF = 1e37


@inline
def _origin(p, ng, i, dx, dy, dz, eps, o32, r):
    """Row ``r`` of ``o32``: p_i moved by ε along ±n_g, to the side of ``d`` (``offset_origin``)."""
    side = eps if ng[i, 0] * dx + ng[i, 1] * dy + ng[i, 2] * dz >= 0 else -eps
    for j in range(3):
        o32[r, j] = np.float32(ng[i, j] * side + p[i, j])


@kernel(IN2, IN2, IN2, IN1, IN1, BOOL, IN2, IN2, IN2, IN1, F8, OUT2, OUT_IDX, OUT2_F4, OUT2_F4, OUT1_F4)
def light_rays(radiance, f, wo, pdf, w, mis, p, ng, wi, dist, eps, c, live, o32, d32, t32):
    """Fill ``c`` and, in their first ``live[-1]`` rows, the live points' indices and shadow rays (module
    docstring); ``live`` has one more entry than there are points: the count."""
    n = f.shape[0]
    count = 0
    for i in range(n):
        z = wo[i, 2]
        s = z if z >= 0.0 or z != z else 0.0  # np.maximum(z, 0): NaN propagates, −0 stays −0
        if mis:
            s *= w[i]
        q = pdf[i]
        s /= q if q > 0 else np.inf
        keep = False
        for j in range(3):
            v = radiance[i, j] * f[i, j]
            v *= s
            c[i, j] = v
            keep = keep or v > 0
        if not keep:
            c[i, 0] = c[i, 1] = c[i, 2] = 0.0
            continue
        live[count] = i
        dx, dy, dz = wi[i, 0], wi[i, 1], wi[i, 2]
        _origin(p, ng, i, dx, dy, dz, eps, o32, count)
        d32[count, 0], d32[count, 1], d32[count, 2] = np.float32(dx), np.float32(dy), np.float32(dz)
        t = dist[i] * (1.0 - 1e-3)
        t -= eps
        if t > T_INF:
            t = T_INF
        t32[count] = np.float32(t)
        count += 1
    live[n] = count


@kernel(IN2, IN2, IN1, IN2, IN1, IN1, FLAGS, IN2, IN2, BOOL, IN2, IN2, F8, OUT_IDX, OUT2, OUT1, OUT2, OUT2_F4)
def bsdf_rays(wo, weight, pdf, n, sign, a, tmask, ts, tt, has_tangent, p, ng, eps, live, d, pdf_live, weight_live,
              o32):
    """Fill, in their first ``live[-1]`` rows, the indices of the points with a positive weight channel, their
    unit world directions, pdfs, weights and ray origins (module docstring); ``live`` has one more entry than
    there are points: the count. With ``has_tangent``, the rows where ``tmask`` is set use the frame (s, t, n)."""
    m = wo.shape[0]
    count = 0
    for i in range(m):
        if not (weight[i, 0] > 0 or weight[i, 1] > 0 or weight[i, 2] > 0):
            continue
        nx, ny, nz = n[i, 0], n[i, 1], n[i, 2]
        vx, vy, vz = wo[i, 0], wo[i, 1], wo[i, 2]
        r = sign[i] * nx
        r *= vx
        r += ny * vy
        k = a[i] * r
        k += vz
        x = nx * k + vx
        y = sign[i] * vy + ny * k
        z = nz * vz - r
        if has_tangent and tmask[i]:  # to_world(v, s, t, n)
            x = vx * ts[i, 0] + vy * tt[i, 0] + vz * nx
            y = vx * ts[i, 1] + vy * tt[i, 1] + vz * ny
            z = vx * ts[i, 2] + vy * tt[i, 2] + vz * nz
        ln = math.sqrt(x * x + y * y + z * z)
        x, y, z = x / ln, y / ln, z / ln
        d[count, 0], d[count, 1], d[count, 2] = x, y, z
        _origin(p, ng, i, x, y, z, eps, o32, count)
        for j in range(3):
            weight_live[count, j] = weight[i, j]
        pdf_live[count] = pdf[i]
        live[count] = i
        count += 1
    live[m] = count


@kernel(IDX, IN1_F4, IN1_F4, IN1_F4, IN2, IDX, IN2, IN2, BOOL, IN2, IN1, OUT2, OUT1)
def emission(prim, bu32, bv32, t32, d, tri_emitter, face_n, tri_nrm, smooth, rad, pdf_scale, le, pdf):
    """Fill L_e and the light-sampling pdf of each ray (0 where it found no light or its back side)."""
    for i in range(prim.shape[0]):
        k = prim[i]
        e = tri_emitter[k]  # a miss (−1) reads the table's last entry, −1
        if e < 0:
            le[i, 0] = le[i, 1] = le[i, 2] = 0.0
            pdf[i] = 0.0
            continue
        nx, ny, nz = face_n[0, k], face_n[1, k], face_n[2, k]
        if smooth:
            mx, my, mz, ok = vertex_normal(tri_nrm, k, np.float64(bu32[i]), np.float64(bv32[i]))
            if ok:
                nx, ny, nz = mx, my, mz
        cos_l = -(nx * d[i, 0] + ny * d[i, 1] + nz * d[i, 2])
        front = cos_l > 0
        for j in range(3):
            le[i, j] = rad[j, e] * (1.0 if front else 0.0)
        dist = np.float64(t32[i])
        p = dist * dist * pdf_scale[e] / cos_l
        pdf[i] = p if front and p < np.inf else 0.0


def light_set_emission(g, rh, d: np.ndarray, tri_emitter: np.ndarray, lights) -> tuple[np.ndarray, np.ndarray]:
    """(L_e (N, 3), pdf (N,)) found by the rays ``d`` of the trace ``rh`` in a scene whose area lights form the
    :class:`~brdflab.emitter.area.AreaLightSet` ``lights`` (``emission_along`` before the environment), compiled."""
    n = len(d)
    le, pdf = columns(n, [3, None])
    smooth = g.tri_nrm is not None
    emission(rh.prim, rh.u, rh.v, rh.t, _f8(d), tri_emitter, g.face_normal_cols, g.tri_nrm if smooth else _NO_NRM,
             smooth, lights._emitter_radiance, lights._emitter_pdf_scale, le, pdf)
    return le, pdf


def light_tail(g, p: np.ndarray, ng: np.ndarray, radiance: np.ndarray, f: np.ndarray, wo: np.ndarray,
               pdf: np.ndarray, w: np.ndarray | None, wi: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """(M, 3) contributions of the light samples (``light_contributions``, visibility included), compiled;
    ``g`` is the scene's geometry, ``w`` the MIS weights or None."""
    m = len(f)
    (c,) = columns(m, [3])
    live = np.empty(m + 1, np.int64)
    o32, d32, t32 = np.empty((m, 3), np.float32), np.empty((m, 3), np.float32), np.empty(m, np.float32)
    light_rays(_f8(radiance), _f8(f), _f8(wo), _f8(pdf), _NO_W if w is None else _f8(w), w is not None, p, ng,
               _f8(wi), _f8(dist), g.eps, c, live, o32, d32, t32)
    k = int(live[m])
    if k and len(g.faces):
        blocked = live[:k][g.occluded_f32(o32[:k], d32[:k], t32[:k])]
        for j in range(3):  # a column at a time: 3× faster than one scatter of rows
            c[:, j][blocked] = 0.0
    return c


def bsdf_ray_batch(g, sp, wo: np.ndarray, weight: np.ndarray, pdf: np.ndarray):
    """(live, d, o32, weight, pdf) of ``direct_mats.bsdf_rays`` before its trace, compiled."""
    m = len(wo)
    live = np.empty(m + 1, np.int64)
    d, w_live, pdf_live = columns(m, [3, 3, None])
    o32 = np.empty((m, 3), np.float32)
    fr = sp.frames
    bsdf_rays(_f8(wo), _f8(weight), _f8(pdf), fr.n, fr.sign, fr.a, *tangent_args(fr), fr.tangent is not None,
              sp.p, sp.ng, g.eps, live, d, pdf_live, w_live, o32)
    k = int(live[m])
    return live[:k], d[:k], o32[:k], w_live[:k], pdf_live[:k]


@kernel(OUT2, IDX, IN2)
def set_rows(L, idx, values):
    """L[idx[i]] = values[i] (:func:`brdflab.integrator.common.set_rows`)."""
    for i in range(idx.shape[0]):
        r = idx[i]
        for j in range(3):
            L[r, j] = values[i, j]


@kernel(OUT2, IDX, IN2, IN2, IN1, BOOL)
def accumulate(L, idx, a, b, scale, scaled):
    """L[idx[i]] += a[i]·b[i] (·scale[i] when ``scaled``) per channel, rounded as
    :func:`brdflab.integrator.common.accumulate` rounds (the product first, then the sum)."""
    for i in range(idx.shape[0]):
        r = idx[i]
        for j in range(3):
            c = a[i, j] * b[i, j]
            if scaled:
                c *= scale[i]
            L[r, j] = L[r, j] + c


def _f8(a: np.ndarray) -> np.ndarray:
    return np.asarray(a, np.float64)


_NO_W = np.zeros(0)
_NO_NRM = np.zeros((9, 0))
