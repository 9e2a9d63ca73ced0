"""The judges integrate a thin curved streak (anisotropic α_u/α_v = 250 at grazing incidence) about an axis it runs
along, chosen from the pilot and the pdf only; a pdf that is wrong stays wrong about every axis (negative controls).

The streak: α_u = 10⁻³, α_v = 0.25 reflects ω_i about normals in the yz plane, so ω_o·x = −ω_i·x (a small circle
about the x axis, ~2·10⁻³ rad wide). About the normal, its (θ, φ) bins cut it obliquely and the Gauss nodes
missed 1 % of ∫ p (error estimate 10⁻⁵): a correct sampler failed chi-square and consistency at
``validate --samples 100000``.
"""

from __future__ import annotations

import numpy as np
import pytest

import brdflab as bl
from brdflab.judges.material import chi2 as c2
from brdflab.judges.material.consistency import consistency_test

STREAK = {"alpha": 1e-3, "alpha_v": 0.25}


class ScaledPdf(bl.RoughConductor):
    """Negative control: pdf() 2 % short of the sampler's density (sample() keeps the true pdf)."""

    type_name = "streak_scaled_pdf"

    def pdf(self, wi, wo, uv=None):
        return 0.98 * super().pdf(wi, wo, uv)


def test_streak_passes_chi2_about_the_axis_it_runs_along():
    r = c2.bsdf_test("streak", bl.RoughConductor(**STREAK), 85.0, 100_000, seed=11, phi_deg=221.834,
                     params=dict(STREAK))
    assert r.passed, r.message
    assert abs(r.integral - r.valid_fraction) < 0.005, r.message
    assert r.axis is not None and abs(r.axis[2]) < 0.9, r.message  # not the normal: the streak's own frame


def test_streak_passes_consistency():
    r = consistency_test(bl.RoughConductor(**STREAK), theta=85.0, samples=100_000, seed=3)  # failed before
    assert r.passed, r.message


def test_isotropic_lobe_keeps_the_normal_frame():
    r = c2.bsdf_test("iso", bl.RoughConductor(alpha=0.3), 45.0, 50_000, seed=3, params={"alpha": 0.3})
    assert r.passed, r.message
    assert r.axis is not None and r.axis[2] == 1.0


@pytest.mark.parametrize("test", ["chi2", "consistency"])
def test_a_pdf_short_of_the_sampler_fails_about_every_axis(test):
    bsdf = ScaledPdf(**STREAK)
    if test == "chi2":
        r = c2.bsdf_test("scaled", bsdf, 85.0, 100_000, seed=11, phi_deg=221.834, params=dict(STREAK))
    else:
        r = consistency_test(bsdf, theta=85.0, samples=100_000, seed=3)
    assert not r.passed, r.message


def test_best_frame_prefers_the_axis_with_the_most_mass():
    """The frame search uses the pilot and the pdf: about x, the streak's ∫ p matches the pilot's valid fraction."""
    b = bl.RoughConductor(**STREAK)
    wi1 = c2.incident(85.0, 221.834)
    rng = np.random.default_rng(5)
    s = b.sample(np.tile(wi1, (25_000, 1)), rng.random((25_000, 3)))
    pilot = s.wo[s.pdf > 0]
    valid = len(pilot) / 25_000

    def pdf(w):
        return b.pdf(np.ascontiguousarray(np.broadcast_to(wi1, (len(w), 3))), w)

    axis, _, _, mass, _, _ = c2.best_frame(pilot, len(pilot), valid, pdf, 16, 24, False, False, 10**6)
    assert abs(mass.sum() - valid) < 3.5 * np.sqrt(valid * (1 - valid) / 25_000)
    assert abs(axis[2]) < 0.9
