"""Kernels of the built-in BSDFs: ``diffuse``, ``roughconductor``, ``roughsubstrate`` (compiled engine).

One kernel per material runs either *terms* (f and/or p of given directions: ``eval``, ``pdf``,
``eval_pdf``) or *sample* (warp, then the same terms and the weight f·cos θ_o/p). The per-point
formulas are those of the material's module docstring, written as in its NumPy ``_terms``/``sample``
(same operations, same order; see :mod:`brdflab.kernels.scalar`).

Parameters reach a kernel as a table and a row per point: a constant (one row), a texture looked up by
the NumPy code (one row per point) or a material family's member constants (a row index per point, see
:mod:`brdflab.bsdf.family`). Texture lookups stay in NumPy.
"""

from __future__ import annotations

import math

import numpy as np

from brdflab.bsdf import microfacet as mf
from brdflab.bsdf.base import BSDFSample, uv_or_zeros
from brdflab.kernels.buffers import columns
from brdflab.kernels.jit import BOOL, F8, I8, IDX, IN1, IN2, OUT1, OUT2, inline, kernel
from brdflab.kernels.scalar import (
    INV_PI,
    TWO_PI,
    beckmann_d,
    beckmann_lambda,
    cos_over_pdf,
    finite_or_zero,
    fresnel_conductor,
    fresnel_dielectric,
    g1,
    ggx_lambda,
    ndf,
    pow5,
    smith_g1,
)
from brdflab.texture import PointValues, Texture

#: Kernel operations.
TERMS, SAMPLE = 0, 1
#: Parameter modes: one constant row, one row per point, a row index per point.
CONSTANT, PER_POINT, INDEXED = 0, 1, 2
#: roughsubstrate lobes (its ``lobe`` argument).
LOBES = {"both": 0, "specular": 1, "diffuse": 2}
_NO_INDEX = np.zeros(0, np.int64)
_NO_U = np.zeros((0, 3))
_NO_LG = np.zeros(0)
_NO_ETA = np.ones(3)
_NO_SLOPES = np.zeros((0, 2))


def _nan_or(x: float | None) -> float:
    return math.nan if x is None else float(x)


@inline
def _row(mode, idx, i):
    if mode == CONSTANT:
        return 0
    if mode == PER_POINT:
        return i
    return idx[i]


@inline
def _beckmann_normal(lg, u1, a):
    """:func:`brdflab.math.warps.square_to_beckmann` (PBR eq. 8.12) for one sample, given
    ``lg`` = ln(1 − ξ1) (from NumPy's log1p: the C library's may round differently)."""
    tan2 = -(a * a) * lg
    cos_t = 1.0 / math.sqrt(1.0 + tan2)
    sin_t = math.sqrt(tan2) * cos_t if math.isfinite(tan2) else 1.0
    phi = TWO_PI * u1
    return sin_t * math.cos(phi), sin_t * math.sin(phi), cos_t


@inline
def _cosine_dir(u0, u1):
    """:func:`brdflab.math.warps.square_to_cosine_hemisphere` (Malley's method) for one sample."""
    r = math.sqrt(u0)
    phi = TWO_PI * u1
    return r * math.cos(phi), r * math.sin(phi), math.sqrt(max(0.0, 1.0 - u0))


@inline
def _reflect(wix, wiy, wiz, hx, hy, hz):
    """:func:`brdflab.bsdf.microfacet.reflect`: 2(ω_i·ω_h)ω_h − ω_i."""
    d2 = 2.0 * (wix * hx + wiy * hy + wiz * hz)
    return d2 * hx - wix, d2 * hy - wiy, d2 * hz - wiz


@inline
def _half(wix, wiy, wiz, wox, woy, woz):
    """:func:`brdflab.bsdf.microfacet.half_vector`: (ω_h, defined) and ω_i·ω_h."""
    hx, hy, hz = wix + wox, wiy + woy, wiz + woz
    n = math.sqrt(hx * hx + hy * hy + hz * hz)
    ok = n > 1e-12
    if not ok:
        n = 1.0
    hx, hy, hz = hx / n, hy / n, hz / n
    return hx, hy, hz, ok, hx * wix + hy * wiy + hz * wiz


@inline
def _reflection_pdf(hx, hy, hz, wox, woy, woz, d):
    """:func:`brdflab.bsdf.microfacet.reflection_pdf` (PBR eq. 8.13) given D(ω_h)."""
    oh = abs(wox * hx + woy * hy + woz * hz)
    return finite_or_zero(d * max(hz, 0.0) / (4.0 * oh))


@kernel(I8, BOOL, BOOL, IN2, OUT2, IN2, IN2, I8, IDX, OUT2, OUT1, OUT2)
def diffuse(op, need_f, need_pdf, wi, wo, u, alb, alb_mode, alb_idx, f, pdf, weight):
    """``diffuse``: f = albedo/π, p = cos θ_o/π, cosine-weighted sampling."""
    for i in range(wi.shape[0]):
        if op == SAMPLE:
            wo[i, 0], wo[i, 1], wo[i, 2] = _cosine_dir(u[i, 0], u[i, 1])
        ci, co = wi[i, 2], wo[i, 2]
        k = _row(alb_mode, alb_idx, i)
        s = INV_PI if ci > 0.0 and co > 0.0 else 0.0
        p = (co * INV_PI if co >= 0.0 else 0.0) if ci > 0.0 else 0.0
        pdf[i] = p
        c = cos_over_pdf(co, p)
        for j in range(3):
            fj = s * alb[k, j]
            if op == SAMPLE:
                weight[i, j] = finite_or_zero(fj * c)
            elif need_f:
                f[i, j] = fj


@inline
def _normalized(x, y, z):
    """``brdflab.bsdf.microfacet._normalize`` for one vector."""
    n = math.sqrt(x * x + y * y + z * z)
    return x / n, y / n, z / n


@inline
def _slope_normal(ggx, lg, u0, u1, ax, ay):
    """:func:`brdflab.bsdf.microfacet.sample_normals` (stretched slopes) for one sample; ``lg`` = ln(1 − ξ1)."""
    r2 = u0 / (1.0 - u0) if ggx else -lg
    r = math.sqrt(r2)
    phi = TWO_PI * u1
    return _normalized(-ax * r * math.cos(phi), -ay * r * math.sin(phi), 1.0)


@inline
def _ggx_visible_normal(wix, wiy, wiz, u0, u1, ax, ay):
    """:func:`brdflab.bsdf.microfacet.sample_visible_normals` of GGX (Heitz 2018, listing 3) for one sample."""
    vx, vy, vz = ax * wix, ay * wiy, wiz
    vn = math.sqrt(vx * vx + vy * vy + vz * vz)
    vx, vy, vz = vx / vn, vy / vn, vz / vn
    lensq = vx * vx + vy * vy
    t1x, t1y = 1.0, 0.0
    if lensq > 0.0:
        inv = 1.0 / math.sqrt(lensq)
        t1x, t1y = -vy * inv, vx * inv
    t2x, t2y, t2z = -vz * t1y, vz * t1x, vx * t1y - vy * t1x
    r = math.sqrt(u0)
    phi = TWO_PI * u1
    p1 = r * math.cos(phi)
    p2 = r * math.sin(phi)
    s = 0.5 * (1.0 + vz)
    p2 = (1.0 - s) * math.sqrt(max(0.0, 1.0 - p1 * p1)) + s * p2
    p3 = math.sqrt(max(0.0, 1.0 - p1 * p1 - p2 * p2))
    nx = p1 * t1x + p2 * t2x + p3 * vx
    ny = p1 * t1y + p2 * t2y + p3 * vy
    nz = p2 * t2z + p3 * vz
    return _normalized(ax * nx, ay * ny, max(0.0, nz))


@inline
def _beckmann_visible_normal(wix, wiy, wiz, sx, sy, ax, ay):
    """:func:`brdflab.bsdf.microfacet.sample_visible_normals` of Beckmann (Heitz & d'Eon 2014) for one sample,
    from its slopes (x̃, ỹ) of :func:`~brdflab.bsdf.microfacet.beckmann_visible_slopes` (computed by NumPy)."""
    vx, vy, vz = ax * wix, ay * wiy, wiz
    vn = math.sqrt(vx * vx + vy * vy + vz * vz)
    vx, vy, vz = vx / vn, vy / vn, vz / vn
    if not vz > 0.0:  # ω_i below the surface: the sample fails (as the NumPy function's NaN rows)
        return math.nan, math.nan, math.nan
    sin_t = math.sqrt(vx * vx + vy * vy)
    cos_p, sin_p = 1.0, 0.0
    if sin_t > 0.0:
        cos_p, sin_p = vx / sin_t, vy / sin_t
    x = ax * (cos_p * sx - sin_p * sy)
    y = ay * (sin_p * sx + cos_p * sy)
    return _normalized(-x, -y, 1.0)


@inline
def _conductor_point(wix, wiy, wiz, wox, woy, woz, a, ax, ay, iso, ggx, vis, use_eta, eta, kk, r0, k, need_f,
                     need_pdf, out, i):
    """f (into ``out[i]``) and returns p of one query (:meth:`RoughConductor._terms`): the course's Beckmann D
    and G1 when ``iso``, else :func:`~brdflab.kernels.scalar.ndf`/``g1``; Schlick, or (η, k) with ``use_eta``;
    the D cos θ_h or (``vis``) the visible-normal density."""
    ci, co = wiz, woz
    hx, hy, hz, okh, hi = _half(wix, wiy, wiz, wox, woy, woz)
    d = beckmann_d(hz, a) if iso else ndf(ggx, hx, hy, hz, ax, ay)
    if need_f:
        ok = ci > 0.0 and co > 0.0 and okh
        oh = wox * hx + woy * hy + woz * hz
        if iso:
            g = smith_g1(ci, hi, a) * smith_g1(co, oh, a)
        else:
            g = g1(ggx, wix, wiy, wiz, hi, ax, ay) * g1(ggx, wox, woy, woz, oh, ax, ay)
        s = finite_or_zero(d * g / (4.0 * ci * co)) if ok else 0.0
        if use_eta:
            for j in range(3):
                out[i, j] = fresnel_conductor(hi, eta[j], kk[j]) * s
        else:
            m5 = pow5(1.0 - min(max(hi, 0.0), 1.0))
            for j in range(3):
                r = r0[k, j]
                out[i, j] = (m5 * (1.0 - r) + r) * s
    p = 0.0
    if need_pdf and ci > 0.0 and okh and hi > 0.0:
        if vis:
            oh = abs(wox * hx + woy * hy + woz * hz)
            lam = ggx_lambda(wix, wiy, wiz, ax, ay) if ggx else beckmann_lambda(wix, wiy, wiz, ax, ay)
            p = finite_or_zero(d * max(hi, 0.0) / ((1.0 + lam) * ci * 4.0 * oh))
        else:
            p = _reflection_pdf(hx, hy, hz, wox, woy, woz, d)
    return p


@kernel(I8, BOOL, BOOL, IN2, OUT2, IN2, IN1, IN2, I8, IDX, IN1, I8, IDX, BOOL, BOOL, BOOL, BOOL, F8, F8, IN1, IN1,
        IN2, OUT2, OUT1, OUT2)
def conductor(op, need_f, need_pdf, wi, wo, u, lg, r0, r0_mode, r0_idx, al, al_mode, al_idx, iso, ggx, vis, use_eta,
              au, av, eta, kk, slopes, f, pdf, weight):
    """``roughconductor``: Beckmann (the course's, or anisotropic) or GGX D, Schlick or (η, k) F, Smith G1;
    D cos θ_h sampling (the Beckmann warp, or stretched slopes) or visible normals (Beckmann's from the
    ``slopes`` NumPy solved), then reflection."""
    for i in range(wi.shape[0]):
        a = al[_row(al_mode, al_idx, i)]
        ax = a if math.isnan(au) else au
        ay = a if math.isnan(av) else av
        wix, wiy, wiz = wi[i, 0], wi[i, 1], wi[i, 2]
        if op == SAMPLE:
            if iso and not vis:
                hx, hy, hz = _beckmann_normal(lg[i], u[i, 1], a)
            elif vis and ggx:
                hx, hy, hz = _ggx_visible_normal(wix, wiy, wiz, u[i, 0], u[i, 1], ax, ay)
            elif vis:
                hx, hy, hz = _beckmann_visible_normal(wix, wiy, wiz, slopes[i, 0], slopes[i, 1], ax, ay)
            else:
                hx, hy, hz = _slope_normal(ggx, 0.0 if ggx else lg[i], u[i, 0], u[i, 1], ax, ay)
            ox, oy, oz = _reflect(wix, wiy, wiz, hx, hy, hz)
            if not (math.isfinite(ox) and math.isfinite(oy) and math.isfinite(oz)):
                ox, oy, oz = 0.0, 0.0, -1.0
            wo[i, 0], wo[i, 1], wo[i, 2] = ox, oy, oz
        k = _row(r0_mode, r0_idx, i)
        out = weight if op == SAMPLE else f
        p = _conductor_point(wix, wiy, wiz, wo[i, 0], wo[i, 1], wo[i, 2], a, ax, ay, iso, ggx, vis, use_eta, eta, kk,
                             r0, k, need_f, need_pdf, out, i)
        pdf[i] = p
        if op == SAMPLE:
            c = cos_over_pdf(wo[i, 2], p)
            for j in range(3):
                weight[i, j] = finite_or_zero(weight[i, j] * c)


@inline
def _p_specular(ci, lobe, eta_ext, eta_int):
    """:meth:`RoughSubstrate._p_specular`: min(F_dielectric(cos θ_i), 0.95) (1 or 0 for one lobe)."""
    if lobe == 1:
        return 1.0
    if lobe == 2:
        return 0.0
    return min(fresnel_dielectric(ci, eta_ext, eta_int), 0.95)


@kernel(I8, BOOL, BOOL, IN2, OUT2, IN2, IN1, IN2, I8, IDX, IN1, I8, IDX, I8, F8, F8, F8, OUT2, OUT1, OUT2)
def substrate(op, need_f, need_pdf, wi, wo, u, lg, kd, kd_mode, kd_idx, al, al_mode, al_idx, lobe, eta_ext, eta_int,
              diffuse_scale, f, pdf, weight):
    """``roughsubstrate``: Ashikhmin–Shirley diffuse + Beckmann dielectric coat; mixture sampling."""
    out = weight if op == SAMPLE else f
    for i in range(wi.shape[0]):
        a = al[_row(al_mode, al_idx, i)]
        wix, wiy, wiz = wi[i, 0], wi[i, 1], wi[i, 2]
        ps = _p_specular(wiz, lobe, eta_ext, eta_int)
        if op == SAMPLE:
            wox, woy, woz = _cosine_dir(u[i, 0], u[i, 1])
            if u[i, 2] < ps:
                hx, hy, hz = _beckmann_normal(lg[i], u[i, 1], a)
                wox, woy, woz = _reflect(wix, wiy, wiz, hx, hy, hz)
            wo[i, 0], wo[i, 1], wo[i, 2] = wox, woy, woz
        else:
            wox, woy, woz = wo[i, 0], wo[i, 1], wo[i, 2]
        ci, co = wiz, woz
        hx, hy, hz, okh, hi = _half(wix, wiy, wiz, wox, woy, woz)
        d = beckmann_d(hz, a)
        if need_f:
            ok = ci > 0.0 and co > 0.0
            s = 0.0
            if lobe != 1 and ok:
                s = diffuse_scale * (1.0 - pow5(1.0 - 0.5 * ci)) * (1.0 - pow5(1.0 - 0.5 * co))
            m = 0.0
            if lobe != 2:
                fr = fresnel_dielectric(min(max(hi, 0.0), 1.0), eta_ext, eta_int)
                g = smith_g1(ci, hi, a) * smith_g1(co, wox * hx + woy * hy + woz * hz, a)
                m = finite_or_zero(d * fr * g / (4.0 * ci * co)) if ok and okh else 0.0
            k = _row(kd_mode, kd_idx, i)
            for j in range(3):
                out[i, j] = (0.0 + kd[k, j] * s if lobe != 1 else 0.0) + m
        p = 0.0
        if need_pdf and ci > 0.0:
            p_mf = _reflection_pdf(hx, hy, hz, wox, woy, woz, d) if okh and hi > 0.0 else 0.0
            p_d = co * INV_PI if co >= 0.0 else 0.0
            p = ps * p_mf + (1.0 - ps) * p_d
        pdf[i] = p
        if op == SAMPLE:
            c = cos_over_pdf(co, p)
            for j in range(3):
                weight[i, j] = finite_or_zero(weight[i, j] * c)


def _slot(tex: Texture, uv: np.ndarray | None, n: int, grey: bool) -> tuple[np.ndarray, int, np.ndarray]:
    """(table, mode, row index) of a texture slot: colours (K, 3), or with ``grey`` luminances (K,) (the
    roughness α), as the NumPy code reads them."""
    if tex.constant:
        return (np.array([tex.luminance()]) if grey else tex.value.reshape(1, 3)), CONSTANT, _NO_INDEX
    if isinstance(tex, PointValues):
        return (tex.lum if grey else tex.table.T), INDEXED, tex.index.astype(np.int64, copy=False)
    uvs = uv_or_zeros(uv, n)
    return np.asarray(tex.luminance(uvs) if grey else tex.eval(uvs), np.float64), PER_POINT, _NO_INDEX


def _run(bsdf, op: int, need_f: bool, need_pdf: bool, wi: np.ndarray, wo: np.ndarray | None,
         u: np.ndarray | None, uv: np.ndarray | None):
    n = len(wi)
    wi = np.asarray(wi, np.float64)
    if op == TERMS:
        wo = np.asarray(wo, np.float64)
        if not wo.flags.writeable:  # the kernel's ω_o argument is also its output when it samples
            wo = wo.copy()
    # Outputs are left uninitialised: the kernels write every row of the ones they are asked for.
    f = weight = np.empty((0, 3), order="F")
    if op == SAMPLE:
        wo, weight, pdf = columns(n, [3, 3, None])
        need_f = need_pdf = True
    elif need_f:
        f, pdf = columns(n, [3, None])
    else:
        pdf = np.empty(n)
    u = _NO_U if u is None else np.asarray(u, np.float64)
    # ln(1 − ξ1) of the Beckmann warp by NumPy: its SIMD log1p and the C library's differ in the last bit,
    # which tiny α amplifies (exp, sin, cos and sqrt agree or are not amplified).
    lg = _NO_LG
    name = type(bsdf).kernel
    if op == SAMPLE and name != "diffuse" and getattr(bsdf, "distribution", "") != "ggx":
        with np.errstate(divide="ignore"):  # ξ1 = 1: ln 0 = −∞, the horizon (as in the NumPy warp)
            lg = np.log1p(-u[:, 0])
    if name == "diffuse":
        diffuse(op, need_f, need_pdf, wi, wo, u, *_slot(bsdf.albedo, uv, n, False), f, pdf, weight)
    elif name == "roughconductor":
        eta = _NO_ETA if bsdf.eta is None else bsdf.eta
        kk = _NO_ETA if bsdf.k is None else bsdf.k
        slopes = _NO_SLOPES
        if op == SAMPLE and bsdf.sample_visible and bsdf.distribution == "beckmann":
            # Beckmann's visible slope is the root of a CDF of erfc, where SciPy's and the C library's erfc differ
            # by an ulp and the root amplifies it (to 1e-10 at α = 10⁻³): NumPy solves it, the kernel does the rest.
            slopes = np.stack(mf.beckmann_visible_slopes(wi, u, *bsdf.alphas(uv, n)), axis=1)
        conductor(op, need_f, need_pdf, wi, wo, u, lg, *_slot(bsdf.R0, uv, n, False), *_slot(bsdf.alpha, uv, n, True),
                  bsdf.isotropic_beckmann, bsdf.distribution == "ggx", bsdf.sample_visible, bsdf.eta is not None,
                  _nan_or(bsdf.alpha_u), _nan_or(bsdf.alpha_v), eta, kk, slopes, f, pdf, weight)
    else:
        substrate(op, need_f, need_pdf, wi, wo, u, lg, *_slot(bsdf.kd, uv, n, False), *_slot(bsdf.alpha, uv, n, True),
                  LOBES.get(bsdf.lobe, 0), bsdf.ext_ior, bsdf.int_ior, bsdf.diffuse_scale, f, pdf, weight)
    return f, pdf, wo, weight


def _covered(bsdf) -> bool:
    """False for an instance outside the kernel's models: the NumPy method runs instead (the twin returns
    ``NotImplemented``). Every roughconductor (Beckmann or GGX, visible normals or not) is covered; a roughsubstrate
    only with the default coat (Beckmann, one α, D cos θ_h)."""
    if type(bsdf).kernel == "roughsubstrate":
        return bsdf.default_options
    return True


def eval_bsdf(bsdf, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None = None) -> np.ndarray:
    """``bsdf.eval`` of a built-in material, compiled."""
    if not _covered(bsdf):
        return NotImplemented
    return _run(bsdf, TERMS, True, False, wi, wo, None, uv)[0]


def pdf_bsdf(bsdf, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None = None) -> np.ndarray:
    """``bsdf.pdf`` of a built-in material, compiled."""
    if not _covered(bsdf):
        return NotImplemented
    return _run(bsdf, TERMS, False, True, wi, wo, None, uv)[1]


def eval_pdf_bsdf(bsdf, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None = None):
    """``bsdf.eval_pdf`` of a built-in material, compiled."""
    if not _covered(bsdf):
        return NotImplemented
    f, pdf, _, _ = _run(bsdf, TERMS, True, True, wi, wo, None, uv)
    return f, pdf


def sample_bsdf(bsdf, wi: np.ndarray, u: np.ndarray, uv: np.ndarray | None = None) -> BSDFSample:
    """``bsdf.sample`` of a built-in material, compiled."""
    if not _covered(bsdf):
        return NotImplemented
    _, pdf, wo, weight = _run(bsdf, SAMPLE, True, True, wi, None, u, uv)
    return BSDFSample(wo, weight, pdf)
