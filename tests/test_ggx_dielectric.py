"""roughdielectric's and roughsubstrate's coat options: GGX, anisotropic α, visible normals (issue 45).

Golden values are independent of brdflab's code: Walter et al.'s f with anisotropic GGX (Heitz 2014's polar
form) written out below in long double (x87 80-bit, NumPy's ``longdouble``), and its reflection + transmission
integral ∫ f |cos θ_o| dω_o, computed once in long double by Gauss–Legendre quadrature (128 θ panels × 96 φ panels
of 24 nodes; 64 × 16 nodes gave the same value to 1e-6: the constants below). The samplers pass the chi-square on
the whole sphere at random azimuths, from outside and inside; the negative controls (visible-normal pdf without
G1(ω_i), α_u/α_v swapped in the sampler only) must fail it; the course's defaults keep their code path bit for
bit (against the formulas of the course's model written out below).
"""

from __future__ import annotations

import numpy as np
import pytest

import brdflab as bl
from brdflab import RoughDielectric, RoughSubstrate, kernels
from brdflab.bsdf import microfacet as mf
from brdflab.bsdf.base import abs_cos_weight, cos_weight
from brdflab.bsdf.fresnel import fresnel_dielectric, pow5
from brdflab.errors import BrdflabError
from brdflab.judges.material import transmission_controls as tc
from brdflab.judges.material.chi2 import SIGNIFICANCE, sidak
from brdflab.math import warps
from tests.conftest import sphere_scene
from tests.test_ggx_conductor import CONFIGS as CONDUCTOR_CONFIGS

L = np.longdouble
#: The conductor's configurations without its Fresnel options: GGX and Beckmann, visible normals or not, anisotropic.
CONFIGS = {k: v for k, v in CONDUCTOR_CONFIGS.items() if "eta" not in v}
#: One family-wise significance of 0.01 for the chi-square tests of correct samplers below (Šidák).
THRESHOLD = sidak(SIGNIFICANCE, 5 * len(CONFIGS))
#: ∫ f |cos θ_o| dω_o of RoughDielectric(intIOR=1.5, extIOR=1, ggx, α_u = 0.15, α_v = 0.45) at ω_i of θ, φ = 0.5 rad
#: (module docstring; ±2e-6).
GOLDEN_ALBEDO = {40.0: 0.4550918, 140.0: 1.3636159}


def _unit(rng, n):
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1)[:, None]


def _wi(theta_deg, phi=0.5):
    t = np.radians(theta_deg)
    return np.array([[np.sin(t) * np.cos(phi), np.sin(t) * np.sin(phi), np.cos(t)]])


# -- the independent reference ---------------------------------------------------------------------------------------
def ref_ggx_dielectric(wi, wo, ax, ay, ext, int_):
    """Walter et al. 2007 eqs. 20–21 (radiance form) with anisotropic GGX D and its exact G1 in the polar form of
    Heitz 2014 (eqs. 85–86), in long double, two-sided (media swapped and z flipped for ω_i inside)."""
    wi, wo = np.asarray(wi, L).copy(), np.asarray(wo, L).copy()
    ax, ay, ext, int_ = L(ax), L(ay), L(ext), L(int_)
    inside = wi[:, 2] < 0
    ei, et = np.where(inside, int_, ext), np.where(inside, ext, int_)
    wi[inside, 2] *= -1
    wo[inside, 2] *= -1
    refl = wo[:, 2] > 0
    h = np.where(refl[:, None], wi + wo, -(ei[:, None] * wi + et[:, None] * wo))
    h = h / (np.sqrt((h * h).sum(1)) * np.where(h[:, 2] > 0, 1, -1))[:, None]
    ih, oh = (wi * h).sum(1), (wo * h).sum(1)
    s2 = (ei / et) ** 2 * (1 - ih * ih)
    ct = np.sqrt(np.maximum(L(0), 1 - s2))
    rs = (ei * ih - et * ct) / (ei * ih + et * ct)
    rp = (et * ih - ei * ct) / (et * ih + ei * ct)
    fres = np.where(s2 >= 1, L(1), (rs * rs + rp * rp) / 2)

    def polar(v):  # tan²θ, cos²φ
        r2 = v[:, 0] ** 2 + v[:, 1] ** 2
        return r2 / v[:, 2] ** 2, v[:, 0] ** 2 / (r2 + L(1e-300))

    tan2, c2 = polar(h)
    d = 1 / (np.pi * ax * ay * h[:, 2] ** 4 * (1 + tan2 * (c2 / ax ** 2 + (1 - c2) / ay ** 2)) ** 2)

    def g1(v, vh):
        t2, c2v = polar(v)
        return np.where(vh / v[:, 2] > 0, 2 / (1 + np.sqrt(1 + (c2v * ax ** 2 + (1 - c2v) * ay ** 2) * t2)), L(0))

    g = g1(wi, ih) * g1(wo, oh)
    fr = fres * d * g / (4 * wi[:, 2] * wo[:, 2])
    ft = np.abs(ih * oh) * ei ** 2 * (1 - fres) * d * g / (np.abs(wi[:, 2] * wo[:, 2]) * (ei * ih + et * oh) ** 2)
    return np.where(refl, fr, np.where((ih > 0) & (oh < 0), ft, L(0)))


def test_ggx_dielectric_against_the_long_double_reference():
    """f on random pairs of the sphere (both sides, reflection and transmission) and near the lobes, 1e-9."""
    rng = np.random.default_rng(4801)
    m = RoughDielectric(0.3, 1.5, 1.0, distribution="ggx", alpha_u=0.15, alpha_v=0.45)
    wi, wo = _unit(rng, 2000), _unit(rng, 2000)
    s = m.sample(wi, rng.random((2000, 3)))
    wi, wo = np.concatenate([wi, wi]), np.concatenate([wo, s.wo])
    got, ref = m.eval(wi, wo)[:, 0], ref_ggx_dielectric(wi, wo, 0.15, 0.45, 1.0, 1.5)
    assert (ref > 0).sum() > 2500 and ((ref > 0) & (wi[:, 2] * wo[:, 2] < 0)).sum() > 800
    np.testing.assert_allclose(got, ref.astype(np.float64), rtol=1e-9, atol=1e-300)


def _albedo(f, wi, n=16, panels=32, phi_panels=16):
    """∫ f |cos θ_o| dω_o by Gauss–Legendre: ``panels`` per hemisphere in θ, ``phi_panels`` in φ."""
    x, w = np.polynomial.legendre.leggauss(n)

    def nodes(edges):
        lo, hi = edges[:-1, None], edges[1:, None]
        return (lo + (hi - lo) * (x + 1) / 2).ravel(), (w * (hi - lo) / 2).ravel()

    th, wt = nodes(np.linspace(0, np.pi, 2 * panels + 1))
    ph, wp = nodes(np.linspace(0, 2 * np.pi, phi_panels + 1))
    t, p = np.meshgrid(th, ph, indexing="ij")
    weight = np.outer(wt, wp) * np.abs(np.cos(t)) * np.sin(t)
    wo = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1).reshape(-1, 3)
    return float(np.sum(f(np.repeat(wi, len(wo), axis=0), wo) * weight.ravel()))


@pytest.mark.parametrize("theta", [40.0, 140.0])
def test_reflection_plus_transmission_golden_integral(theta):
    """brdflab's f integrated (quadrature, 1e-4) and its sampler's mean weight (10⁶ samples, within 4.5 standard
    errors) against the long-double golden ∫ f |cos θ_o| dω_o, from outside and from inside."""
    wi = _wi(theta)
    for vis in (True, False):
        m = RoughDielectric(0.3, 1.5, 1.0, distribution="ggx", alpha_u=0.15, alpha_v=0.45, sample_visible=vis)
        if vis:
            assert _albedo(lambda a, b, m=m: m.eval(a, b)[:, 0], wi) == pytest.approx(GOLDEN_ALBEDO[theta], rel=1e-4)
        n = 1_000_000
        w = m.sample(np.repeat(wi, n, axis=0), np.random.default_rng(int(theta) + vis).random((n, 3))).weight[:, 0]
        assert abs(w.mean() - GOLDEN_ALBEDO[theta]) < 4.5 * w.std() / np.sqrt(n), (vis, w.mean())


# -- the judges -----------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", list(CONFIGS))
@pytest.mark.parametrize("theta", [30.0, 80.0, 140.0])
def test_dielectric_samplers_pass_chi_square(name, theta):
    r = bl.chi2_test(RoughDielectric(0.3, 1.5, 1.0, **CONFIGS[name]), theta=theta, samples=60_000,
                     threshold=THRESHOLD)
    assert r.passed, r.message


@pytest.mark.parametrize("name", list(CONFIGS))
def test_substrate_coats_pass_chi_square(name):
    r = bl.chi2_test(RoughSubstrate(0.5, 0.3, **CONFIGS[name]), theta=60.0, samples=60_000, threshold=THRESHOLD)
    assert r.passed, r.message
    spec = RoughSubstrate(0.5, 0.3, lobe="specular", **CONFIGS[name])
    assert bl.chi2_test(spec, theta=30.0, samples=60_000, threshold=THRESHOLD).passed


@pytest.mark.parametrize("cls,theta", [(tc.VndfWithoutG1RoughDielectric, 60.0),
                                       (tc.VndfWithoutG1RoughDielectric, 120.0),
                                       (tc.SwappedAlphaRoughDielectric, 30.0), (tc.SwappedAlphaRoughDielectric, 150.0)])
def test_dielectric_negative_controls_fail_chi_square(cls, theta):
    r = bl.chi2_test(cls(0.3, 1.5, 1.0), theta=theta, samples=60_000, threshold=THRESHOLD)
    assert not r.passed, (cls.__name__, theta)


def test_consistency_and_furnace():
    m = RoughDielectric(0.3, 1.5, 1.0, distribution="ggx", alpha_u=0.1, alpha_v=0.4)
    for theta in (50.0, 130.0):
        assert bl.consistency_test(m, theta=theta, samples=40_000).passed
    assert bl.furnace_test(m, thetas=(0.0, 60.0), samples=20_000).passed
    s = RoughSubstrate(1.0, 0.3, distribution="beckmann", alpha_u=0.1, alpha_v=0.4, sample_visible=True)
    assert bl.consistency_test(s, theta=50.0, samples=40_000).passed
    assert bl.furnace_test(s, thetas=(0.0, 60.0), samples=20_000).passed


def test_the_flip_keeps_the_anisotropy():
    """From inside, f is the outside model (media exchanged) of the directions mirrored in z: the flip leaves
    x and y, so α_u stays along x (exchanging α_u and α_v changes the values)."""
    rng = np.random.default_rng(4802)
    wi, wo = _unit(rng, 3000), _unit(rng, 3000)
    wi[:, 2] = -np.abs(wi[:, 2])
    m = RoughDielectric(0.3, 1.5, 1.0, distribution="ggx", alpha_u=0.1, alpha_v=0.4)
    out = RoughDielectric(0.3, 1.0, 1.5, distribution="ggx", alpha_u=0.1, alpha_v=0.4)
    z = np.array([1.0, 1.0, -1.0])
    np.testing.assert_array_equal(m.eval(wi, wo), out.eval(wi * z, wo * z))
    np.testing.assert_array_equal(m.pdf(wi, wo), out.pdf(wi * z, wo * z))
    swapped = RoughDielectric(0.3, 1.5, 1.0, distribution="ggx", alpha_u=0.4, alpha_v=0.1)
    assert np.max(np.abs(swapped.eval(wi, wo) - m.eval(wi, wo))) > 0.1


# -- the course's model, written out (the defaults must keep it to the bit) -------------------------------------------
def _course_dielectric(wi, wo, a, ext, int_):
    n = len(wi)
    s = np.where(wi[:, 2] >= 0, 1.0, -1.0)
    eta_i, eta_t = np.where(s > 0, ext, int_), np.where(s > 0, int_, ext)
    flip = np.stack([np.ones(n), np.ones(n), s], axis=1)
    wi_f, wo_f = wi * flip, wo * flip
    ci, co = wi_f[:, 2], wo_f[:, 2]
    refl, trans = co > 0, co < 0
    h = np.where(refl[:, None], wi_f + wo_f, -(eta_i[:, None] * wi_f + eta_t[:, None] * wo_f))
    norm = np.sqrt(h[:, 0] * h[:, 0] + h[:, 1] * h[:, 1] + h[:, 2] * h[:, 2])
    okh = norm > 1e-12
    h = h / np.where(okh, np.where(h[:, 2] < 0, -norm, norm), 1.0)[:, None]
    wih = h[:, 0] * wi_f[:, 0] + h[:, 1] * wi_f[:, 1] + h[:, 2] * wi_f[:, 2]
    woh = h[:, 0] * wo_f[:, 0] + h[:, 1] * wo_f[:, 1] + h[:, 2] * wo_f[:, 2]
    ok = (ci > 0) & okh & (wih > 0) & (refl | (trans & (woh < 0)))
    d = mf.beckmann_d(h[:, 2], a)
    fr = fresnel_dielectric(s * wih, ext, int_)
    with np.errstate(divide="ignore", invalid="ignore"):
        den = eta_i * wih + eta_t * woh
        jac = np.where(refl, 1.0, eta_t * eta_t * np.abs(woh) / (den * den))
        g = mf.smith_g1(wi_f, h, a, wih) * mf.smith_g1(wo_f, h, a, woh)
        r = fr * d * g / (4.0 * ci * co)
        t = wih * eta_i * eta_i * (1.0 - fr) * d * g * jac / (ci * np.abs(co) * eta_t * eta_t)
        p = np.where(refl, fr * d * h[:, 2] / (4.0 * np.abs(woh)), (1.0 - fr) * d * h[:, 2] * jac)
    r, t = np.where(ok & refl & np.isfinite(r), r, 0.0), np.where(ok & trans & np.isfinite(t), t, 0.0)
    return r, t, np.where(ok & np.isfinite(p), p, 0.0)


def _course_substrate(m, wi, wo, a, ps):
    wh, okh = mf.half_vector(wi, wo)
    hi = wh[:, 0] * wi[:, 0] + wh[:, 1] * wi[:, 1] + wh[:, 2] * wi[:, 2]
    d = mf.beckmann_d(wh[:, 2], a)
    ci, co = wi[:, 2], wo[:, 2]
    ok = (ci > 0) & (co > 0)
    f = np.zeros((len(wi), 3), order="F")
    s = m.diffuse_scale * (1.0 - pow5(1.0 - 0.5 * ci)) * (1.0 - pow5(1.0 - 0.5 * co))
    f += m.kd.value * np.where(ok, s, 0.0)[:, None]
    fr = fresnel_dielectric(np.clip(hi, 0.0, 1.0), m.ext_ior, m.int_ior)
    g = mf.smith_g1(wi, wh, a, hi) * mf.smith_g1(wo, wh, a)
    with np.errstate(divide="ignore", invalid="ignore"):
        spec = np.where(ok & okh, d * fr * g / (4.0 * ci * co), 0.0)
    f += np.where(np.isfinite(spec), spec, 0.0)[:, None]
    p_mf = np.where(okh & (hi > 0), mf.reflection_pdf(wh, wo, a, d), 0.0)
    return f, np.where(ci > 0, ps * p_mf + (1.0 - ps) * warps.square_to_cosine_hemisphere_pdf(wo), 0.0)


def test_the_course_models_are_unchanged_to_the_bit():
    rng = np.random.default_rng(4803)
    wi = _unit(rng, 5000)
    u = rng.random((5000, 3))
    for g in (RoughDielectric(0.2, 1.5, 1.0), RoughDielectric(1e-3), RoughDielectric(0.7, 1.33, 1.0, ka=0.5),
              RoughDielectric(0.4, distribution="beckmann", sample_visible=False)):
        assert g.default_options
        a = g.alpha.luminance()
        side = np.where(wi[:, 2] >= 0, 1.0, -1.0)
        s = np.stack([np.ones(len(wi)), np.ones(len(wi)), side], axis=1)
        wi_f = wi * s
        h = warps.square_to_beckmann(u[:, :2], a)
        wih = wi_f[:, 0] * h[:, 0] + wi_f[:, 1] * h[:, 1] + wi_f[:, 2] * h[:, 2]
        fr, cos_t, eta = g.refraction(side * wih, wi_f)
        wo_f = np.where((u[:, 2] < fr)[:, None], 2.0 * wih[:, None] * h - wi_f,
                        -eta[:, None] * wi_f + (eta * wih - cos_t)[:, None] * h)
        ok = (wih > 0) & (wi_f[:, 2] > 0) & np.where(u[:, 2] < fr, wo_f[:, 2] > 0, wo_f[:, 2] < 0)
        wo = wo_f * s
        r, t, rp = _course_dielectric(wi, wo, a, g.ext_ior, g.int_ior)
        rf3 = r[:, None] + t[:, None] * np.broadcast_to(g.ka.value, (len(wi), 3))
        smp = g.sample(wi, u)
        np.testing.assert_array_equal(smp.wo, wo)
        np.testing.assert_array_equal(smp.pdf, np.where(ok, rp, 0.0))
        np.testing.assert_array_equal(smp.weight, abs_cos_weight(rf3, wo, np.where(ok, rp, 0.0)))
        f, p = g.eval_pdf(wi, wo)
        np.testing.assert_array_equal(f, rf3)
        np.testing.assert_array_equal(p, rp)
    up = np.abs(wi)
    for m in (RoughSubstrate([0.3, 0.5, 0.7], 0.1), RoughSubstrate(0.5, 0.6, 1.33, 1.0)):
        assert m.default_options
        a = m.alpha.luminance()
        ps = np.minimum(fresnel_dielectric(up[:, 2], m.ext_ior, m.int_ior), 0.95)
        wo = warps.square_to_cosine_hemisphere(u[:, :2])
        spec = u[:, 2] < ps
        wo[spec] = mf.reflect(up[spec], warps.square_to_beckmann(u[spec, :2], a))
        with kernels.use_engine("numpy"):
            smp = m.sample(up, u)
            f, p = m.eval_pdf(up, wo)
        rf, rp = _course_substrate(m, up, wo, a, ps)
        np.testing.assert_array_equal(smp.wo, wo)
        np.testing.assert_array_equal(f, rf)
        np.testing.assert_array_equal(p, rp)
        np.testing.assert_array_equal(smp.weight, cos_weight(rf, wo, rp))


def test_non_default_coats_do_not_run_the_beckmann_kernel():
    """The substrate's kernel serves the default coat only: the others give the NumPy result under either engine."""
    if not kernels._numba_available():
        pytest.skip("numba is not installed")
    from brdflab.kernels import bsdf as kb

    assert kb._covered(RoughSubstrate(0.5, 0.2))
    rng = np.random.default_rng(4804)
    wi = np.abs(_unit(rng, 2000))
    u = rng.random((2000, 3))
    u[:, 2] *= 0.1  # mostly the coat's lobe
    for cfg in CONFIGS.values():
        m = RoughSubstrate(0.5, 0.3, **cfg)
        assert not kb._covered(m)
        with kernels.use_engine("numpy"):
            ref = m.sample(wi, u)
        with kernels.use_engine("numba"):
            got = m.sample(wi, u)
        for a, b in zip(ref[:3], got[:3], strict=True):
            np.testing.assert_array_equal(np.asarray(b), np.asarray(a))


# -- parameters ------------------------------------------------------------------------------------------------------
@pytest.mark.filterwarnings("ignore:.*no emitter")
def test_parameters_from_scene_param_and_constructor(tmp_path):
    from brdflab.plugins import make_bsdf

    for name in ("roughdielectric", "roughsubstrate"):
        m = make_bsdf(name, {"distribution": "ggx", "alpha_u": "0.2", "alpha_v": "0.45"})
        assert (m.distribution, m.alpha_u, m.alpha_v, m.sample_visible) == ("ggx", 0.2, 0.45, True)
        b = make_bsdf(name, {"sample_visible": "true"})
        assert b.distribution == "beckmann" and b.sample_visible and not b.default_options
        assert make_bsdf(name, {}).default_options
        assert m.scalar_parameters() != make_bsdf(name, {}).scalar_parameters()  # no family with the default
        for bad, word in [({"distribution": "phong"}, "distribution"), ({"alpha_u": "-1"}, "alpha_u"),
                          ({"sample_visible": "maybe"}, "sample_visible")]:
            with pytest.raises(BrdflabError, match=word):
                make_bsdf(name, bad)
    with pytest.raises(ValueError, match="distribution"):
        RoughDielectric(distribution="phong")
    xml = sphere_scene(tmp_path, '<bsdf type="roughdielectric"><string name="distribution" value="ggx"/>'
                       '<float name="alpha_u" value="0.1"/><float name="alpha_v" value="0.3"/>'
                       '<boolean name="sample_visible" value="false"/></bsdf>')
    (g,) = [b for b in bl.load_scene(str(xml)).bsdfs if isinstance(b, RoughDielectric)]
    assert (g.distribution, g.alpha_u, g.alpha_v, g.sample_visible) == ("ggx", 0.1, 0.3, False)


@pytest.mark.filterwarnings("ignore:.*creates energy")
def test_chi2_samples_against_the_ggx_glass(tmp_path):
    """``chi2 --samples FILE --against roughdielectric --param distribution=ggx …``: a correct anisotropic GGX file
    passes against the same parameters and fails against the default (Beckmann) glass."""
    from brdflab.judges.samples.bsdf_checks import check_samples

    glass = RoughDielectric(0.2, 1.5, 1.0, distribution="ggx", alpha_u=0.1, alpha_v=0.3)
    rng = np.random.default_rng(4805)
    rows = []
    for th in (30.0, 150.0):
        t = np.radians(th)
        wi = np.tile([np.sin(t) * np.cos(0.7), np.sin(t) * np.sin(0.7), np.cos(t)], (20_000, 1))
        s = glass.sample(wi, rng.random((20_000, 3)))
        rows.append(np.column_stack([wi, np.where((s.pdf > 0)[:, None], s.wo, 0.0), s.pdf, s.weight]))
    path = tmp_path / "ggx.txt"
    np.savetxt(path, np.concatenate(rows), fmt="%.9g")
    params = {"intIOR": 1.5, "extIOR": 1.0, "distribution": "ggx", "alpha_u": 0.1, "alpha_v": 0.3}
    r = check_samples(path, "roughdielectric", alpha=0.2, params=params)
    assert r.passed, r.messages()
    assert not check_samples(path, "roughdielectric", alpha=0.2, params={"intIOR": 1.5, "extIOR": 1.0}).passed
