"""Microfacet distributions, Smith shadowing and the normal samplers (spec §11.1, PBR §8.4, Heitz 2014/2018).

Local frame with the normal along z; cos θ = z; α_u (``ax``) is the roughness along the frame's x axis, α_v
(``ay``) along y (Mitsuba 3's convention). The course's isotropic Beckmann functions (:func:`beckmann_d`,
:func:`smith_g1`, the warp :func:`brdflab.math.warps.square_to_beckmann`) are kept exactly as they were: the
anisotropic and GGX formulas below are separate functions, used only when a material asks for them.

* Beckmann NDF (PBR eq. 8.9 with α_x = α_y = α):
  D(ω_h) = exp(−tan²θ_h / α²) / (π α² cos⁴θ_h), 0 for cos θ_h ≤ 0.
  tan²θ is formed as (1 − cos²θ)/cos²θ = sin²θ/cos²θ from the clamped cosine, which stays finite and
  non-negative at grazing angles (no tan of an angle, no cancellation in 1 − cos² below 1e-16).
* Smith G1, rational approximation of the Beckmann shadowing term (Walter et al. 2007, eq. 27):
  G1(v, ω_h) = χ⁺((v·ω_h)/(v·n)) · { (3.535b + 2.181b²)/(1 + 2.276b + 2.577b²) if b < 1.6; 1 otherwise },
  b = 1/(α tan θ_v); θ_v = 0 gives b = ∞ and G1 = 1.
* Microfacet reflection: ω_o = 2(ω_i·ω_h)ω_h − ω_i, with the half-vector Jacobian
  dω_h/dω_o = 1/(4 |ω_o·ω_h|) (PBR eq. 8.13), so p(ω_o) = D(ω_h) cos θ_h / (4 |ω_o·ω_h|).

Anisotropic and GGX (:func:`ndf`, :func:`g1`, :func:`smith_lambda`; Heitz 2014, "Understanding the
Masking-Shadowing Function", eqs. 71–72, 80–86; PBR-3 eqs. 8.10–8.12, 8.16):

* Beckmann: D(ω_h) = exp(−(x²/α_u² + y²/α_v²)/z²) / (π α_u α_v z⁴);
  GGX (Trowbridge–Reitz): D(ω_h) = 1 / (π α_u α_v (x²/α_u² + y²/α_v² + z²)²), both 0 for z ≤ 0.
* With a = 1/(α(φ_v) tan θ_v) = z / √(α_u² x² + α_v² y²) for v = (x, y, z): GGX Λ(v) = (−1 + √(1 + 1/a²))/2
  and its exact G1 = χ⁺ · 2/(1 + √(1 + 1/a²)); Beckmann Λ(v) = (e^(−a²)/(a√π) − erfc(a))/2 (exact, used for the
  density of visible-normal sampling) and, for f, the rational G1 above with b = a (the course's approximation).
* Sampling ω_h ∝ D cos θ_h (:func:`sample_normals`): slopes of the stretched distribution, (x̃, ỹ) =
  (α_u r cos φ, α_v r sin φ) with φ = 2πξ2 and r² = −ln(1 − ξ1) (Beckmann) or ξ1/(1 − ξ1) (GGX), then
  ω_h = normalize(−x̃, −ỹ, 1) (Heitz 2014 §5.2 slope space: P22 is D cos⁴θ_h, dω = cos³θ_h d(slope)).
* Visible normals (:func:`sample_visible_normals`), density D_ωi(ω_h) = G1(ω_i) max(0, ω_i·ω_h) D(ω_h) / cos θ_i
  with the exact G1 = 1/(1 + Λ(ω_i)) (Heitz 2018, JCGT 7(4), eq. 1; :func:`visible_pdf` adds the reflection
  Jacobian 1/(4 |ω_o·ω_h|)). GGX: Heitz 2018's hemisphere construction (listing 3: stretch ω_i, sample the
  projected disk, unstretch). Beckmann: Heitz & d'Eon 2014 ("Importance Sampling Microfacet-Based BSDFs using
  the Distribution of Visible Normals", §4 and appendix): stretch ω_i to α = 1, sample the slope x̃ with density
  ∝ (cos θ − x̃ sin θ) e^(−x̃²) on x̃ < cot θ by inverting its CDF
  C(x̃) ∝ cos θ (√π/2) erfc(−x̃) + sin θ e^(−x̃²)/2 (safeguarded Newton to rounding, at most 48 steps),
  ỹ = erfinv(2ξ2 − 1), rotate by φ_i, unstretch, ω_h = normalize(−x̃, −ỹ, 1).

All functions are vectorised and computed in float64.
"""

from __future__ import annotations

import numpy as np

BECKMANN, GGX = "beckmann", "ggx"
DISTRIBUTIONS = (BECKMANN, GGX)
_SQRT_PI = float(np.sqrt(np.pi))
_EPS = float(np.finfo(np.float64).eps)


def tan2_theta(cos_t: np.ndarray) -> np.ndarray:
    """tan²θ = (1 − cos²θ)/cos²θ for cos θ > 0 (inf for cos θ ≤ 0)."""
    c2 = cos_t * cos_t
    with np.errstate(divide="ignore", invalid="ignore"):
        t2 = np.maximum(1.0 - c2, 0.0) / c2
    return np.where(cos_t > 0, t2, np.inf)


def beckmann_d(cos_theta_h: np.ndarray, alpha: np.ndarray | float) -> np.ndarray:
    """Beckmann NDF D(ω_h) given cos θ_h (PBR eq. 8.9); 0 for cos θ_h ≤ 0."""
    c = np.asarray(cos_theta_h, dtype=np.float64)
    a2 = np.asarray(alpha, dtype=np.float64) ** 2
    ok = c > 0
    cs = np.where(ok, c, 1.0)
    with np.errstate(over="ignore", under="ignore", invalid="ignore", divide="ignore"):
        c2 = cs * cs
        d = np.exp(-tan2_theta(cs) / a2) / (np.pi * a2 * (c2 * c2))  # cos⁴ by products (as the kernel)
    return np.where(ok & np.isfinite(d), d, 0.0)


def smith_g1(v: np.ndarray, wh: np.ndarray, alpha: np.ndarray | float, vh: np.ndarray | None = None) -> np.ndarray:
    """Rational Smith G1(v, ω_h) for the Beckmann NDF (Walter et al. 2007, eq. 27); ``vh`` = v·ω_h if known."""
    cos_v = v[:, 2]
    if vh is None:
        vh = v[:, 0] * wh[:, 0] + v[:, 1] * wh[:, 1] + v[:, 2] * wh[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        chi = (vh / cos_v) > 0
        tan_v = np.sqrt(np.maximum(1.0 - cos_v * cos_v, 0.0)) / np.abs(cos_v)
        b = 1.0 / (np.asarray(alpha, dtype=np.float64) * tan_v)
    b = np.where(np.isnan(b), np.inf, b)
    small = b < 1.6
    bs = np.where(small, b, 0.0)
    g = np.where(small, (3.535 * bs + 2.181 * bs * bs) / (1.0 + 2.276 * bs + 2.577 * bs * bs), 1.0)
    return np.where(chi, g, 0.0)


def half_vector(wi: np.ndarray, wo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """ω_h = normalize(ω_i + ω_o) and a mask of where it is defined (ω_i ≠ −ω_o)."""
    h = wi + wo
    n = np.sqrt(h[:, 0] ** 2 + h[:, 1] ** 2 + h[:, 2] ** 2)
    ok = n > 1e-12
    return h / np.where(ok, n, 1.0)[:, None], ok


def reflect(wi: np.ndarray, wh: np.ndarray) -> np.ndarray:
    """Mirror ω_i about ω_h: 2(ω_i·ω_h)ω_h − ω_i."""
    d = wi[:, 0] * wh[:, 0] + wi[:, 1] * wh[:, 1] + wi[:, 2] * wh[:, 2]
    return 2.0 * d[:, None] * wh - wi


def reflection_pdf(wh: np.ndarray, wo: np.ndarray, alpha: np.ndarray | float,
                   d: np.ndarray | None = None) -> np.ndarray:
    """p(ω_o) = D(ω_h) cos θ_h / (4 |ω_o·ω_h|) for ω_o reflected about a Beckmann-sampled ω_h.

    ``d`` is D(ω_h) when the caller has it already.
    """
    oh = np.abs(wo[:, 0] * wh[:, 0] + wo[:, 1] * wh[:, 1] + wo[:, 2] * wh[:, 2])
    if d is None:
        d = beckmann_d(wh[:, 2], alpha)
    with np.errstate(divide="ignore", invalid="ignore"):
        p = d * np.maximum(wh[:, 2], 0.0) / (4.0 * oh)
    return np.where(np.isfinite(p), p, 0.0)


def _special():
    """scipy.special, imported on first use (a render of the course's model never needs it)."""
    from scipy import special

    return special


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


def _normalize(x: np.ndarray, y: np.ndarray, z: np.ndarray) -> np.ndarray:
    n = np.sqrt(x * x + y * y + z * z)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.stack([x / n, y / n, z / n], axis=1)


def ndf(dist: str, wh: np.ndarray, ax, ay) -> np.ndarray:
    """D(ω_h) of ``dist`` (``beckmann`` or ``ggx``) with roughness (α_u, α_v) (module docstring); 0 for z ≤ 0."""
    x, y, z = wh[:, 0], wh[:, 1], wh[:, 2]
    ax = np.asarray(ax, dtype=np.float64)
    ay = np.asarray(ay, dtype=np.float64)
    ok = z > 0
    with np.errstate(over="ignore", under="ignore", invalid="ignore", divide="ignore"):
        e = (x / ax) ** 2 + (y / ay) ** 2  # slope term x²/α_u² + y²/α_v²
        z2 = z * z
        if dist == GGX:
            q = e + z2
            d = 1.0 / (np.pi * ax * ay * (q * q))
        else:
            d = np.exp(-e / z2) / (np.pi * ax * ay * (z2 * z2))
    return np.where(ok & np.isfinite(d), d, 0.0)


def _inv_a2(v: np.ndarray, ax, ay) -> np.ndarray:
    """1/a² = (α_u² x² + α_v² y²)/z² = α(φ)² tan²θ of directions ``v`` (inf for z = 0)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t = ((ax * v[:, 0]) ** 2 + (ay * v[:, 1]) ** 2) / (v[:, 2] * v[:, 2])
    return np.where(np.isnan(t), np.inf, t)


def smith_lambda(dist: str, v: np.ndarray, ax, ay) -> np.ndarray:
    """Exact Smith Λ(v) of ``dist`` (Heitz 2014, eqs. 72 and 86), for directions with z > 0."""
    t = _inv_a2(v, ax, ay)
    if dist == GGX:
        return 0.5 * (np.sqrt(1.0 + t) - 1.0)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        a = 1.0 / np.sqrt(t)
        lam = 0.5 * (np.exp(-a * a) / (a * _SQRT_PI) - _special().erfc(a))
    return np.where(a == 0, np.inf, np.where(np.isfinite(lam), np.maximum(lam, 0.0), 0.0))


def g1(dist: str, v: np.ndarray, wh: np.ndarray, ax, ay, vh: np.ndarray | None = None) -> np.ndarray:
    """Smith G1(v, ω_h) for f: exact for GGX, the rational approximation for Beckmann (anisotropic α)."""
    if vh is None:
        vh = _dot(v, wh)
    with np.errstate(divide="ignore", invalid="ignore"):
        chi = (vh / v[:, 2]) > 0
    t = _inv_a2(v, ax, ay)
    if dist == GGX:
        g = 2.0 / (1.0 + np.sqrt(1.0 + t))
    else:
        with np.errstate(divide="ignore"):
            b = 1.0 / np.sqrt(t)
        small = b < 1.6
        bs = np.where(small, b, 0.0)
        g = np.where(small, (3.535 * bs + 2.181 * bs * bs) / (1.0 + 2.276 * bs + 2.577 * bs * bs), 1.0)
    return np.where(chi, g, 0.0)


def sample_normals(dist: str, u: np.ndarray, ax, ay) -> np.ndarray:
    """Normals ω_h with density D(ω_h) cos θ_h (module docstring: stretched slopes); ξ1 = 1 gives NaN rows
    (the caller's sample then fails)."""
    u1 = u[:, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        r2 = u1 / (1.0 - u1) if dist == GGX else -np.log1p(-u1)
    r = np.sqrt(r2)
    phi = 2.0 * np.pi * u[:, 1]
    return _normalize(-ax * r * np.cos(phi), -ay * r * np.sin(phi), np.ones_like(r))


def _beckmann_slope_x(cos_t: np.ndarray, sin_t: np.ndarray, u: np.ndarray) -> np.ndarray:
    """The slope x̃ < cot θ with density ∝ (cos θ − x̃ sin θ) e^(−x̃²) at CDF value ``u`` (safeguarded Newton).

    Each element stops when C(x̃) meets the target to its rounding or the step is at the rounding of x̃ (then
    Newton may only alternate between neighbours), at most 48 steps; only the elements still moving are
    computed. Elements with cos θ ≤ 0 (ω_i below the surface: the sample fails) keep the start value.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        mu = np.minimum(np.where(sin_t > 0, cos_t / sin_t, np.inf), 8.0)

    def cdf(x, c, s):  # unnormalised C(x̃)
        return c * (0.5 * _SQRT_PI) * _special().erfc(-x) + s * 0.5 * np.exp(-x * x)

    target = u * cdf(mu, cos_t, sin_t)
    lo = np.full_like(mu, -8.0)
    hi = mu.copy()
    x = np.clip(_special().erfinv(2.0 * u - 1.0), lo, hi)  # the normal-incidence solution as the start
    act = np.flatnonzero(cos_t > 0)
    for _ in range(48):
        if not len(act):
            break
        xa, c, s = x[act], cos_t[act], sin_t[act]
        cx = cdf(xa, c, s)
        fx = cx - target[act]
        below = fx < 0
        la = lo[act] = np.where(below, xa, lo[act])
        ha = hi[act] = np.where(below, hi[act], xa)
        dens = (c - xa * s) * np.exp(-xa * xa)
        with np.errstate(divide="ignore", invalid="ignore"):
            xn = xa - fx / dens
        # Newton inside the bracket [lo, hi] (closed: at the root itself it stays there), else bisection
        x_next = np.where((xn >= la) & (xn <= ha), xn, 0.5 * (la + ha))
        x[act] = x_next
        # Done: C(x̃) equals the target to its rounding, or the step is an ulp or two of x̃
        done = (np.abs(fx) <= 4.0 * _EPS * cx) | (np.abs(x_next - xa) <= 4.0 * _EPS * np.maximum(np.abs(xa), 1.0))
        act = act[~done]
    return x


def _stretched(wi: np.ndarray, ax, ay) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ω_i stretched to α = 1: normalize(α_u x, α_v y, z)."""
    vx, vy, vz = ax * wi[:, 0], ay * wi[:, 1], wi[:, 2]
    vn = np.sqrt(vx * vx + vy * vy + vz * vz)
    return vx / vn, vy / vn, vz / vn


def beckmann_visible_slopes(wi: np.ndarray, u: np.ndarray, ax, ay) -> tuple[np.ndarray, np.ndarray]:
    """The slopes (x̃, ỹ) of Beckmann's visible normals for ω_i stretched by (α_u, α_v), before the rotation by
    φ_i and the scaling by α (Heitz & d'Eon 2014; module docstring). The compiled engine takes them from here:
    x̃ is the root of a CDF evaluated with SciPy's erfc, which the C library's differs from by an ulp."""
    vx, vy, vz = _stretched(wi, ax, ay)
    return _beckmann_slope_x(vz, np.sqrt(vx * vx + vy * vy), u[:, 0]), _special().erfinv(2.0 * u[:, 1] - 1.0)


def sample_visible_normals(dist: str, wi: np.ndarray, u: np.ndarray, ax, ay) -> np.ndarray:
    """Normals ω_h with density D_ωi(ω_h) = G1(ω_i) max(0, ω_i·ω_h) D(ω_h) / cos θ_i (module docstring).

    ``wi`` must have z > 0 (rows with z ≤ 0 return arbitrary unit vectors (GGX) or NaN (Beckmann): the caller's
    sample fails).
    """
    vx, vy, vz = _stretched(wi, ax, ay)
    lensq = vx * vx + vy * vy
    if dist == GGX:  # Heitz 2018, listing 3
        inv = np.where(lensq > 0, 1.0 / np.sqrt(np.where(lensq > 0, lensq, 1.0)), 0.0)
        t1x, t1y = np.where(lensq > 0, -vy * inv, 1.0), np.where(lensq > 0, vx * inv, 0.0)
        t2x, t2y, t2z = -vz * t1y, vz * t1x, vx * t1y - vy * t1x  # T2 = V × T1 (T1_z = 0)
        r = np.sqrt(u[:, 0])
        phi = 2.0 * np.pi * u[:, 1]
        p1 = r * np.cos(phi)
        p2 = r * np.sin(phi)
        s = 0.5 * (1.0 + vz)
        p2 = (1.0 - s) * np.sqrt(np.maximum(0.0, 1.0 - p1 * p1)) + s * p2
        p3 = np.sqrt(np.maximum(0.0, 1.0 - p1 * p1 - p2 * p2))
        nx = p1 * t1x + p2 * t2x + p3 * vx
        ny = p1 * t1y + p2 * t2y + p3 * vy
        nz = p2 * t2z + p3 * vz
        return _normalize(ax * nx, ay * ny, np.maximum(0.0, nz))
    # Beckmann: Heitz & d'Eon 2014 (module docstring)
    sin_t = np.sqrt(lensq)
    cos_p = np.where(sin_t > 0, vx / np.where(sin_t > 0, sin_t, 1.0), 1.0)
    sin_p = np.where(sin_t > 0, vy / np.where(sin_t > 0, sin_t, 1.0), 0.0)
    sx, sy = beckmann_visible_slopes(wi, u, ax, ay)
    x = ax * (cos_p * sx - sin_p * sy)
    y = ay * (sin_p * sx + cos_p * sy)
    return _normalize(np.where(vz > 0, -x, np.nan), -y, np.ones_like(x))  # ω_i below: NaN, the sample fails


def visible_pdf(dist: str, wi: np.ndarray, wh: np.ndarray, wo: np.ndarray, ax, ay,
                d: np.ndarray | None = None, hi: np.ndarray | None = None) -> np.ndarray:
    """p(ω_o) = G1(ω_i) max(0, ω_i·ω_h) D(ω_h) / cos θ_i · 1/(4 |ω_o·ω_h|) with the exact G1 = 1/(1 + Λ(ω_i));
    ``d`` = D(ω_h) and ``hi`` = ω_i·ω_h when the caller has them."""
    if d is None:
        d = ndf(dist, wh, ax, ay)
    if hi is None:
        hi = _dot(wi, wh)
    oh = np.abs(_dot(wo, wh))
    ci = wi[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        p = d * np.maximum(hi, 0.0) / ((1.0 + smith_lambda(dist, wi, ax, ay)) * ci * 4.0 * oh)
    return np.where((ci > 0) & np.isfinite(p), p, 0.0)
