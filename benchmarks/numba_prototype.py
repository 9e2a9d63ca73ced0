"""Prototype, NOT used by brdflab: Numba kernels for the NumPy hot spots of a render unit, timed against
brdflab's NumPy code on the same inputs (issue 17: "propose a compiled kernel with the profile before
adopting it").

Usage (Numba is not a brdflab dependency; install it into a separate venv with brdflab)::

    python -m venv /tmp/nb && /tmp/nb/bin/pip install -e . numba
    /tmp/nb/bin/python benchmarks/numba_prototype.py [SCENE.xml] [--rounds 200]

One 16 k-sample unit (the bench unit size) is rendered with brdflab's functions; its
intermediate arrays are the inputs of four kernels, each checked against the NumPy result
(``allclose``, rtol 1e-12: the kernels sum in another order) and timed alternately with it by thread CPU
time (robust on a shared machine), median of ``--rounds``:

* ``splat``: :meth:`brdflab.film.Film.splat` (separable phase tables) → one loop over samples adding
  taps² weights straight into the tile film.
* ``shading``: :meth:`Geometry.surface` + :func:`make_shading_points` (positions, face normals, interpolated
  vertex normals on smooth meshes, frames, local ω_i) → one loop over hits.
* ``light+shadow``: the area-light sample (:class:`AreaLightSet`, or one :class:`AreaEmitter`: triangles
  or its parallelogram; the discrete choice of the triangle stays in NumPy), ω in the local frame, cos θ
  and the float32 shadow rays (origin offset, direction, t_max) → one loop.
* ``bsdf``: ``eval`` of the scene's first rough conductor (D, G1, Schlick) or rough substrate (with the
  dielectric Fresnel and the Ashikhmin–Shirley diffuse term) at every shading point → one loop; the
  projection counts it with the share of camera hits on that material.

Finally the whole unit's CPU time is measured and the speed-up of the unit projected by Amdahl's law
(the unit with these four stages replaced; Embree and the rest unchanged).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

try:
    import numba as nb
except ImportError:  # pragma: no cover - the prototype needs numba
    sys.exit("numba_prototype.py needs numba (pip install numba in a separate venv; see the docstring)")

from brdflab.alloc import tune_allocator  # noqa: E402
from brdflab.film import Film  # noqa: E402
from brdflab.integrator.common import (  # noqa: E402
    area_light_set,
    light_dims,
    make_shading_points,
    point_uniforms,
    scene_tables,
    sort_by_code,
)
from brdflab.math.frame import take_rows  # noqa: E402
from brdflab.render import _pixel_offsets  # noqa: E402
from brdflab.scene.loader import load_scene  # noqa: E402

JIT = dict(nopython=True, fastmath=False, cache=False, nogil=True)


@nb.jit(**JIT)
def splat_kernel(sx, sy, L, data, wt, offset, nph, bits, taps, bx, by, bw, bh):
    """Separable phase-table splat, one sample at a time (same taps and weights as Film._taps), into an
    accumulator with the four channels of a pixel adjacent (one cache line per tap), then the film."""
    acc = np.zeros((bh, bw, 4))
    for i in range(len(sx)):
        tx = np.int64(np.floor(sx[i] * nph - 0.5 * nph))
        ty = np.int64(np.floor(sy[i] * nph - 0.5 * nph))
        phx, phy = tx & (nph - 1), ty & (nph - 1)
        fx = min(max((tx >> bits) + offset[phx] + bx, 0), bw - taps)
        fy = min(max((ty >> bits) + offset[phy] + by, 0), bh - taps)
        r, g, b = L[i, 0], L[i, 1], L[i, 2]
        for ky in range(taps):
            wy = wt[phy, ky]
            for kx in range(taps):
                w = wy * wt[phx, kx]
                cell = acc[fy + ky, fx + kx]
                cell[0] += w * r
                cell[1] += w * g
                cell[2] += w * b
                cell[3] += w
    for y in range(bh):
        for x in range(bw):
            for c in range(4):
                data[c, y, x] += acc[y, x, c]


@nb.jit(**JIT)
def shading_kernel(prim, bu, bv, smooth, tri_pos, fn, tri_nrm, d, p, ng, ns, sign, a, wi):
    """Hit records (position, face normal, interpolated vertex normal where ``smooth``) + Duff frame (σ, a)
    of the shading normal + ω_i = −d in the local frame."""
    for i in range(len(prim)):
        k, u, v = prim[i], bu[i], bv[i]
        for j in range(3):
            p[i, j] = tri_pos[j, k] + u * tri_pos[3 + j, k] + v * tri_pos[6 + j, k]
            ng[i, j] = fn[j, k]
            ns[i, j] = fn[j, k]
        if smooth[i]:
            mx = tri_nrm[0, k] + u * tri_nrm[3, k] + v * tri_nrm[6, k]
            my = tri_nrm[1, k] + u * tri_nrm[4, k] + v * tri_nrm[7, k]
            mz = tri_nrm[2, k] + u * tri_nrm[5, k] + v * tri_nrm[8, k]
            ln = np.sqrt(mx * mx + my * my + mz * mz)
            if ln > 0:
                inv = 1.0 / ln
                ns[i, 0], ns[i, 1], ns[i, 2] = mx * inv, my * inv, mz * inv
        nx, ny, nz = ns[i, 0], ns[i, 1], ns[i, 2]
        s = 1.0 if nz >= 0 else -1.0
        aa = -1.0 / (s + nz)
        sign[i], a[i] = s, aa
        vx, vy, vz = -d[i, 0], -d[i, 1], -d[i, 2]
        w = nx * vx + ny * vy
        q = aa * w - vz
        wi[i, 0] = vx + s * nx * q
        wi[i, 1] = s * vy + ny * q
        wi[i, 2] = w + nz * vz


@nb.jit(**JIT)
def light_shadow_kernel(k, u1, u2, pos, face_n, nrm, rad, pdf_scale, p, ng, ns, sign, a, eps, quad,
                        wo, cos_o, radiance, pdf, o32, d32, tmax):
    """Triangle point (folding warp), direction and distance, light normal (interpolated vertex normals
    when ``nrm`` has 9 columns), pdf, radiance; ω in the local frame; shadow ray (origin offset along ±n_g,
    float32) stopping before the light point. Tables are one row per triangle: a random triangle's 9 values
    share a cache line or two (brdflab's column-per-triangle layout suits NumPy's gathers, not this)."""
    for i in range(len(k)):
        t = k[i]
        x0, x1 = u1[i], u2[i]
        if quad:  # y = c + ξ1 e1 + ξ2 e2
            bu, bv = x0, x1
        elif x0 + x1 > 1.0:
            b0, bu = 1.0 - x0, 1.0 - x1
            bv = 1.0 - b0 - bu
        else:
            b0, bu = x0, x1
            bv = 1.0 - b0 - bu
        dx = pos[t, 0] + bu * pos[t, 3] + bv * pos[t, 6] - p[i, 0]
        dy = pos[t, 1] + bu * pos[t, 4] + bv * pos[t, 7] - p[i, 1]
        dz = pos[t, 2] + bu * pos[t, 5] + bv * pos[t, 8] - p[i, 2]
        d2 = dx * dx + dy * dy + dz * dz
        dist = np.sqrt(d2)
        inv = 1.0 / max(dist, 2.2250738585072014e-308)
        wx, wy, wz = dx * inv, dy * inv, dz * inv
        if nrm.shape[1] == 9:
            lx = nrm[t, 0] + bu * nrm[t, 3] + bv * nrm[t, 6]
            ly = nrm[t, 1] + bu * nrm[t, 4] + bv * nrm[t, 7]
            lz = nrm[t, 2] + bu * nrm[t, 5] + bv * nrm[t, 8]
            ln = np.sqrt(lx * lx + ly * ly + lz * lz)
            if not ln > 0:
                ln = 1.0
            cos_l = -(lx / ln * wx + ly / ln * wy + lz / ln * wz)
        else:
            cos_l = -(face_n[t, 0] * wx + face_n[t, 1] * wy + face_n[t, 2] * wz)
        pd = d2 * pdf_scale[t] / cos_l if cos_l != 0 else np.inf
        ok = pd > 0 and pd < np.inf
        pdf[i] = pd if ok else 0.0
        for j in range(3):
            radiance[i, j] = rad[t, j] if ok else 0.0
        nx, ny, nz = ns[i, 0], ns[i, 1], ns[i, 2]
        s, aa = sign[i], a[i]
        w = nx * wx + ny * wy
        q = aa * w - wz
        wo[i, 0] = wx + s * nx * q
        wo[i, 1] = s * wy + ny * q
        wo[i, 2] = w + nz * wz
        cos_o[i] = max(wo[i, 2], 0.0)
        nx, ny, nz = ng[i, 0], ng[i, 1], ng[i, 2]
        side = eps if nx * wx + ny * wy + nz * wz >= 0 else -eps
        o32[i, 0] = p[i, 0] + nx * side
        o32[i, 1] = p[i, 1] + ny * side
        o32[i, 2] = p[i, 2] + nz * side
        d32[i, 0], d32[i, 1], d32[i, 2] = wx, wy, wz
        tmax[i] = min(dist * (1.0 - 1e-3) - eps, 1e37)


@nb.jit(**JIT)
def beckmann_dg(ix, iy, iz, ox, oy, oz, hx, hy, hz, alpha, a2):
    """Beckmann D(ω_h) and the rational Smith G1(ω_i) G1(ω_o) for a unit half vector with h_z > 0."""
    c2 = hz * hz
    d = np.exp(-max(1.0 - c2, 0.0) / c2 / a2) / (np.pi * a2 * c2 * c2)
    g = 1.0
    for cz, vh in ((iz, hx * ix + hy * iy + hz * iz), (oz, hx * ox + hy * oy + hz * oz)):
        if vh / cz <= 0:
            return d, 0.0
        tan_v = np.sqrt(max(1.0 - cz * cz, 0.0)) / abs(cz)
        b = 1.0 / (alpha * tan_v) if tan_v > 0 else np.inf
        if b < 1.6:
            g *= (3.535 * b + 2.181 * b * b) / (1.0 + 2.276 * b + 2.577 * b * b)
    return d, g


@nb.jit(**JIT)
def conductor_kernel(wi, wo, alpha, r0, f):
    """Beckmann D · Schlick F · rational Smith G1² / (4 cos θ_i cos θ_o)."""
    a2 = alpha * alpha
    for i in range(len(wi)):
        ix, iy, iz = wi[i, 0], wi[i, 1], wi[i, 2]
        ox, oy, oz = wo[i, 0], wo[i, 1], wo[i, 2]
        f[i, 0] = f[i, 1] = f[i, 2] = 0.0
        hx, hy, hz = ix + ox, iy + oy, iz + oz
        hn = np.sqrt(hx * hx + hy * hy + hz * hz)
        if iz <= 0 or oz <= 0 or hn <= 1e-12:
            continue
        hx, hy, hz = hx / hn, hy / hn, hz / hn
        if hz <= 0:
            continue
        hi = hx * ix + hy * iy + hz * iz
        d, g = beckmann_dg(ix, iy, iz, ox, oy, oz, hx, hy, hz, alpha, a2)
        s = d * g / (4.0 * iz * oz)
        if not np.isfinite(s):
            continue
        m = 1.0 - min(max(hi, 0.0), 1.0)
        m5 = m * m
        m5 *= m5
        m5 *= m
        for j in range(3):
            f[i, j] = (r0[j] + m5 * (1.0 - r0[j])) * s


@nb.jit(**JIT)
def substrate_kernel(wi, wo, alpha, kd, scale, eta_e, eta_i, f):
    """Ashikhmin–Shirley diffuse under a Beckmann dielectric coat (the ``lobe="both"`` eval)."""
    a2 = alpha * alpha
    for i in range(len(wi)):
        ix, iy, iz = wi[i, 0], wi[i, 1], wi[i, 2]
        ox, oy, oz = wo[i, 0], wo[i, 1], wo[i, 2]
        f[i, 0] = f[i, 1] = f[i, 2] = 0.0
        if iz <= 0 or oz <= 0:
            continue
        mi, mo = 1.0 - 0.5 * iz, 1.0 - 0.5 * oz
        sd = scale * (1.0 - mi * mi * mi * mi * mi) * (1.0 - mo * mo * mo * mo * mo)
        hx, hy, hz = ix + ox, iy + oy, iz + oz
        hn = np.sqrt(hx * hx + hy * hy + hz * hz)
        spec = 0.0
        if hn > 1e-12:
            hx, hy, hz = hx / hn, hy / hn, hz / hn
            hi = hx * ix + hy * iy + hz * iz
            if hz > 0:
                d, g = beckmann_dg(ix, iy, iz, ox, oy, oz, hx, hy, hz, alpha, a2)
                ci = min(max(hi, 0.0), 1.0)
                s2 = (eta_e / eta_i) ** 2 * max(0.0, 1.0 - ci * ci)
                if s2 >= 1.0:
                    fr = 1.0
                else:
                    ct = np.sqrt(max(0.0, 1.0 - s2))
                    rs = (eta_e * ci - eta_i * ct) / (eta_e * ci + eta_i * ct)
                    rp = (eta_i * ci - eta_e * ct) / (eta_i * ci + eta_e * ct)
                    fr = 0.5 * (rs * rs + rp * rp)
                    fr = min(max(fr, 0.0), 1.0) if np.isfinite(fr) else 1.0
                spec = d * fr * g / (4.0 * iz * oz)
                if not np.isfinite(spec):
                    spec = 0.0
        for j in range(3):
            f[i, j] = kd[j] * sd + spec


def cpu_ab(fa, fb, rounds: int) -> tuple[float, float]:
    """Median thread CPU milliseconds of ``fa`` and ``fb``, run alternately."""
    ta, tb = [], []
    for r in range(rounds):
        for f, acc in ((fa, ta), (fb, tb)) if r % 2 == 0 else ((fb, tb), (fa, ta)):
            t0 = time.thread_time()
            f()
            acc.append(time.thread_time() - t0)
    return 1e3 * statistics.median(ta), 1e3 * statistics.median(tb)


def main(argv: list[str] | None = None) -> int:
    """Time the four kernels against NumPy on one unit of the scene."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    default = ROOT.parent / "shared/scenes/assignment-3/cbox/cbox_conductors_ems.xml"
    ap.add_argument("scene", nargs="?", type=Path,
                    default=default if default.exists() else ROOT / "scenes/cbox/cbox_spheres.xml")
    ap.add_argument("--rounds", type=int, default=200)
    a = ap.parse_args(argv)
    tune_allocator()
    scene = load_scene(a.scene)
    g, cam = scene.geometry, scene.camera
    # One bench unit: a 16 × 16-pixel tile at 64 spp in the middle of the image.
    w = h = 16
    spp = 64
    x0, y0 = (cam.width // 2) // 16 * 16, (cam.height // 2) // 16 * 16
    rng = np.random.Generator(np.random.SFC64(1))
    px, py = _pixel_offsets(w, h, spp)
    n = w * h * spp
    sx, sy = rng.random(n) + px + x0, rng.random(n) + py + y0
    o, d, tmax = cam.generate_rays(sx, sy)
    rh = g.trace(o, d, tmax)
    tab = scene_tables(scene)
    code = np.take(tab.tri_code, rh.prim)
    idx, runs = sort_by_code(code, tab.codes)
    groups: list[tuple[int, slice]] = []
    for c, sl in runs:  # as trace_camera: one slice per family, flat meshes before smooth ones
        if groups and groups[-1][0] == c >> 1:
            groups[-1] = (c >> 1, slice(groups[-1][1].start, sl.stop))
        else:
            groups.append((c >> 1, sl))
    smooth_sl = [sl for c, sl in runs if c & 1]
    rows_out: list[tuple[str, float, float]] = []
    agree: list[str] = []

    # -- shading points -------------------------------------------------------------------------
    def np_shading():
        hh = g.surface(rh, idx, uv=tab.bsdf_uv, smooth=None if len(smooth_sl) == len(runs) else smooth_sl)
        return make_shading_points(scene, hh, take_rows(d, idx), idx, groups)

    m = len(idx)
    prim = np.take(rh.prim, idx)
    bu, bv = np.take(rh.u, idx).astype(np.float64), np.take(rh.v, idx).astype(np.float64)
    smooth = np.zeros(m, np.bool_)
    for sl in smooth_sl:
        smooth[sl] = True
    tri_nrm = g.tri_nrm if g.tri_nrm is not None else np.zeros((9, 1))
    d_idx = np.ascontiguousarray(take_rows(d, idx))
    out = [np.empty((m, 3)), np.empty((m, 3)), np.empty((m, 3)), np.empty(m), np.empty(m), np.empty((m, 3))]

    def nb_shading():
        shading_kernel(prim, bu, bv, smooth, g.tri_pos, g.face_normal_cols, tri_nrm, d_idx, *out)

    sp = np_shading()
    nb_shading()
    ok = all(np.allclose(x, y, rtol=1e-12, atol=1e-14) for x, y in
             ((out[0], sp.p), (out[1], sp.ng), (out[2], sp.ns), (out[3], sp.frames.sign), (out[4], sp.frames.a),
              (out[5], sp.wi)))
    agree.append(f"shading {'agrees' if ok else 'DIFFERS'} ({int(smooth.sum())} of {m} points on smooth meshes)")
    rows_out.append(("shading", *cpu_ab(np_shading, nb_shading, a.rounds)))

    # -- light sample + shadow-ray setup --------------------------------------------------------
    fused = area_light_set(scene)
    em = fused if fused is not None else scene.emitters[0]
    u = point_uniforms(rng, n, sp, light_dims(scene))
    quad = None
    light_ok = True
    nrm = np.zeros((1, 1))
    if fused is not None:
        kk, u12 = fused.chooser.sample(u[:, 0]), u[:, 1:3]
        pos, face_n, rad, pdf_scale = fused._pos, fused._face_n, fused._radiance, fused._pdf_scale
        nrm = fused._nrm if fused._nrm is not None else np.zeros((1, 1))
    elif type(em).__name__ == "AreaEmitter" and em.radiance.constant and em._nrm is None:
        value = em.radiance.value * em.scale
        kk, u12, pos = em.chooser.sample(u[:, 2]), u[:, 0:2], em._pos
        face_n = np.broadcast_to(em._normal, (pos.shape[1], 3)) if em._normal.ndim == 1 else em._face_n
        rad = np.repeat(value[:, None], pos.shape[1], axis=1)
        pdf_scale = np.full(pos.shape[1], 1.0 / em.area)
        if em._quad is not None:  # the parallelogram warp: one "triangle" c, e1, e2 with y = c + ξ1 e1 + ξ2 e2
            c, e1, e2 = em._quad
            quad = True
            kk = np.zeros(n, np.int64)
            pos = np.concatenate([c, e1, e2])[:, None]
            face_n, rad, pdf_scale = em._normal[None, :], value[:, None], np.array([1.0 / em.area])
    else:
        light_ok = False
    if light_ok:
        def np_light():
            ls = em.sample(sp.p, u)
            wo = sp.local(ls.wi)
            cos_o = np.maximum(wo[:, 2], 0.0)
            o32 = g.offset_origin(sp.p, sp.ng, ls.wi, f32=True)
            d32 = np.empty((m, 3), np.float32)
            for j in range(3):
                d32[:, j] = ls.wi[:, j]
            return ls, wo, cos_o, o32, d32, g.shadow_tmax(ls.dist)

        lo = [np.empty((m, 3)), np.empty(m), np.empty((m, 3)), np.empty(m), np.empty((m, 3), np.float32),
              np.empty((m, 3), np.float32), np.empty(m)]
        p_c, ng_c, ns_c = np.ascontiguousarray(sp.p), np.ascontiguousarray(sp.ng), np.ascontiguousarray(sp.ns)
        sign, fa = sp.frames.sign, sp.frames.a
        u1, u2 = np.ascontiguousarray(u12[:, 0]), np.ascontiguousarray(u12[:, 1])
        fn_c = np.ascontiguousarray(face_n)
        choose = (lambda: fused.chooser.sample(u[:, 0])) if fused is not None else \
            (lambda: em.chooser.sample(u[:, 2])) if quad is None else (lambda: kk)

        pos_r, nrm_r, rad_r = np.ascontiguousarray(pos.T), np.ascontiguousarray(nrm.T), np.ascontiguousarray(rad.T)

        def nb_light():  # the discrete choice stays in NumPy (as timed on the NumPy side)
            light_shadow_kernel(choose(), u1, u2, pos_r, fn_c, nrm_r, rad_r, pdf_scale, p_c, ng_c, ns_c, sign, fa,
                                g.eps, quad is not None, *lo)

        ls, wo_np, cos_np, o32_np, d32_np, tmax_np = np_light()
        nb_light()
        ok = (np.allclose(lo[0], wo_np, rtol=1e-12, atol=1e-12) and np.allclose(lo[3], ls.pdf, rtol=1e-10)
              and np.allclose(lo[2], ls.radiance) and np.allclose(lo[4], o32_np, rtol=1e-6)
              and np.allclose(lo[6], tmax_np, rtol=1e-12))
        agree.append(f"light+shadow {'agrees' if ok else 'DIFFERS'} ({'parallelogram' if quad else 'triangles'})")
        rows_out.append(("light+shadow", *cpu_ab(np_light, nb_light, a.rounds)))
    else:
        agree.append("light+shadow skipped (emitter kind not in the prototype)")

    # -- BSDF -----------------------------------------------------------------------------------
    kinds = {"RoughConductor": conductor_kernel, "RoughSubstrate": substrate_kernel}
    picked = [b for b in scene.bsdfs if type(b).__name__ in kinds and all(
        getattr(b, t).constant for t in b.texture_slots) and getattr(b, "lobe", "both") == "both"]
    if picked and light_ok:
        inner = picked[0]
        kind = type(inner).__name__
        wi_s, wo_s = np.ascontiguousarray(sp.wi), np.ascontiguousarray(wo_np)
        alpha = float(inner.alpha.luminance())
        fo = np.empty((m, 3))
        if kind == "RoughConductor":
            r0 = np.asarray(inner.R0.value, float)

            def nb_bsdf():
                conductor_kernel(wi_s, wo_s, alpha, r0, fo)
        else:
            kd = np.asarray(inner.kd.value, float)

            def nb_bsdf():
                substrate_kernel(wi_s, wo_s, alpha, kd, inner.diffuse_scale, inner.ext_ior, inner.int_ior, fo)

        def np_bsdf():
            return inner.eval(sp.wi, wo_np)

        ref_f = np_bsdf()
        nb_bsdf()
        agree.append(f"bsdf {'agrees' if np.allclose(fo, ref_f, rtol=1e-10, atol=1e-14) else 'DIFFERS'} "
                     f"(the scene's first {kind} at every shading point, light-sample directions)")
        # Share of camera hits on that kind over the whole image (one tile may have none).
        fams = scene_tables(scene).bsdf_families.families
        ox, oy = rng.random(n) * cam.width, rng.random(n) * cam.height
        c_all = np.take(tab.tri_code, g.trace(*cam.generate_rays(ox, oy)).prim)
        share = sum(int(np.sum(c_all >> 1 == fi)) for fi, fam in enumerate(fams)
                    if type(fam.members[0]).__name__ == kind) / n
        t_np, t_nb = cpu_ab(np_bsdf, nb_bsdf, a.rounds)
        agree.append(f"  ({100 * share:.0f} % of the camera hits over the image are {kind}: the projection counts "
                     "that share of the BSDF times)")
        rows_out.append((f"bsdf ({kind}, ×{share:.2f})", share * t_np, share * t_nb))
    else:
        agree.append("bsdf skipped (no constant roughconductor or roughsubstrate)")

    # -- splat ----------------------------------------------------------------------------------
    L = np.asfortranarray(np.random.default_rng(3).random((n, 3)))
    f = scene.filter
    ref = Film(cam.width, cam.height, f, x0, y0, w, h)
    ref.splat(sx, sy, L)
    L_c = np.ascontiguousarray(L)
    wt_c = np.ascontiguousarray(f.phase_weights)  # (phases, taps)

    def np_splat():
        Film(cam.width, cam.height, f, x0, y0, w, h).splat(sx, sy, L)

    def nb_splat():
        film = Film(cam.width, cam.height, f, x0, y0, w, h)
        splat_kernel(sx, sy, L_c, film.data, wt_c, f.phase_offset, f.phases, f.phase_bits,
                     f.phase_taps, film.border - x0, film.border - y0, film.bw, film.bh)
        return film

    if f.phase_bits is not None:
        got = nb_splat()
        agree.append(f"splat {'agrees' if np.allclose(got.data, ref.data, rtol=1e-12, atol=1e-12) else 'DIFFERS'}")
        rows_out.append(("splat", *cpu_ab(np_splat, nb_splat, a.rounds)))

    # -- the whole unit ---------------------------------------------------------------------------
    from brdflab.render import _render_unit

    def unit():
        _render_unit(scene, 0, 0, (x0, y0, w, h), spp, 0)

    unit_ms = cpu_ab(unit, unit, max(20, a.rounds // 10))[0]
    print(f"scene {a.scene}, one {n}-sample unit ({m} shading points), thread CPU ms, median of {a.rounds}")
    for s in agree:
        print("  " + s)
    print(f"{'kernel':30s} {'NumPy':>8s} {'Numba':>8s} {'speed-up':>9s}")
    saved = 0.0
    for name, t_np, t_nb in rows_out:
        print(f"{name:30s} {t_np:8.3f} {t_nb:8.3f} {t_np / max(t_nb, 1e-9):8.1f}×")
        saved += t_np - t_nb
    staged = sum(r[1] for r in rows_out)
    print(f"whole unit (NumPy, {scene.integrator_type}): {unit_ms:.2f} ms; these stages {staged:.2f} ms "
          f"({100 * staged / unit_ms:.0f} %)")
    print(f"projected unit with the kernels: {unit_ms - saved:.2f} ms → {unit_ms / (unit_ms - saved):.2f}× "
          "(Amdahl; Embree and the remaining NumPy unchanged)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
