"""Judges of a BSDF that mixes a delta lobe with a smooth one (``has_delta`` without ``all_delta``).

The material (a test double, written here): a smooth dielectric coat (Fresnel F of the incident cosine, a
mirror lobe of probability F and weight 1) over a Lambertian base, f = (1 − F_i)(1 − F_o)·k_d/π (reciprocal),
sampled as "mirror with probability F_i, else cosine-weighted" (pdf (1 − F_i) cos θ_o/π, weight
(1 − F_o)·k_d). Correct, it must pass the chi-square test (its delta samples count in the cell of mass
1 − ∫p dω, with the failed ones), the consistency checks (weights and pdfs of its smooth samples) and the
furnace (smooth part: quadrature against Monte Carlo; the delta lobes' energy counted in ρ ≤ 1). Before the
judges knew this kind of BSDF, the correct material failed all three (its delta samples piled into one bin of
the chi-square test, their weight 1 was compared with eval·cos/pdf). Negative controls: the mirror chosen with
probability F/2 while the pdf says 1 − F for the rest; a pdf without the factor 1 − F; a delta weight of 2.
"""

from __future__ import annotations

import numpy as np
import pytest

import brdflab as bl
from brdflab.bsdf.base import BSDF, BSDFSample
from brdflab.bsdf.fresnel import fresnel_dielectric


class CoatedDiffuse(BSDF):
    """Smooth coat over Lambert (module docstring); ``bug`` plants one of the negative controls."""

    type_name = "test_coated_diffuse"
    has_delta = True
    all_delta = False

    def __init__(self, kd: float = 0.6, ior: float = 1.5, bug: str = "") -> None:
        self.kd, self.ior, self.bug = kd, ior, bug

    def _f(self, c):
        return fresnel_dielectric(np.abs(c), 1.0, self.ior)

    def eval(self, wi, wo, uv=None):
        ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
        f = (1 - self._f(wi[:, 2])) * (1 - self._f(wo[:, 2])) * self.kd / np.pi
        return np.where(ok, f, 0.0)[:, None] * np.ones(3)

    def pdf(self, wi, wo, uv=None):
        ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
        scale = 1.0 if self.bug == "pdf" else 1 - self._f(wi[:, 2])
        return np.where(ok, scale * wo[:, 2] / np.pi, 0.0)

    def sample(self, wi, u, uv=None):
        F = self._f(wi[:, 2])
        spec = u[:, 2] < (F / 2 if self.bug == "frequency" else F)
        r, ph = np.sqrt(u[:, 0]), 2 * np.pi * u[:, 1]
        d = np.stack([r * np.cos(ph), r * np.sin(ph), np.sqrt(np.maximum(0.0, 1 - u[:, 0]))], axis=1)
        wo = np.where(spec[:, None], wi * np.array([-1.0, -1.0, 1.0]), d)
        ok = wi[:, 2] > 0
        pdf = np.where(ok, np.where(spec, F, (1 - F) * d[:, 2] / np.pi), 0.0)
        w_delta = 2.0 if self.bug == "delta_weight" else 1.0
        weight = np.where(spec, w_delta, (1 - self._f(d[:, 2])) * self.kd)
        return BSDFSample(wo, np.where(ok, weight, 0.0)[:, None] * np.ones(3), pdf, spec & ok)


@pytest.mark.parametrize("theta", [0.0, 60.0, 85.0])
def test_a_correct_mixed_bsdf_passes_every_judge(theta):
    b = CoatedDiffuse()
    assert bl.chi2_test(b, theta=theta, samples=100_000).passed
    c = bl.consistency_test(b, theta=theta, samples=50_000)
    assert c.passed, c.message
    assert c.max_weight_error < 1e-12
    fr = bl.furnace_test(b, thetas=(theta,), samples=50_000)
    assert fr.passed, fr.message
    point = fr.points[0]
    F = float(fresnel_dielectric(np.array([np.cos(np.radians(theta))]), 1.0, 1.5)[0])
    assert point.delta_part == pytest.approx(F, abs=4 * point.delta_stderr + 1e-12)  # weight 1, frequency F


def test_wrong_lobe_frequency_fails_the_chi_square_test():
    assert not bl.chi2_test(CoatedDiffuse(bug="frequency"), theta=60.0, samples=100_000).passed


def test_pdf_without_the_lobe_probability_fails():
    b = CoatedDiffuse(bug="pdf")
    assert not bl.chi2_test(b, theta=30.0, samples=100_000).passed
    assert not bl.consistency_test(b, theta=30.0, samples=50_000).passed


def test_a_delta_lobe_that_creates_energy_fails_the_furnace():
    # weight 2 on a lobe of probability F: at grazing incidence (F ≈ 0.6) the delta lobes alone carry ρ > 1
    fr = bl.furnace_test(CoatedDiffuse(bug="delta_weight"), thetas=(85.0,), samples=50_000)
    assert not fr.passed
    assert "creates energy" in fr.points[0].message
