"""Golden values of the delta and transmissive materials (issue 44), computed independently of brdflab:
Fresnel by hand (normal incidence ((n1 − n2)/(n1 + n2))², Brewster's angle in exact rationals, the critical
angle of total internal reflection), Snell's law with mpmath, and Walter et al.'s rough dielectric with the
mpmath references of tests/test_golden.py (D, G1, Fresnel written from the spec)."""

from __future__ import annotations

from fractions import Fraction

import mpmath as mp
import numpy as np
import pytest

import brdflab as bl
from brdflab.bsdf.fresnel import dielectric_refraction, fresnel_dielectric
from brdflab.plugins import make_bsdf
from brdflab.scene.loader import load_scene
from tests.conftest import CAMERA, QUAD_OBJ, write_scene
from tests.test_golden import dotm, ref_d, ref_fresnel, ref_g1

mp.mp.dps = 40


def _dir(theta_deg: float, phi_deg: float = 0.0) -> np.ndarray:
    t, p = np.radians(theta_deg), np.radians(phi_deg)
    return np.array([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)])


@pytest.mark.parametrize("n1,n2", [(1.0, 1.5), (1.5, 1.0), (1.0, 1.33), (1.000277, 1.5046)])
def test_fresnel_normal_incidence(n1, n2):
    """((n1 − n2)/(n1 + n2))² at θ_i = 0, from either side."""
    expect = ((n1 - n2) / (n1 + n2)) ** 2
    f, ct, eta = dielectric_refraction(np.array([1.0, -1.0]), n1, n2)
    np.testing.assert_allclose(f, expect, rtol=1e-14)
    np.testing.assert_allclose(ct, 1.0, rtol=1e-15)
    np.testing.assert_allclose(eta, [n1 / n2, n2 / n1], rtol=1e-15)


def test_fresnel_brewster_exact():
    """At Brewster's angle tan θ_B = n2/n1, r_p = 0 and r_s = (n1² − n2²)/(n1² + n2²): for 1 → 1.5,
    r_s = −5/13, F = 25/338 (by hand); from inside (1.5 → 1) tan θ_B = 1/1.5 and F is the same."""
    expect = float(Fraction(25, 338))
    tb = np.arctan(1.5)
    inside = np.arctan(1 / 1.5)
    f = fresnel_dielectric(np.array([np.cos(tb), -np.cos(inside)]), 1.0, 1.5)
    np.testing.assert_allclose(f, expect, rtol=1e-13)


def test_total_internal_reflection_boundary():
    """Inside glass (1.5 → 1) the critical angle is asin(1/1.5): F < 1 just below, F = 1 at and above."""
    crit = np.degrees(np.arcsin(1 / 1.5))
    cos_i = -np.cos(np.radians([crit - 1e-3, crit + 1e-6, crit + 10.0, 89.0]))
    f, ct, _ = dielectric_refraction(cos_i, 1.0, 1.5)
    assert f[0] < 1.0 and ct[0] > 0
    np.testing.assert_array_equal(f[1:], 1.0)
    np.testing.assert_array_equal(ct[1:], 0.0)
    for c, got in zip(cos_i, fresnel_dielectric(cos_i, 1.0, 1.5), strict=True):
        assert got == pytest.approx(float(ref_fresnel(mp.mpf(float(c)), mp.mpf(1), mp.mpf("1.5"))), rel=1e-12)


@pytest.mark.parametrize("theta", [0.0, 10.0, 35.0, 60.0, 85.0, 120.0, 139.0, 170.0])
@pytest.mark.parametrize("phi", [0.0, 77.0])
def test_dielectric_refraction_snell(theta, phi):
    """The refracted direction is Snell's (mpmath): η_i sin θ_i = η_t sin θ_t, in the plane of incidence on the
    other side, azimuth opposite; the weight is (η_i/η_t)² and pdf 1 − F; reflections mirror with weight 1."""
    ext, int_ = 1.0, 1.5
    g = bl.Dielectric(intIOR=int_, extIOR=ext)
    wi = _dir(theta, phi)[None, :]
    s_t = g.sample(wi, np.array([[0.5, 0.5, 1.0 - 1e-12]]))  # ξ3 ≈ 1 > F: refract (unless TIR)
    s_r = g.sample(wi, np.array([[0.5, 0.5, 0.0]]))          # ξ3 = 0 < F: reflect
    outside = theta < 90
    ei, et = (ext, int_) if outside else (int_, ext)
    sin_i = mp.sin(mp.radians(theta))
    sin2_t = (mp.mpf(ei) / et) ** 2 * sin_i ** 2
    F = float(ref_fresnel(mp.cos(mp.radians(theta)), mp.mpf(ext), mp.mpf(int_)))
    np.testing.assert_allclose(s_r.wo[0], [-wi[0, 0], -wi[0, 1], wi[0, 2]], atol=1e-15)
    assert s_r.weight[0].tolist() == [1.0] * 3 and s_r.pdf[0] == pytest.approx(F, rel=1e-12)
    assert s_r.delta.tolist() == [True] and s_t.delta.tolist() == [True]
    if sin2_t >= 1:
        assert F == 1.0 and s_t.wo[0].tolist() == s_r.wo[0].tolist()  # TIR: always reflected
        return
    sin_t, cos_t = mp.sqrt(sin2_t), mp.sqrt(1 - sin2_t)
    p = np.radians(phi)
    expect = [-float(sin_t) * np.cos(p), -float(sin_t) * np.sin(p), float(-cos_t if outside else cos_t)]
    np.testing.assert_allclose(s_t.wo[0], expect, atol=2e-15)
    np.testing.assert_allclose(s_t.weight[0], (ei / et) ** 2, rtol=1e-15)
    assert s_t.pdf[0] == pytest.approx(1 - F, rel=1e-12)
    assert g.eval(wi, s_t.wo).tolist() == [[0.0] * 3] and g.pdf(wi, s_t.wo).tolist() == [0.0]


def test_mirror_one_sided():
    """Spec §10.3: (−x, −y, z), weight 1, pdf 1 above; a failed sample (weight 0, pdf 0) below."""
    wi = np.array([_dir(40.0, 30.0), _dir(130.0)])
    s = bl.Mirror().sample(wi, np.zeros((2, 3)))
    np.testing.assert_array_equal(s.wo, wi * [-1, -1, 1])
    assert s.weight.tolist() == [[1.0] * 3, [0.0] * 3] and s.pdf.tolist() == [1.0, 0.0]
    assert bl.Mirror().eval(wi, s.wo).tolist() == [[0.0] * 3] * 2


def test_flags_and_old_contract():
    """The contract's class attributes; an old-style 3-field BSDFSample still works (delta None)."""
    assert bl.Mirror.all_delta and not bl.Mirror.two_sided and not bl.Mirror.has_transmission
    assert bl.Dielectric.all_delta and bl.Dielectric.two_sided and bl.Dielectric.has_transmission
    assert not bl.RoughDielectric.has_delta and bl.RoughDielectric.has_transmission
    assert not bl.Diffuse.has_delta and not bl.Diffuse.two_sided and bl.BSDFSample(1, 2, 3).delta is None


def ref_g1_sphere(v, h, a):
    """Rational Smith G1 (§11.1) for v on either side: χ⁺((v·h)/v_z), b = 1/(α tan θ_v) with tan θ_v ≥ 0 from
    |v_z| (tests/test_golden.py's ref_g1 is the upper hemisphere's)."""
    if dotm(v, h) / v[2] <= 0:
        return mp.mpf(0)
    return ref_g1([v[0], v[1], abs(v[2])], [0, 0, 1], a)


def ref_rough_dielectric(wi, wo, a, ext, int_):
    """Walter et al. 2007 eqs. 20–21 in mpmath (radiance form, η of ω_i's side squared), two-sided."""
    wi, wo = [mp.mpf(float(x)) for x in wi], [mp.mpf(float(x)) for x in wo]
    ei, et = (mp.mpf(ext), mp.mpf(int_)) if wi[2] >= 0 else (mp.mpf(int_), mp.mpf(ext))
    if wi[2] < 0:
        wi, wo = [wi[0], wi[1], -wi[2]], [wo[0], wo[1], -wo[2]]
    if wo[2] > 0:
        h = [wi[k] + wo[k] for k in range(3)]
    else:
        h = [-(ei * wi[k] + et * wo[k]) for k in range(3)]
    n = mp.sqrt(dotm(h, h)) * (1 if h[2] > 0 else -1)
    h = [x / n for x in h]
    ih, oh = dotm(wi, h), dotm(wo, h)
    F = ref_fresnel(ih, ei, et)  # flipped frame: ω_i·ω_h > 0 is on the side of index η_i
    G = ref_g1_sphere(wi, h, a) * ref_g1_sphere(wo, h, a)
    D = ref_d(h[2], a)
    if wo[2] > 0:
        return F * D * G / (4 * wi[2] * wo[2])
    if ih <= 0 or oh >= 0:
        return mp.mpf(0)
    return abs(ih) * abs(oh) * ei ** 2 * (1 - F) * D * G / (abs(wi[2]) * abs(wo[2]) * (ei * ih + et * oh) ** 2)


@pytest.mark.parametrize("alpha", [0.05, 0.3, 0.8])
def test_rough_dielectric_against_mpmath(alpha):
    """f of RoughDielectric against the mpmath transcription of Walter et al. on random pairs of the sphere
    (both sides, reflection and transmission), relative 1e-10."""
    rng = np.random.default_rng(44)
    wi = bl.warps.square_to_uniform_sphere(rng.random((300, 2)))
    wo = bl.warps.square_to_uniform_sphere(rng.random((300, 2)))
    # and directions near the refracted and mirror ones, where f is large
    g = bl.RoughDielectric(alpha=alpha, intIOR=1.5, extIOR=1.0)
    s = g.sample(wi, rng.random((300, 3)))
    wi, wo = np.concatenate([wi, wi]), np.concatenate([wo, s.wo])
    got = g.eval(wi, wo)[:, 0]
    ref = np.array([float(ref_rough_dielectric(a, b, mp.mpf(alpha), 1.0, 1.5)) for a, b in zip(wi, wo, strict=True)])
    assert (ref > 0).sum() > 300
    np.testing.assert_allclose(got, ref, rtol=1e-10, atol=1e-300)


@pytest.mark.filterwarnings("ignore:.*no emitter")
def test_built_from_xml_and_by_name(tmp_path):
    """Scene XML builds the three materials (ka as m_ka texture slot name too); names and defaults as §10."""
    g = make_bsdf("dielectric", {"intIOR": "1.33"})
    assert (g.int_ior, g.ext_ior) == (1.33, 1.000277)
    r = make_bsdf("roughdielectric", {"ka": "0.5,0.6,0.7"}, alpha=0.2)
    assert r.alpha_value == pytest.approx(0.2) and r.ka.value.tolist() == [0.5, 0.6, 0.7] and r.int_ior == 1.5046
    mesh = ('<mesh type="obj"><string name="filename" value="q.obj"/><bsdf type="{t}">{b}</bsdf></mesh>')
    body = "".join(mesh.format(t=t, b=b) for t, b in [
        ("mirror", ""), ("dielectric", '<float name="intIOR" value="1.33"/>'),
        ("roughdielectric", '<float name="alpha" value="0.2"/><texture type="checker" name="m_ka"/>')])
    p = write_scene(tmp_path, '<integrator type="direct_ems"/>' + CAMERA + body, {"q.obj": QUAD_OBJ})
    kinds = [type(b).__name__ for b in load_scene(p).bsdfs]
    assert {"Mirror", "Dielectric", "RoughDielectric"} <= set(kinds)
