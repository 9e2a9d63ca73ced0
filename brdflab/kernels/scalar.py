"""Scalar versions of the microfacet, Fresnel and warp formulas, one query at a time.

Each function mirrors a vectorised one of the specification (named in its docstring) operation for
operation, so that both round alike; see that function for the equation and its citation.
"""

from __future__ import annotations

import math

from brdflab.kernels.jit import inline

PI = math.pi
INV_PI = 1.0 / math.pi
TWO_PI = 2.0 * math.pi
SQRT_PI = math.sqrt(math.pi)  # the float64 of brdflab.bsdf.microfacet._SQRT_PI (np.sqrt(np.pi))


@inline
def beckmann_d(c, alpha):
    """:func:`brdflab.bsdf.microfacet.beckmann_d` (PBR eq. 8.9) for one cos θ_h."""
    if not c > 0.0:
        return 0.0
    a2 = alpha * alpha
    c2 = c * c
    t2 = max(1.0 - c2, 0.0) / c2
    d = math.exp(-t2 / a2) / (PI * a2 * (c2 * c2))
    return d if math.isfinite(d) else 0.0


@inline
def smith_g1(cos_v, vh, alpha):
    """:func:`brdflab.bsdf.microfacet.smith_g1` (Walter et al. 2007, eq. 27) with ``vh`` = v·ω_h."""
    if not (vh / cos_v) > 0.0:
        return 0.0
    tan_v = math.sqrt(max(1.0 - cos_v * cos_v, 0.0)) / abs(cos_v)
    b = 1.0 / (alpha * tan_v)
    if math.isnan(b) or not b < 1.6:
        return 1.0
    return (3.535 * b + 2.181 * b * b) / (1.0 + 2.276 * b + 2.577 * b * b)


@inline
def fresnel_dielectric(cos_i, eta_ext, eta_int):
    """:func:`brdflab.bsdf.fresnel.fresnel_dielectric` (PBR eqs. 8.1–8.3) for one cosine."""
    cos_i = min(max(cos_i, -1.0), 1.0)
    if eta_ext == eta_int:
        return 0.0
    if cos_i >= 0.0:
        eta_i, eta_t, ci = eta_ext, eta_int, cos_i
    else:
        eta_i, eta_t, ci = eta_int, eta_ext, abs(cos_i)
    e = eta_i / eta_t
    sin2_t = e * e * max(0.0, 1.0 - ci * ci)
    if sin2_t >= 1.0:
        return 1.0
    ct = math.sqrt(max(0.0, 1.0 - sin2_t))
    rs = (eta_i * ci - eta_t * ct) / (eta_i * ci + eta_t * ct)
    rp = (eta_t * ci - eta_i * ct) / (eta_t * ci + eta_i * ct)
    f = 0.5 * (rs * rs + rp * rp)
    if not math.isfinite(f):
        return 1.0
    return min(max(f, 0.0), 1.0)


@inline
def pow5(x):
    """:func:`brdflab.bsdf.fresnel.pow5`: x⁵ by products."""
    x2 = x * x
    x2 *= x2
    return x2 * x


@inline
def cos_over_pdf(cos_o, pdf):
    """The factor cos θ_o / p of :func:`brdflab.bsdf.base.cos_weight` (0 where the sample failed)."""
    if pdf > 0.0 and cos_o > 0.0:
        return cos_o / pdf
    return 0.0


@inline
def finite_or_zero(x):
    """x where finite, else 0."""
    return x if math.isfinite(x) else 0.0


@inline
def inv_a2(x, y, z, ax, ay):
    """``brdflab.bsdf.microfacet._inv_a2``: (α_u² x² + α_v² y²)/z² (∞ for 0/0)."""
    px, py = ax * x, ay * y
    t = (px * px + py * py) / (z * z)  # error_model="numpy": x/0 is ∞ or NaN, as in NumPy
    return math.inf if math.isnan(t) else t


@inline
def ndf(ggx, x, y, z, ax, ay):
    """:func:`brdflab.bsdf.microfacet.ndf` (Beckmann or GGX, anisotropic) for one ω_h."""
    if not z > 0.0:
        return 0.0
    qx, qy = x / ax, y / ay
    e = qx * qx + qy * qy
    z2 = z * z
    if ggx:
        q = e + z2
        d = 1.0 / (PI * ax * ay * (q * q))
    else:
        d = math.exp(-e / z2) / (PI * ax * ay * (z2 * z2))
    return 0.0 if not math.isfinite(d) else d


@inline
def g1(ggx, x, y, z, vh, ax, ay):
    """:func:`brdflab.bsdf.microfacet.g1`: exact GGX, rational Beckmann (anisotropic), with ``vh`` = v·ω_h."""
    if not (vh / z) > 0.0:
        return 0.0
    t = inv_a2(x, y, z, ax, ay)
    if ggx:
        return 2.0 / (1.0 + math.sqrt(1.0 + t))
    b = 1.0 / math.sqrt(t)
    if not b < 1.6:
        return 1.0
    return (3.535 * b + 2.181 * b * b) / (1.0 + 2.276 * b + 2.577 * b * b)


@inline
def ggx_lambda(x, y, z, ax, ay):
    """:func:`brdflab.bsdf.microfacet.smith_lambda` of GGX (Heitz 2014, eq. 72)."""
    return 0.5 * (math.sqrt(1.0 + inv_a2(x, y, z, ax, ay)) - 1.0)


@inline
def fresnel_conductor(c, eta, k):
    """:func:`brdflab.bsdf.fresnel.fresnel_conductor` (PBR-3 eqs. 8.5–8.6) for one cosine and channel."""
    c = min(max(c, 0.0), 1.0)
    c2 = c * c
    s2 = 1.0 - c2
    e2, k2 = eta * eta, k * k
    t0 = e2 - k2 - s2
    a2b2 = math.sqrt(t0 * t0 + 4.0 * e2 * k2)
    a = math.sqrt(max(0.5 * (a2b2 + t0), 0.0))
    t1 = a2b2 + c2
    t2 = 2.0 * c * a
    rs = (t1 - t2) / (t1 + t2)
    t3 = c2 * a2b2 + s2 * s2
    t4 = t2 * s2
    rp = rs * (t3 - t4) / (t3 + t4)
    f = 0.5 * (rs + rp)
    return min(max(f, 0.0), 1.0) if math.isfinite(f) else 1.0


@inline
def beckmann_lambda(x, y, z, ax, ay):
    """:func:`brdflab.bsdf.microfacet.smith_lambda` of Beckmann (Heitz 2014, eq. 86) for one direction."""
    a = 1.0 / math.sqrt(inv_a2(x, y, z, ax, ay))
    if a == 0.0:
        return math.inf
    lam = 0.5 * (math.exp(-a * a) / (a * SQRT_PI) - math.erfc(a))
    return max(lam, 0.0) if math.isfinite(lam) else 0.0

