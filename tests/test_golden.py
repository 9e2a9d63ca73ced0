"""Golden values: every model term against an independent high-precision transcription of its equation.

The references below are written from ``../shared/docs/nori-scene-format.md`` (§10.5, §10.6, §11.1, §11.2)
in ``mpmath`` at 40 significant digits (Schlick in exact ``fractions``), without calling any brdflab code.
brdflab's float64 results are compared at a grid of (α, θ_i, θ_o, φ) that includes normal incidence,
grazing angles (89.9°, 89.999°), tiny roughness (α = 10⁻³, 10⁻⁴) with directions a few α from the mirror
direction, both branches of the rational G1 (b just below and above 1.6), total internal reflection and
the critical angle. The tolerances (≤ 1e-9 relative, looser only where float64 itself is ill-conditioned,
each stated) are far below the effect of changing any constant or exponent of a formula (the smallest,
1.6 → 1.7 in G1's branch point, changes G1 by 6e-5), so every such change fails here.

The pdfs are also integrated over the sphere by quadrature: ∫ p dω = 1 (minus the documented missing mass of
microfacets facing away from ω_i), which a missing or wrong Jacobian breaks.
"""

from __future__ import annotations

from fractions import Fraction

import mpmath as mp
import numpy as np
import pytest

from brdflab.bsdf.diffuse import Diffuse
from brdflab.bsdf.fresnel import fresnel_dielectric, fresnel_schlick
from brdflab.bsdf.microfacet import beckmann_d, smith_g1
from brdflab.bsdf.roughconductor import RoughConductor
from brdflab.bsdf.roughsubstrate import RoughSubstrate
from brdflab.math import warps

mp.mp.dps = 40
ETA_EXT, ETA_INT = 1.000277, 1.5046  # the spec's default IORs (§10.4)
R0 = (0.9, 0.5, 0.1)
KD = (0.2, 0.5, 0.8)


# -- independent references (spec equations, mpmath) ----------------------------------------------------------
def M(x) -> mp.mpf:
    """The float64 input, exactly."""
    return mp.mpf(float(x))


def vec(w) -> list[mp.mpf]:
    """A float64 direction, exactly, renormalised in high precision."""
    v = [M(c) for c in w]
    n = mp.sqrt(sum(c * c for c in v))
    return [c / n for c in v]


def dotm(a, b) -> mp.mpf:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def ref_d(c: mp.mpf, a: mp.mpf) -> mp.mpf:
    """Beckmann D = exp(−tan²θ_h/α²)/(π α² cos⁴θ_h) (§11.1), 0 for cos θ_h ≤ 0."""
    if c <= 0:
        return mp.mpf(0)
    t2 = (1 - c * c) / (c * c)
    return mp.exp(-t2 / (a * a)) / (mp.pi * a * a * c**4)


def ref_g1(v, h, a: mp.mpf) -> mp.mpf:
    """Rational Smith G1 (§11.1): χ⁺((v·h)/v_z); b = 1/(α tan θ_v); rational for b < 1.6, else 1."""
    vz = v[2]
    if dotm(v, h) / vz <= 0:
        return mp.mpf(0)
    s = mp.sqrt(max(1 - vz * vz, mp.mpf(0)))
    if s == 0:
        return mp.mpf(1)
    b = 1 / (a * s / vz)
    if b >= mp.mpf("1.6"):
        return mp.mpf(1)
    return (mp.mpf("3.535") * b + mp.mpf("2.181") * b * b) / (1 + mp.mpf("2.276") * b + mp.mpf("2.577") * b * b)


def ref_fresnel(ci: mp.mpf, ext: mp.mpf, int_: mp.mpf) -> mp.mpf:
    """Exact unpolarised dielectric Fresnel (§11.1), with the media swapped for cos θ_i < 0 and TIR → 1."""
    if ext == int_:
        return mp.mpf(0)
    ei, et = ext, int_
    if ci < 0:
        ei, et, ci = int_, ext, -ci
    sin2t = (ei / et) ** 2 * (1 - ci * ci)
    if sin2t > 1:
        return mp.mpf(1)
    ct = mp.sqrt(1 - sin2t)
    rs = (ei * ci - et * ct) / (ei * ci + et * ct)
    rp = (et * ci - ei * ct) / (et * ci + ei * ct)
    return (rs * rs + rp * rp) / 2


def ref_schlick(c: float, r0: float) -> Fraction:
    """Schlick F = R0 + (1 − R0)(1 − cos θ)⁵ (§11.1), exactly in rationals."""
    c, r0 = Fraction(c), Fraction(r0)
    return r0 + (1 - r0) * (1 - c) ** 5


def ref_half(wi, wo):
    h = [wi[k] + wo[k] for k in range(3)]
    n = mp.sqrt(dotm(h, h))
    return [x / n for x in h]


def ref_conductor(wi, wo, a: mp.mpf, r0) -> list[mp.mpf]:
    """f = D F_Schlick(ω_h·ω_i) G1(ω_i) G1(ω_o) / (4 cos θ_i cos θ_o) (§10.5), per channel."""
    if wi[2] <= 0 or wo[2] <= 0:
        return [mp.mpf(0)] * 3
    h = ref_half(wi, wo)
    s = ref_d(h[2], a) * ref_g1(wi, h, a) * ref_g1(wo, h, a) / (4 * wi[2] * wo[2])
    hi = dotm(h, wi)
    return [s * (M(r) + (1 - M(r)) * (1 - hi) ** 5) for r in r0]


def ref_fdiff(ci: mp.mpf, co: mp.mpf, kd, ext=ETA_EXT, int_=ETA_INT) -> list[mp.mpf]:
    """Ashikhmin–Shirley f_diff = 28 k_d/(23π) (1 − R_n)(1 − (1 − cos θ_i/2)⁵)(1 − (1 − cos θ_o/2)⁵) (§10.6)."""
    if ci <= 0 or co <= 0:
        return [mp.mpf(0)] * 3
    rn = ((M(ext) - M(int_)) / (M(ext) + M(int_))) ** 2
    s = 28 / (23 * mp.pi) * (1 - rn) * (1 - (1 - ci / 2) ** 5) * (1 - (1 - co / 2) ** 5)
    return [M(k) * s for k in kd]


def ref_substrate(wi, wo, a: mp.mpf, kd, ext=ETA_EXT, int_=ETA_INT) -> list[mp.mpf]:
    """f = f_diff + D F_diel(ω_h·ω_i; η_ext, η_int) G1 G1 / (4 cos θ_i cos θ_o) (§10.6)."""
    if wi[2] <= 0 or wo[2] <= 0:
        return [mp.mpf(0)] * 3
    h = ref_half(wi, wo)
    spec = (ref_d(h[2], a) * ref_fresnel(dotm(h, wi), M(ext), M(int_)) * ref_g1(wi, h, a) * ref_g1(wo, h, a)
            / (4 * wi[2] * wo[2]))
    return [x + spec for x in ref_fdiff(wi[2], wo[2], kd, ext, int_)]


def ref_mf_pdf(wi, wo, a: mp.mpf) -> mp.mpf:
    """Reflection density p(ω_o) = D(ω_h) cos θ_h / (4 |ω_o·ω_h|) (§10.5), 0 for cos θ_i ≤ 0 or ω_i·ω_h ≤ 0."""
    if wi[2] <= 0:
        return mp.mpf(0)
    h = ref_half(wi, wo)
    if dotm(wi, h) <= 0 or h[2] <= 0:
        return mp.mpf(0)
    return ref_d(h[2], a) * h[2] / (4 * abs(dotm(wo, h)))


def ref_substrate_pdf(wi, wo, a: mp.mpf, ext=ETA_EXT, int_=ETA_INT) -> mp.mpf:
    """Mixture p = p_s p_mf + (1 − p_s) cos θ_o/π with p_s = min(F_diel(cos θ_i), 0.95) (§10.6; brdflab's
    documented lobe probability)."""
    if wi[2] <= 0:
        return mp.mpf(0)
    ps = min(ref_fresnel(wi[2], M(ext), M(int_)), mp.mpf("0.95"))
    return ps * ref_mf_pdf(wi, wo, a) + (1 - ps) * max(wo[2], mp.mpf(0)) / mp.pi


# -- comparison helper -----------------------------------------------------------------------------------------
def assert_close(actual, reference, rtol, what: str, floor: float = 1e-300) -> None:
    """|actual − ref| ≤ rtol·|ref| + floor elementwise (``rtol`` a number or one per row)."""
    a = np.asarray(actual, dtype=np.float64).ravel()
    r = np.array([float(x) for x in np.asarray(reference, dtype=object).ravel()])
    assert a.shape == r.shape
    assert np.all(np.isfinite(a)), what
    err = np.abs(a - r)
    rtol = np.asarray(rtol, dtype=np.float64)
    if rtol.ndim:
        rtol = np.repeat(rtol, len(a) // len(rtol))
    bad = err > rtol * np.abs(r) + floor
    assert not bad.any(), (f"{what}: {bad.sum()} of {len(a)} values off; worst rel. error "
                           f"{np.max(err / np.maximum(np.abs(r), floor)):.3g} at index {int(np.argmax(bad))}: "
                           f"{a[np.argmax(bad)]!r} vs {r[np.argmax(bad)]!r}")


def direction(theta_deg: float, phi_deg: float = 0.0) -> np.ndarray:
    t, p = np.radians(theta_deg), np.radians(phi_deg)
    return np.array([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)])


ALPHAS = (1e-4, 1e-3, 0.05, 0.3, 1.0)
THETAS = (0.0, 30.0, 60.0, 85.0, 89.9)
PHIS = (0.0, 90.0, 135.0, 180.0)


def direction_grid(alpha: float) -> tuple[np.ndarray, np.ndarray]:
    """(wi, wo) pairs: the θ_i × θ_o × φ grid, plus directions 0.3α … 3α off the mirror direction (where a
    tiny-α lobe is not negligible) and at grazing incidence."""
    wi, wo = [], []
    for ti in THETAS:
        for to in THETAS:
            for ph in PHIS:
                wi.append(direction(ti))
                wo.append(direction(to, ph))
    for ti in (0.0, 20.0, 45.0, 70.0, 89.0, 89.999):
        for k in (0.0, 0.3, 1.0, 3.0):
            d = np.degrees(k * alpha)
            for dt, dp in ((d, 0.0), (-d, 0.0), (0.0, d / max(np.sin(np.radians(ti)), 1e-3))):
                to = min(max(ti + dt, 0.0), 89.9999)
                wi.append(direction(ti))
                wo.append(direction(to, 180.0 + dp))
    for ti in (90.5, 120.0, 180.0):  # ω_i below the surface: f = 0 and pdf = 0 (one-sided, §10.1)
        for to in (0.0, 45.0, 100.0):
            wi.append(direction(ti))
            wo.append(direction(to, 180.0))
    return np.array(wi), np.array(wo)


# -- D, G1, Fresnel, Schlick -----------------------------------------------------------------------------------
@pytest.mark.parametrize("alpha", ALPHAS)
def test_beckmann_d(alpha):
    # tan θ_h = k·α (the lobe's own scale), fixed angles up to grazing, and normal incidence.
    ks = np.array([0.0, 0.1, 0.5, 1.0, 2.0, 4.0, 8.0, 20.0])
    cos_h = np.concatenate([1.0 / np.sqrt(1.0 + (ks * alpha) ** 2),
                            np.cos(np.radians([10.0, 45.0, 80.0, 89.9, 89.999])), [0.0, -0.3]])
    ref = [ref_d(M(c), M(alpha)) for c in cos_h]
    # exp(−x) amplifies the float64 error of x = tan²θ/α² (absolute ≈ 1e-16/α²) into a relative error of D.
    assert_close(beckmann_d(cos_h, alpha), ref, rtol=max(1e-12, 4e-16 / alpha**2 * 20), what=f"D α={alpha}")
    # The Beckmann warp's density is D·cos θ_h (§11.2).
    w = np.column_stack([np.sqrt(np.maximum(0.0, 1 - cos_h**2)), np.zeros_like(cos_h), cos_h])
    assert_close(warps.square_to_beckmann_pdf(w, alpha), [r * M(c) for r, c in zip(ref, cos_h, strict=True)],
                 rtol=max(1e-12, 4e-16 / alpha**2 * 20), what=f"Beckmann warp pdf α={alpha}")


B_VALUES = (0.05, 0.3, 1.0, 1.5, 1.59, 1.599999, 1.6 * (1 + 1e-9), 1.600001, 1.61, 1.7, 3.0, 50.0)


@pytest.mark.parametrize("alpha", (1e-3, 0.1, 0.5, 1.0))
def test_smith_g1_both_branches(alpha):
    """b = 1/(α tan θ_v) on both sides of 1.6 (the rational branch exceeds 1 there by 6e-5), normal
    incidence (b = ∞), and the χ⁺ test with ω_h behind v."""
    vs, hs = [], []
    for b in B_VALUES:
        t = np.arctan(1.0 / (alpha * b))
        v = np.array([np.sin(t), 0.0, np.cos(t)])
        vs += [v, v, v]
        hs += [np.array([0.0, 0.0, 1.0]), direction(20.0, 30.0), -direction(10.0, 0.0) * [1, 1, -1]]
    vs.append(np.array([0.0, 0.0, 1.0]))
    hs.append(direction(5.0, 0.0))
    vs, hs = np.array(vs), np.array(hs)
    hs /= np.linalg.norm(hs, axis=1)[:, None]
    ref = [ref_g1(vec(v), vec(h), M(alpha)) for v, h in zip(vs, hs, strict=True)]
    assert_close(smith_g1(vs, hs, alpha), ref, rtol=1e-12, what=f"G1 α={alpha}")
    # Both branches and the χ⁺ zero really occur in this grid.
    refs = np.array([float(r) for r in ref])
    assert (refs == 0).any() and (refs == 1).any() and ((refs > 0) & (refs < 1)).any() and (refs > 1).any()


def test_schlick_exact():
    cos = np.array([0.0, 1e-6, 1e-3, 0.1, 0.25, 0.5, 0.75, 0.9, 0.999, 1.0])
    r0 = np.array([[0.04, 0.5, 0.95], [1.0, 0.0, 0.71]])
    for row in r0:
        out = fresnel_schlick(cos, row)
        ref = [[ref_schlick(c, r) for r in row] for c in cos]
        assert_close(out, ref, rtol=1e-14, what=f"Schlick R0={row}", floor=1e-18)
        scale = np.linspace(0.5, 2.0, len(cos))
        assert_close(fresnel_schlick(cos, row, scale), [[x * Fraction(s) for x in r] for r, s in
                                                         zip(ref, scale, strict=True)], 1e-14, "Schlick·scale")
    # Per-point colours (a material family).
    rows = np.tile(r0, (5, 1))
    assert_close(fresnel_schlick(cos, rows), [[ref_schlick(c, r) for r in row] for c, row in
                                              zip(cos, rows, strict=True)], 1e-14, "Schlick per point", 1e-18)


@pytest.mark.parametrize("ext, int_", [(ETA_EXT, ETA_INT), (ETA_INT, ETA_EXT), (1.0, 1.33), (1.5, 1.0),
                                       (1.2, 1.2)])
def test_dielectric_fresnel_incl_total_internal_reflection(ext, int_):
    crit = []
    if int_ < ext:  # from the exterior side: TIR beyond asin(int/ext); just inside and outside the edge
        c = np.sqrt(1 - (int_ / ext) ** 2)
        crit += [c * (1 + 1e-7), c * (1 - 1e-7), c * (1 + 1e-3), c * (1 - 1e-3)]
    if ext < int_:  # from the interior side (negative cosines)
        c = np.sqrt(1 - (ext / int_) ** 2)
        crit += [-c * (1 + 1e-7), -c * (1 - 1e-7), -c * (1 + 1e-3), -c * (1 - 1e-3)]
    cos = np.concatenate([np.cos(np.radians([0.0, 10.0, 30.0, 45.0, 60.0, 80.0, 89.0, 89.9, 89.999])),
                          [0.0, 1e-9], -np.cos(np.radians([0.0, 30.0, 60.0, 85.0, 89.9])), crit])
    ref = [ref_fresnel(M(c), M(ext), M(int_)) for c in cos]
    # Near the critical angle cos θ_t = √(1 − sin²θ_t) amplifies the float64 error of sin²θ_t.
    assert_close(fresnel_dielectric(cos, ext, int_), ref, rtol=1e-6 if crit else 1e-12, what=f"F {ext}/{int_}",
                 floor=1e-15)
    away = np.abs(np.abs(cos) - abs(crit[0])) > 1e-2 if crit else np.ones(len(cos), bool)
    assert_close(fresnel_dielectric(cos[away], ext, int_), [r for r, k in zip(ref, away, strict=True) if k],
                 rtol=1e-12, what=f"F {ext}/{int_} away from the critical angle", floor=1e-15)
    refs = np.array([float(r) for r in ref])
    if ext != int_:
        assert (refs == 1).any()  # total internal reflection is in the grid
    # All-positive cosines take a separate fast branch: it agrees with the reference too.
    pos = cos[cos >= 0]
    assert_close(fresnel_dielectric(pos, ext, int_), [r for r, c in zip(ref, cos, strict=True) if c >= 0],
                 rtol=1e-6 if crit else 1e-12, what="F (positive cosines)", floor=1e-15)


# -- full materials ----------------------------------------------------------------------------------------------
def _tol(alpha: float, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """Relative tolerance of f and pdf per direction pair: the half vector in float64 carries ≈ 1e-16
    absolute error in tan²θ_h, which exp(−tan²θ_h/α²) turns into ≈ 1e-16/α² · (tan²θ_h/α²) relative error
    of D; at grazing angles the cosines and ω_o·ω_h (≈ 1e-5 at 89.999°) lose digits to cancellation."""
    graze = np.minimum(np.abs(wi[:, 2]), np.abs(wo[:, 2]))
    graze = np.minimum(graze, np.abs(np.sum(wo * (wi + wo), axis=1)) / np.linalg.norm(wi + wo, axis=1))
    return max(1e-9, 3e-14 / alpha**2) + 1e-11 / np.maximum(graze, 1e-6)


@pytest.mark.parametrize("alpha", ALPHAS)
def test_roughconductor_f_and_pdf(alpha):
    wi, wo = direction_grid(alpha)
    bsdf = RoughConductor(np.array(R0), alpha)
    ref_f = [ref_conductor(vec(a), vec(b), M(alpha), R0) for a, b in zip(wi, wo, strict=True)]
    f, p = bsdf.eval_pdf(wi, wo)
    assert_close(f, ref_f, _tol(alpha, wi, wo), f"roughconductor f α={alpha}")
    assert_close(bsdf.eval(wi, wo), ref_f, _tol(alpha, wi, wo), f"roughconductor eval α={alpha}")
    ref_p = [ref_mf_pdf(vec(a), vec(b), M(alpha)) for a, b in zip(wi, wo, strict=True)]
    assert_close(p, ref_p, _tol(alpha, wi, wo), f"roughconductor pdf α={alpha}")
    assert_close(bsdf.pdf(wi, wo), ref_p, _tol(alpha, wi, wo), f"roughconductor pdf() α={alpha}")
    assert np.count_nonzero(f[:, 0] > 1e-3) > 10  # the grid does probe the lobe


@pytest.mark.parametrize("alpha", ALPHAS)
@pytest.mark.parametrize("ext, int_", [(ETA_EXT, ETA_INT), (1.5, 1.0)])
def test_roughsubstrate_f_and_pdf(alpha, ext, int_):
    wi, wo = direction_grid(alpha)
    bsdf = RoughSubstrate(np.array(KD), alpha, intIOR=int_, extIOR=ext)
    ref_f = [ref_substrate(vec(a), vec(b), M(alpha), KD, ext, int_) for a, b in zip(wi, wo, strict=True)]
    f, p = bsdf.eval_pdf(wi, wo)
    assert_close(f, ref_f, _tol(alpha, wi, wo), f"roughsubstrate f α={alpha} η={ext}/{int_}")
    assert_close(bsdf.eval(wi, wo), ref_f, _tol(alpha, wi, wo), "roughsubstrate eval")
    ref_p = [ref_substrate_pdf(vec(a), vec(b), M(alpha), ext, int_) for a, b in zip(wi, wo, strict=True)]
    assert_close(p, ref_p, _tol(alpha, wi, wo), f"roughsubstrate pdf α={alpha} η={ext}/{int_}")
    assert_close(bsdf.pdf(wi, wo), ref_p, _tol(alpha, wi, wo), "roughsubstrate pdf()")


@pytest.mark.parametrize("ext, int_", [(ETA_EXT, ETA_INT), (1.0, 1.33), (1.5, 1.0)])
def test_substrate_diffuse_lobe(ext, int_):
    """f_diff alone (lobe="diffuse") with its R_n and the two (1 − cos/2)⁵ factors, at all angle pairs."""
    th = np.array([0.0, 1.0, 20.0, 45.0, 70.0, 85.0, 89.9, 89.999, 90.0, 95.0])
    ti, to = np.meshgrid(th, th)
    wi = np.array([direction(t) for t in ti.ravel()])
    wo = np.array([direction(t, 77.0) for t in to.ravel()])
    bsdf = RoughSubstrate(np.array(KD), 0.3, intIOR=int_, extIOR=ext, lobe="diffuse")
    ref = [ref_fdiff(M(a[2]), M(b[2]), KD, ext, int_) for a, b in zip(wi, wo, strict=True)]
    # 1 − (1 − cos/2)⁵ loses digits for cos → 0 (≈ 1e-16/cos relative); cos 90° = 6e-17 gives 0 vs 1e-17.
    tol = 1e-12 + 1e-15 / np.maximum(np.minimum(np.abs(wi[:, 2]), np.abs(wo[:, 2])), 1e-6)
    assert_close(bsdf.eval(wi, wo), ref, tol, f"f_diff {ext}/{int_}", floor=1e-15)
    # The specular lobe alone is the total minus f_diff.
    spec = RoughSubstrate(np.array(KD), 0.3, intIOR=int_, extIOR=ext, lobe="specular")
    full = RoughSubstrate(np.array(KD), 0.3, intIOR=int_, extIOR=ext)
    np.testing.assert_allclose(spec.eval(wi, wo) + bsdf.eval(wi, wo), full.eval(wi, wo), rtol=1e-13, atol=1e-300)


def test_diffuse_f_and_pdf():
    wi, wo = direction_grid(0.1)
    wo = np.concatenate([wo, -wo])
    wi = np.concatenate([wi, wi])
    alb = (0.3, 0.6, 0.9)
    b = Diffuse(np.array(alb))
    ref = [[M(x) / mp.pi if (a[2] > 0 and c[2] > 0) else 0 for x in alb] for a, c in zip(wi, wo, strict=True)]
    assert_close(b.eval(wi, wo), ref, 1e-15, "diffuse f")
    ref_p = [max(M(c[2]), 0) / mp.pi if a[2] > 0 else 0 for a, c in zip(wi, wo, strict=True)]
    assert_close(b.pdf(wi, wo), ref_p, 1e-15, "diffuse pdf")


# -- warps ------------------------------------------------------------------------------------------------------
def test_warp_mappings():
    """Each warp maps (ξ1, ξ2) by the formula of §11.2."""
    g = np.array([0.0, 1e-6, 0.1, 0.3, 0.5, 0.7, 0.9, 0.999999])
    u = np.array(np.meshgrid(g, g)).reshape(2, -1).T
    two_pi = 2 * mp.pi
    cases = {
        "disk": (warps.square_to_uniform_disk(u),
                 [[mp.sqrt(M(a)) * mp.cos(two_pi * M(b)), mp.sqrt(M(a)) * mp.sin(two_pi * M(b))] for a, b in u]),
        "triangle": (warps.square_to_uniform_triangle(u),
                     [[1 - M(a), 1 - M(b)] if a + b > 1 else [M(a), M(b)] for a, b in u]),
        "sphere": (warps.square_to_uniform_sphere(u),
                   [[mp.sqrt(1 - (1 - 2 * M(b)) ** 2) * mp.cos(two_pi * M(a)),
                     mp.sqrt(1 - (1 - 2 * M(b)) ** 2) * mp.sin(two_pi * M(a)), 1 - 2 * M(b)] for a, b in u]),
        "hemisphere": (warps.square_to_uniform_hemisphere(u),
                       [[mp.sqrt(1 - (1 - M(b)) ** 2) * mp.cos(two_pi * M(a)),
                         mp.sqrt(1 - (1 - M(b)) ** 2) * mp.sin(two_pi * M(a)), 1 - M(b)] for a, b in u]),
        "cosine": (warps.square_to_cosine_hemisphere(u),
                   [[mp.sqrt(M(a)) * mp.cos(two_pi * M(b)), mp.sqrt(M(a)) * mp.sin(two_pi * M(b)),
                     mp.sqrt(1 - M(a))] for a, b in u]),
    }
    for name, (out, ref) in cases.items():
        # Absolute tolerance: components near 0 are sin/cos of exact-ish angles.
        r = np.array([[float(x) for x in row] for row in ref])
        # sqrt(1 − z²) from the float64 z loses digits near the pole (≈ 1e-16/(1 − z) relative).
        np.testing.assert_allclose(out, r, rtol=1e-10, atol=2e-15, err_msg=name)
    for alpha in (1e-4, 0.05, 0.5, 1.0):
        out = warps.square_to_beckmann(u, alpha)
        ref = []
        for a, b in u:
            t2 = -M(alpha) ** 2 * mp.log(1 - M(a))
            ct = 1 / mp.sqrt(1 + t2)
            st = mp.sqrt(t2) * ct
            ref.append([st * mp.cos(two_pi * M(b)), st * mp.sin(two_pi * M(b)), ct])
        np.testing.assert_allclose(out, np.array([[float(x) for x in row] for row in ref]), rtol=1e-10, atol=2e-15,
                                   err_msg=f"beckmann α={alpha}")


def test_warp_densities():
    rng = np.random.default_rng(41)
    w = rng.normal(size=(200, 3))
    w /= np.linalg.norm(w, axis=1)[:, None]
    z = w[:, 2]
    np.testing.assert_array_equal(warps.square_to_uniform_sphere_pdf(w), np.full(200, float(1 / (4 * mp.pi))))
    np.testing.assert_array_equal(warps.square_to_uniform_hemisphere_pdf(w), np.where(z >= 0, float(1 / (2 * mp.pi)),
                                                                                      0.0))
    np.testing.assert_allclose(warps.square_to_cosine_hemisphere_pdf(w), np.where(z >= 0, z / np.pi, 0.0),
                               rtol=1e-15)
    p = rng.uniform(-1.2, 1.2, (400, 2))
    inside = (p ** 2).sum(axis=1) <= 1
    np.testing.assert_array_equal(warps.square_to_uniform_disk_pdf(p), np.where(inside, float(1 / mp.pi), 0.0))
    b = rng.uniform(-0.2, 1.2, (400, 2))
    tri = (b[:, 0] >= 0) & (b[:, 1] >= 0) & (b.sum(axis=1) <= 1)
    np.testing.assert_array_equal(warps.square_to_uniform_triangle_pdf(b), np.where(tri, 2.0, 0.0))
    # Boundary points count as inside.
    edge = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.5, 0.5]])
    np.testing.assert_array_equal(warps.square_to_uniform_triangle_pdf(edge), 2.0)
    np.testing.assert_array_equal(warps.square_to_uniform_disk_pdf(np.array([[1.0, 0.0], [0.0, -1.0]])),
                                  float(1 / mp.pi))
    np.testing.assert_array_equal(warps.square_to_uniform_hemisphere_pdf(np.array([[1.0, 0.0, 0.0]])),
                                  float(1 / (2 * mp.pi)))


# -- pdf integrals by quadrature --------------------------------------------------------------------------------
def _sphere_integral(pdf, axis: np.ndarray, alpha: float, order: int = 48) -> float:
    """∫ pdf dω over the sphere in polar coordinates about ``axis``: θ′ cut geometrically from 10⁻³α up
    (the lobe's width scales with α) and Gauss–Legendre in each piece and in φ′."""
    a = axis / np.linalg.norm(axis)
    helper = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    s = np.cross(helper, a)
    s /= np.linalg.norm(s)
    t = np.cross(a, s)
    cuts = np.concatenate([[0.0], np.geomspace(1e-3 * min(alpha, 1.0), np.pi, 40)])
    x, wx = np.polynomial.legendre.leggauss(order)
    phi = (np.arange(2 * order) + 0.5) * np.pi / order  # periodic: the midpoint rule is spectrally accurate
    total = 0.0
    for lo, hi in zip(cuts[:-1], cuts[1:], strict=True):
        th = 0.5 * (hi - lo) * x + 0.5 * (hi + lo)
        T, P = np.meshgrid(th, phi, indexing="ij")
        st = np.sin(T)
        d = (st * np.cos(P))[..., None] * s + (st * np.sin(P))[..., None] * t + np.cos(T)[..., None] * a
        vals = pdf(d.reshape(-1, 3)).reshape(T.shape) * st
        total += float((vals * wx[:, None]).sum() * 0.5 * (hi - lo) * (np.pi / order))
    return total


def _upper_mass(alpha: float, theta_i: float) -> float:
    """∫ D cos θ_h dω_h over the microfacets that reflect ω_i above the surface (ω_i·ω_h > 0 and
    (2(ω_i·ω_h)ω_h − ω_i)_z > 0), by quadrature over ω_h: what ∫ p(ω_o) dω_o over the upper hemisphere
    must give if p carries the right Jacobian."""
    wi = direction(theta_i)

    def dens(h):
        c = h[:, 2]
        hi = h @ wi
        up = 2 * hi * c - wi[2] > 0
        with np.errstate(all="ignore"):
            t2 = (1 - c * c) / (c * c)
            d = np.where(c > 0, np.exp(-t2 / alpha**2) / (np.pi * alpha**2 * c**4) * c, 0.0)
        return np.where((hi > 0) & up, np.nan_to_num(d), 0.0)

    return _sphere_integral(dens, np.array([0.0, 0.0, 1.0]), alpha)


@pytest.mark.parametrize("alpha, theta", [(1e-3, 0.0), (1e-3, 70.0), (0.05, 45.0), (0.3, 0.0), (0.3, 80.0),
                                          (1.0, 60.0)])
def test_pdf_integrates_to_one(alpha, theta):
    """∫ p(ω_o) dω_o over the upper hemisphere (quadrature in ω_o) equals the Beckmann mass of the microfacets
    that send ω_i there (quadrature in ω_h, no Jacobian involved); 1 for the diffuse pdf."""
    wi1 = direction(theta)
    mirror = np.array([-wi1[0], 0.0, wi1[2]])
    upper = _upper_mass(alpha, theta)
    ps = min(float(ref_fresnel(M(wi1[2]), M(ETA_EXT), M(ETA_INT))), 0.95)
    for bsdf, axis, expect in (
        (RoughConductor(0.5, alpha), mirror, upper),
        (RoughSubstrate(0.5, alpha), mirror, ps * upper + (1.0 - ps)),
        (Diffuse(0.5), np.array([0.0, 0.0, 1.0]), 1.0),
    ):
        def pdf(w, b=bsdf):
            return np.where(w[:, 2] > 0, b.pdf(np.tile(wi1, (len(w), 1)), w), 0.0)

        total = _sphere_integral(pdf, axis, alpha)
        assert total == pytest.approx(expect, abs=1e-3), (type(bsdf).__name__, alpha, theta, total, expect)
    assert upper > 0.5


@pytest.mark.filterwarnings("ignore:.*no emitter")
def test_scene_file_defaults(tmp_path):
    """Parameters omitted in the scene file take the spec's defaults (§9.2, §10.2, §10.5, §10.6), as colours
    of 3."""
    from brdflab.scene.loader import load_scene
    from tests.conftest import CAMERA, QUAD_OBJ, write_scene

    body = '<integrator type="direct_ems"/>' + CAMERA + '<emitter type="pointlight"/>' + "".join(
        f'<mesh type="obj"><string name="filename" value="q.obj"/><bsdf type="{t}"/></mesh>'
        for t in ("diffuse", "roughconductor", "roughsubstrate"))
    s = load_scene(write_scene(tmp_path, body, {"q.obj": QUAD_OBJ}))
    (point,) = s.emitters  # §9.2: position (0, 100, 0), intensity (1, 1, 1)
    np.testing.assert_array_equal(point.position, [0.0, 100.0, 0.0])
    np.testing.assert_array_equal(point.intensity, np.ones(3))
    diffuse, conductor, substrate = s.bsdfs
    np.testing.assert_array_equal(diffuse.albedo.value, np.full(3, 0.5))
    np.testing.assert_array_equal(conductor.R0.value, np.full(3, 0.5))
    np.testing.assert_array_equal(substrate.kd.value, np.full(3, 0.5))
    assert [conductor.alpha_value, substrate.alpha_value] == pytest.approx([0.1, 0.1], rel=1e-14)
    assert (substrate.int_ior, substrate.ext_ior) == (ETA_INT, ETA_EXT)
    wi, wo = np.array([direction(30.0)]), np.array([direction(40.0, 180.0)])
    for b in s.bsdfs:
        assert b.eval(wi, wo).shape == (1, 3)
    # The Python constructors have the same defaults as the scene files.
    api = (Diffuse(), RoughConductor(), RoughSubstrate())
    np.testing.assert_array_equal(api[0].albedo.value, np.full(3, 0.5))
    np.testing.assert_array_equal(api[1].R0.value, np.full(3, 0.5))
    np.testing.assert_array_equal(api[2].kd.value, np.full(3, 0.5))
    assert [api[1].alpha_value, api[2].alpha_value] == pytest.approx([0.1, 0.1], rel=1e-14)
    assert (api[2].int_ior, api[2].ext_ior) == (ETA_INT, ETA_EXT)


def test_sample_weight_guards():
    """weight = f·cos θ_o/pdf (spec §10.1), 0 where the pdf is 0, cos θ_o ≤ 0 or the quotient overflows."""
    from brdflab.bsdf.base import cos_weight

    f = np.full((4, 3), 0.5)
    wo = np.array([direction(60.0), direction(60.0), direction(100.0), direction(60.0)])
    pdf = np.array([0.25, 0.0, 0.25, 1e-310])
    w = cos_weight(f, wo, pdf)
    np.testing.assert_allclose(w[0], 0.5 * np.cos(np.radians(60.0)) / 0.25, rtol=1e-15)
    np.testing.assert_array_equal(w[1:], 0.0)


def test_beckmann_warp_closed_end_is_the_horizon():
    """ξ1 = 1 (tan²θ = ∞) maps to the unit horizon direction at φ = 2πξ2, not beyond it."""
    w = warps.square_to_beckmann(np.array([[1.0, 0.0], [1.0, 0.25]]), 0.3)
    np.testing.assert_allclose(w, [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], atol=1e-15)


def test_mis_weights_by_hand():
    """Balance w = p/(p+q) and power w = p²/(p²+q²) heuristics (Veach 1997, eq. 9.10/9.13), with limits.

    A zero density gets weight 0; an infinite density (a pdf that overflowed) gets weight 1 and its
    partner 0, so the two weights of a sample pair still sum to one.
    """
    from brdflab.integrator.direct_mis import mis_weight

    p = np.array([1.0, 3.0, 0.0, np.inf, 2.0])
    q = np.array([1.0, 1.0, 5.0, 2.0, np.inf])
    np.testing.assert_array_equal(mis_weight(p, q, 1), [0.5, 0.75, 0.0, 1.0, 0.0])
    np.testing.assert_array_equal(mis_weight(p, q, 2), [0.5, 0.9, 0.0, 1.0, 0.0])
    np.testing.assert_array_equal(mis_weight(q, p, 1) + mis_weight(p, q, 1), [1.0, 1.0, 1.0, 1.0, 1.0])
    from brdflab.integrator.direct_mis import DirectMIS

    assert (DirectMIS("balance").beta, DirectMIS("power").beta, DirectMIS().beta) == (1.0, 2.0, 1.0)


def _ref_beckmann_normal(a, b, alpha) -> list[mp.mpf]:
    t2 = -M(alpha) ** 2 * mp.log(1 - M(a))
    ct = 1 / mp.sqrt(1 + t2)
    st = mp.sqrt(t2) * ct
    return [st * mp.cos(2 * mp.pi * M(b)), st * mp.sin(2 * mp.pi * M(b)), ct]


def _ref_reflect(wi, h) -> list[mp.mpf]:
    d = dotm(wi, h)
    return [2 * d * hc - wc for hc, wc in zip(h, wi, strict=True)]


def test_sampled_directions_by_hand():
    """sample() maps (ξ1, ξ2, ξ3) as the spec says: the conductor reflects ω_i about a Beckmann normal
    (ω_o = 2(ω_i·ω_h)ω_h − ω_i); the substrate does so when ξ3 < p_s = min(F(cos θ_i), 0.95), else it
    draws ω_o cosine-weighted — checked against mpmath for several ω_i (also off the φ = 0 plane)."""
    us = [(0.1, 0.2, 0.01), (0.5, 0.7, 0.02), (0.9, 0.35, 0.5), (0.3, 0.9, 0.99)]
    u = np.array(us)
    for alpha in (0.05, 0.3):
        for theta, phi in ((0.0, 0.0), (40.0, 30.0), (75.0, 200.0)):
            wi = np.tile(direction(theta, phi), (len(us), 1))
            wim = vec(wi[0])
            conductor = RoughConductor(R0=0.9, alpha=alpha).sample(wi, u)
            substrate = RoughSubstrate(kd=0.5, alpha=alpha).sample(wi, u)
            ps = min(ref_fresnel(wim[2], M(ETA_EXT), M(ETA_INT)), mp.mpf("0.95"))
            for k, (a, b, c) in enumerate(us):
                spec = _ref_reflect(wim, _ref_beckmann_normal(a, b, alpha))
                cos = [mp.sqrt(M(a)) * mp.cos(2 * mp.pi * M(b)), mp.sqrt(M(a)) * mp.sin(2 * mp.pi * M(b)),
                       mp.sqrt(1 - M(a))]
                np.testing.assert_allclose(conductor.wo[k], [float(x) for x in spec], rtol=1e-9, atol=1e-13)
                want = spec if M(c) < ps else cos
                np.testing.assert_allclose(substrate.wo[k], [float(x) for x in want], rtol=1e-9, atol=1e-13,
                                           err_msg=f"substrate α={alpha} θ={theta} u={us[k]}")


def test_reflection_pdf_computes_d_itself():
    """p(ω_o) = D(ω_h) cos θ_h / (4 |ω_o·ω_h|) (spec §10.5) when the caller passes no D(ω_h)."""
    from brdflab.bsdf.microfacet import half_vector, reflection_pdf

    for alpha in (0.05, 0.4):
        wi, wo = direction_grid(alpha)
        wh, _ = half_vector(wi, wo)
        got = reflection_pdf(wh, wo, alpha)
        want = []
        for h, o in zip(wh, wo, strict=True):
            hm, om = [M(c) for c in h], [M(c) for c in o]
            want.append(float(ref_d(hm[2], M(alpha)) * hm[2] / (4 * abs(dotm(om, hm)))) if h[2] > 0 else 0.0)
        assert np.count_nonzero(want) > 10
        assert_close(got, np.array(want), 1e-9, f"reflection_pdf α={alpha}")


def test_power_selection_probabilities_by_hand():
    """Power-proportional selection (spec §8, brdflab's radiometric form): Φ = π·lum(L_e)·A for an area
    light, 4π·lum(I) for a point light, 4π·lum(L) for a constant environment, lum = 0.212671 R + 0.715160 G
    + 0.072169 B; the selection pmf is Φ_e / Σ Φ (computed here in exact fractions)."""
    from brdflab.scene.loader import load_scene
    from tests.conftest import ROOT

    s = load_scene(ROOT / "scenes" / "lights" / "mixed_lights_mis.xml")
    s.set_emitter_selection("power")
    lum = [Fraction("0.212671"), Fraction("0.715160"), Fraction("0.072169")]

    def lum_of(rgb):
        return sum(w * Fraction(c) for w, c in zip(lum, rgb, strict=True))

    v = [[Fraction(c) for c in line.split()[1:4]]
         for line in (ROOT / "scenes/lights/meshes/triangle.obj").read_text().splitlines() if line.startswith("v ")]
    e1 = [b - a for a, b in zip(v[0], v[1], strict=True)]
    e2 = [b - a for a, b in zip(v[0], v[2], strict=True)]
    cross = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]]
    area = mp.sqrt(mp.mpf(sum(c * c for c in cross))) / 2
    power = {"AreaEmitter": mp.pi * mp.mpf(lum_of(["9", "8", "7"])) * area,
             "PointLight": 4 * mp.pi * mp.mpf(lum_of(["3", "3", "2.5"])),
             "EnvironmentEmitter": 4 * mp.pi * mp.mpf(lum_of(["0.25", "0.3", "0.4"]))}
    kinds = [type(e).__name__ for e in s.emitters]
    assert sorted(kinds) == sorted(power)
    total = sum(power.values())
    np.testing.assert_allclose(s.emitter_pmf, [float(power[k] / total) for k in kinds], rtol=1e-12)
    for e, k in zip(s.emitters, kinds, strict=True):
        np.testing.assert_allclose(e.power(), float(power[k]), rtol=1e-12, err_msg=k)


def test_point_light_sample_by_hand():
    """§9.2: ω = (p − x)/‖p − x‖, L = I/‖p − x‖², pdf 1; a point at the light itself gets nothing (no 0/0)."""
    from brdflab.emitter.point import PointLight

    light = PointLight(np.array([0.5, 2.0, -1.0]), np.array([3.0, 2.0, 1.0]))
    x = np.array([[0.5, 0.0, -1.0], [1.5, 2.0, -1.0], [0.5, 2.0, -1.0], [0.0, 0.5, 0.0]])
    r = light.sample(x, np.zeros((4, 3)))
    d = light.position - x
    r2 = np.sum(d * d, axis=1)
    np.testing.assert_allclose(r.radiance[[0, 1, 3]], light.intensity / r2[[0, 1, 3], None], rtol=1e-15)
    np.testing.assert_array_equal(r.radiance[2], 0.0)
    np.testing.assert_allclose(r.wi[[0, 1, 3]], d[[0, 1, 3]] / np.sqrt(r2[[0, 1, 3], None]), rtol=1e-15)
    np.testing.assert_allclose(r.dist, np.sqrt(r2), rtol=1e-15)
    np.testing.assert_array_equal(r.pdf, 1.0)


def test_power_of_scaled_and_image_lights_by_hand(tmp_path):
    """Φ of an area light with ``scale`` (π·lum(scale·L_e)·A) and of an image environment (4π·lum of the
    mean texel × radiance/255, spec §9.3's scaling) — the selection weights of the power heuristic."""
    from brdflab.emitter.environment import EnvironmentEmitter
    from brdflab.scene.loader import load_scene
    from tests.conftest import CAMERA, QUAD_OBJ, write_scene

    lum = np.array([0.212671, 0.715160, 0.072169])
    body = (f'<integrator type="direct_ems"/>{CAMERA}<mesh type="obj"><string name="filename" value="q.obj"/>'
            '<emitter type="area"><color name="radiance" value="1,2,3"/><float name="scale" value="4"/></emitter>'
            '</mesh>')
    (light,) = load_scene(write_scene(tmp_path, body, {"q.obj": QUAD_OBJ})).emitters
    np.testing.assert_allclose(light.power(), np.pi * 4 * (lum @ [1.0, 2.0, 3.0]) * 4.0, rtol=1e-14)  # A = 2 × 2
    rng = np.random.default_rng(8)
    img = (rng.random((4, 6, 3)) * 255).astype(np.float32)
    env = EnvironmentEmitter(img, np.array([2.0, 1.0, 0.5]))
    want = 4 * np.pi * float(lum @ (img.astype(np.float64).mean(axis=(0, 1)) * [2.0, 1.0, 0.5] / 255))
    np.testing.assert_allclose(env.power(), want, rtol=1e-12)
