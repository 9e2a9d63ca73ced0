"""roughconductor's GGX, anisotropic α, visible-normal sampling and (η, k) Fresnel (issue 45).

Golden values are independent of brdflab's code: the normalisations ∫ D cos θ_h dω = 1 and
∫ G1(ω_i) max(0, ω_i·ω_h) D(ω_h)/cos θ_i dω_h = 1 (the visible normals' projected area) by quadrature, D and G1
in the polar form of Heitz 2014 and the conductor Fresnel from the complex amplitudes, evaluated in mpmath.
The samplers pass the chi-square at random azimuths; the negative controls (visible-normal pdf without
G1(ω_i), α_u/α_v swapped in the sampler only) must fail it; the course's Beckmann model keeps its code path
bit for bit (against the formulas of the course model written out below).
"""

from __future__ import annotations

import mpmath as mp
import numpy as np
import pytest
from scipy import integrate

import brdflab as bl
from brdflab import RoughConductor, kernels
from brdflab.bsdf import microfacet as mf
from brdflab.bsdf.fresnel import fresnel_conductor, fresnel_schlick
from brdflab.errors import BrdflabError
from brdflab.judges.material.entries import CONDUCTOR_CONTROLS
from tests.conftest import sphere_scene

CONFIGS = {
    "ggx visible": dict(distribution="ggx"),
    "ggx D cos": dict(distribution="ggx", sample_visible=False),
    "beckmann visible": dict(distribution="beckmann", sample_visible=True),
    "ggx anisotropic visible": dict(distribution="ggx", alpha_u=0.08, alpha_v=0.4),
    "ggx anisotropic D cos": dict(distribution="ggx", alpha_u=0.4, alpha_v=0.1, sample_visible=False),
    "beckmann anisotropic visible": dict(distribution="beckmann", alpha_u=0.1, alpha_v=0.4, sample_visible=True),
    "beckmann anisotropic D cos": dict(distribution="beckmann", alpha_u=0.3, alpha_v=0.05),
    "ggx eta/k": dict(distribution="ggx", alpha_u=0.2, alpha_v=0.2, eta=(0.2, 0.92, 1.1), k=(3.9, 2.45, 2.14)),
}


def _sphere_dir(theta, phi):
    return np.array([[np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)]])


@pytest.mark.parametrize("dist", ["beckmann", "ggx"])
@pytest.mark.parametrize("ax,ay", [(0.3, 0.3), (0.15, 0.6), (0.7, 0.2)])
def test_ndf_normalisation_by_quadrature(dist, ax, ay):
    """∫ D(ω_h) cos θ_h dω_h = 1 (anisotropic GGX and Beckmann)."""
    def integrand(t, p):
        return float(mf.ndf(dist, _sphere_dir(t, p), ax, ay)[0]) * np.cos(t) * np.sin(t)
    val, _ = integrate.dblquad(lambda t, p: integrand(t, p), 0, 2 * np.pi, 0, np.pi / 2, epsabs=1e-9, epsrel=1e-8)
    assert val == pytest.approx(1.0, abs=2e-6)


@pytest.mark.parametrize("dist", ["beckmann", "ggx"])
@pytest.mark.parametrize("theta_i,phi_i", [(0.0, 0.0), (50.0, 20.0), (80.0, 200.0)])
def test_visible_normals_have_unit_mass(dist, theta_i, phi_i):
    """∫ G1(ω_i) max(0, ω_i·ω_h) D(ω_h) / cos θ_i dω_h = 1 with the exact Λ (projected-area normalisation)."""
    ax, ay = 0.2, 0.5
    wi = _sphere_dir(np.radians(theta_i), np.radians(phi_i))
    g1 = 1.0 / (1.0 + mf.smith_lambda(dist, wi, ax, ay)[0])

    def integrand(t, p):
        h = _sphere_dir(t, p)
        return float(mf.ndf(dist, h, ax, ay)[0]) * max(0.0, float(h[0] @ wi[0])) * np.sin(t)
    val, _ = integrate.dblquad(integrand, 0, 2 * np.pi, 0, np.pi / 2, epsabs=1e-10, epsrel=1e-8)
    assert g1 * val / wi[0, 2] == pytest.approx(1.0, abs=1e-5)


def test_ndf_and_g1_against_the_polar_forms_in_mpmath():
    """D and the exact GGX G1 in Heitz 2014's polar form (tan θ, φ), evaluated with 30 digits."""
    mp.mp.dps = 30
    ax, ay = mp.mpf("0.15"), mp.mpf("0.55")
    for t, p in [(0.3, 0.4), (1.2, 2.0), (0.05, 5.0), (1.45, 1.0)]:
        tt, pp = mp.mpf(t), mp.mpf(p)
        tan2, c = mp.tan(tt) ** 2, mp.cos(tt)
        e = tan2 * (mp.cos(pp) ** 2 / ax ** 2 + mp.sin(pp) ** 2 / ay ** 2)
        d_ggx = 1 / (mp.pi * ax * ay * c ** 4 * (1 + e) ** 2)
        d_beck = mp.exp(-e) / (mp.pi * ax * ay * c ** 4)
        a2 = (mp.cos(pp) ** 2 * ax ** 2 + mp.sin(pp) ** 2 * ay ** 2) * tan2  # α(φ)² tan²θ
        g1_ggx = 2 / (1 + mp.sqrt(1 + a2))
        a = 1 / mp.sqrt(a2)
        lam_beck = (mp.erf(a) - 1) / 2 + mp.exp(-a * a) / (2 * a * mp.sqrt(mp.pi))
        v = _sphere_dir(t, p)
        assert mf.ndf("ggx", v, 0.15, 0.55)[0] == pytest.approx(float(d_ggx), rel=1e-12)
        assert mf.ndf("beckmann", v, 0.15, 0.55)[0] == pytest.approx(float(d_beck), rel=1e-11)
        assert mf.g1("ggx", v, np.array([[0.0, 0.0, 1.0]]), 0.15, 0.55)[0] == pytest.approx(float(g1_ggx), rel=1e-13)
        lam = mf.smith_lambda("beckmann", v, 0.15, 0.55)[0]  # absolute: Λ enters as 1/(1 + Λ)
        assert lam == pytest.approx(float(lam_beck), rel=1e-9, abs=1e-15)


def test_conductor_fresnel_against_complex_amplitudes():
    """F = (|r_s|² + |r_p|²)/2 with complex n = η + ik (Born & Wolf), in mpmath."""
    mp.mp.dps = 30
    eta, k = np.array([0.2, 0.92, 1.1]), np.array([3.9, 2.45, 2.14])
    cos = np.array([1.0, 0.7, 0.2, 1e-3])
    got = fresnel_conductor(cos, eta, k)
    for i, c in enumerate(cos):
        for j in range(3):
            n = mp.mpc(eta[j], k[j])
            ci = mp.mpf(c)
            s2 = 1 - ci * ci
            ct = mp.sqrt(n * n - s2)
            rs = (ci - ct) / (ci + ct)
            rp = (n * n * ci - ct) / (n * n * ci + ct)
            assert got[i, j] == pytest.approx(float((abs(rs) ** 2 + abs(rp) ** 2) / 2), rel=1e-12)


@pytest.mark.parametrize("name", list(CONFIGS))
@pytest.mark.parametrize("theta", [0.0, 45.0, 80.0])
def test_samplers_pass_chi_square(name, theta):
    r = bl.chi2_test(RoughConductor(0.5, 0.3, **CONFIGS[name]), theta=theta, samples=60_000)
    assert r.passed, r.message


@pytest.mark.parametrize("k", range(len(CONDUCTOR_CONTROLS)))
def test_negative_controls_fail_chi_square(k):
    what, make = CONDUCTOR_CONTROLS[k]
    r = bl.chi2_test(make(), theta=60.0, samples=60_000)
    assert not r.passed, what


@pytest.mark.parametrize("name", ["ggx anisotropic visible", "beckmann anisotropic visible", "ggx eta/k"])
def test_consistency_and_furnace(name):
    m = RoughConductor(1.0, 0.3, **CONFIGS[name])
    assert bl.consistency_test(m, theta=50.0, samples=40_000).passed
    assert bl.furnace_test(m, thetas=(0.0, 60.0), samples=20_000).passed


def test_stability_of_the_new_models():
    res = bl.stability_test()
    assert res.passed
    assert any("ggx" in r.material for r in res)


def _course_terms(wi, wo, r0, a):
    """The course's model written out: Beckmann D, rational G1, Schlick, D cos θ_h sampling density."""
    wh, okh = mf.half_vector(wi, wo)
    hi = wh[:, 0] * wi[:, 0] + wh[:, 1] * wi[:, 1] + wh[:, 2] * wi[:, 2]
    d = mf.beckmann_d(wh[:, 2], a)
    ci, co = wi[:, 2], wo[:, 2]
    g = mf.smith_g1(wi, wh, a, hi) * mf.smith_g1(wo, wh, a)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where((ci > 0) & (co > 0) & okh, d * g / (4.0 * ci * co), 0.0)
    f = fresnel_schlick(np.clip(hi, 0.0, 1.0), r0, np.where(np.isfinite(s), s, 0.0))
    pdf = np.where((ci > 0) & okh & (hi > 0), mf.reflection_pdf(wh, wo, a, d), 0.0)
    return f, pdf


def test_the_course_model_is_unchanged_to_the_bit():
    rng = np.random.default_rng(45)
    wi = rng.normal(size=(5000, 3))
    wi /= np.linalg.norm(wi, axis=1)[:, None]
    u = rng.random((5000, 3))
    for m in (RoughConductor([0.9, 0.6, 0.3], 0.2), RoughConductor(0.5, 1e-3),
              RoughConductor(0.5, 0.7, distribution="beckmann", sample_visible=False)):
        assert m.course_model
        with kernels.use_engine("numpy"):
            s = m.sample(wi, u)
            f, pdf = m.eval_pdf(wi, s.wo)
        from brdflab.math import warps
        wo = mf.reflect(wi, warps.square_to_beckmann(u[:, :2], m.alpha.value[0]))
        np.testing.assert_array_equal(s.wo, wo)
        rf, rp = _course_terms(wi, wo, m.R0.value, m.alpha.luminance())
        np.testing.assert_array_equal(f, rf)
        np.testing.assert_array_equal(pdf, rp)
        np.testing.assert_array_equal(s.pdf, rp)


def test_non_course_instances_do_not_run_the_beckmann_kernel():
    """GGX, anisotropic, visible-normal and η/k instances give the NumPy result through either engine: the kernel
    covers them all (Beckmann's visible slopes solved by NumPy, see brdflab.kernels.bsdf)."""
    if not kernels._numba_available():
        pytest.skip("numba is not installed")
    from brdflab.kernels import bsdf as kb

    assert kb._covered(RoughConductor(distribution="ggx", alpha_v=0.2, material="Au"))
    assert kb._covered(RoughConductor(distribution="beckmann", sample_visible=True))
    rng = np.random.default_rng(7)
    wi = rng.normal(size=(2000, 3))
    wi /= np.linalg.norm(wi, axis=1)[:, None]
    wi[:, 2] = np.abs(wi[:, 2])
    u = rng.random((2000, 3))
    for cfg in CONFIGS.values():
        m = RoughConductor(0.5, 0.3, **cfg)
        with kernels.use_engine("numpy"):
            ref = m.sample(wi, u)
        with kernels.use_engine("numba"):
            got = m.sample(wi, u)
        for a, b in zip(ref[:3], got[:3], strict=True):
            np.testing.assert_allclose(np.asarray(b), np.asarray(a), rtol=1e-12, atol=0)


def test_parameters_from_scene_param_and_constructor(tmp_path):
    from brdflab.plugins import make_bsdf

    m = make_bsdf("roughconductor", {"distribution": "ggx", "alpha_u": "0.2", "alpha_v": "0.45",
                                     "eta": "0.2,0.92,1.1", "k": "3.9,2.45,2.14"})
    assert (m.distribution, m.alpha_u, m.alpha_v, m.sample_visible) == ("ggx", 0.2, 0.45, True)
    np.testing.assert_array_equal(m.k, [3.9, 2.45, 2.14])
    gold = make_bsdf("roughconductor", {"material": "Au", "sample_visible": "false", "distribution": "ggx"})
    assert not gold.sample_visible and gold.eta[0] < gold.eta[2]
    for bad, word in [({"distribution": "phong"}, "distribution"), ({"material": "Xx"}, "material"),
                      ({"k": "1"}, "eta"), ({"material": "Au", "eta": "1"}, "material"),
                      ({"alpha_u": "-1"}, "alpha_u"), ({"eta": "0,1,1"}, "eta"), ({"R0": "0.5", "eta": "1"}, "R0")]:
        with pytest.raises(BrdflabError, match=word):
            make_bsdf("roughconductor", bad)
    xml = sphere_scene(tmp_path, '<bsdf type="roughconductor"><string name="distribution" value="ggx"/>'
                       '<float name="alpha_u" value="0.1"/><float name="alpha_v" value="0.3"/>'
                       '<color name="eta" value="0.2, 0.92, 1.1"/><color name="k" value="3.9, 2.45, 2.14"/></bsdf>')
    scene = bl.load_scene(str(xml))
    (b,) = [b for b in scene.bsdfs if isinstance(b, RoughConductor)]
    assert b.distribution == "ggx" and (b.alpha_u, b.alpha_v) == (0.1, 0.3)
    assert b.scalar_parameters() != RoughConductor(0.5, 0.1).scalar_parameters()  # no family with Beckmann


def test_metal_colours_are_the_conversion_of_the_tables():
    """The stored (η, k) of each metal is the documented conversion of its spectral table; a constant stays grey."""
    from brdflab.bsdf.conductors import MATERIALS, METALS_RGB, convert_table, spectrum_to_rgb

    for name in MATERIALS:
        eta, k = convert_table(name)
        np.testing.assert_allclose(METALS_RGB[name][0], eta, rtol=1e-12)
        np.testing.assert_allclose(METALS_RGB[name][1], k, rtol=1e-12)
    np.testing.assert_allclose(spectrum_to_rgb([380.0, 780.0], [0.7, 0.7]), 0.7, rtol=1e-12)
    assert np.array_str(np.array([0.2])) == "[0.2]"  # importing colour-science left NumPy's print options alone
    r_au = fresnel_conductor(np.array([1.0]), *METALS_RGB["Au"])[0]
    assert r_au[0] > r_au[1] > r_au[2]  # gold reflects red more than blue


def test_furnace_of_a_conductor_with_eta_k_or_material_runs_with_r0_1():
    """The furnace's R0 = 1 replaces a conductor's η/k/material (they are alternatives to R0): validate with
    material=Au raised 'R0 and material are alternatives' at every furnace point before."""
    from brdflab.judges.material.entries import furnace_parameters, resolve_bsdfs

    e = resolve_bsdfs(["roughconductor"])[0]
    prm = furnace_parameters(e, {"material": "Au", "distribution": "ggx", "eta": "1,1,1", "k": "2,2,2"}, {})
    assert prm == {"distribution": "ggx", "R0": 1.0}
    from brdflab.judges.material.furnace import furnace_point

    r = furnace_point(e.make(0.3, prm), theta=30.0, samples=5000)
    assert r.passed, r.message
