"""Transmission in the BRDF views (issue 44): the whole circle, R and T, delta lobes as spikes; and the measured
table's albedo by a fixed rule at its resolution (issue 43: the adaptive rule chased the table's noise)."""

from __future__ import annotations

import numpy as np
import pytest

from brdflab.bsdf.dielectric import Dielectric
from brdflab.bsdf.diffuse import Diffuse
from brdflab.bsdf.mirror import Mirror
from brdflab.bsdf.roughconductor import RoughConductor
from brdflab.bsdf.roughdielectric import RoughDielectric
from brdflab.viz import reflectance, views


def _fresnel(theta_deg: float, n1: float, n2: float) -> float:
    """Unpolarised Fresnel reflectance by hand (Hecht, Optics, eqs. 4.42–4.43), independent of bsdf/fresnel.py."""
    ci = np.cos(np.radians(theta_deg))
    st = n1 / n2 * np.sin(np.radians(theta_deg))
    if st >= 1:
        return 1.0
    ct = np.sqrt(1 - st**2)
    rs = (n1 * ci - n2 * ct) / (n1 * ci + n2 * ct)
    rp = (n2 * ci - n1 * ct) / (n2 * ci + n1 * ct)
    return 0.5 * (rs**2 + rp**2)


@pytest.mark.parametrize("theta", [0.0, 40.0, 75.0])
def test_delta_lobes_of_glass_are_fresnel_at_snells_direction(theta):
    lobes = reflectance.delta_lobes(Dielectric(1.5, 1.0), theta)
    assert [d.transmitted for d in lobes] == [False, True]
    f = _fresnel(theta, 1.0, 1.5)
    assert abs(lobes[0].energy - f) <= 1.0 / reflectance.DELTA_GRID
    assert abs(lobes[1].energy - (1 - f)) <= 1.0 / reflectance.DELTA_GRID
    wi = np.array([np.sin(np.radians(theta)), 0.0, np.cos(np.radians(theta))])
    np.testing.assert_allclose(lobes[0].direction, [-wi[0], 0, wi[2]], atol=1e-12)
    sin_t = np.sin(np.radians(theta)) / 1.5
    np.testing.assert_allclose(lobes[1].direction, [-sin_t, 0, -np.sqrt(1 - sin_t**2)], atol=1e-12)
    r, t = reflectance.albedo_parts(Dielectric(1.5, 1.0), theta)
    assert abs(r + t - 1) <= 2.0 / reflectance.DELTA_GRID


def test_mirror_is_one_reflected_spike():
    (d,) = reflectance.delta_lobes(Mirror(), 30.0)
    assert not d.transmitted and d.energy == pytest.approx(1.0)


def test_rough_glass_albedo_splits_into_r_and_t_that_match_the_furnace():
    """R + T of the views' quadrature (two adaptive hemispheres) against the furnace check's independent one
    (pilot-placed bins over the whole sphere), and against Monte Carlo of the BSDF's sampler."""
    from brdflab.judges.material import furnace

    b = RoughDielectric(0.3, 1.5, 1.0)
    r, t = reflectance.albedo_parts(b, 50.0)
    assert 0.02 < r < 0.3 and 0.6 < t < 0.98  # Fresnel at 50° with roughness: mostly transmitted
    assert r + t == pytest.approx(furnace.albedo_quadrature(b, 50.0), abs=2e-3)
    mean, se = reflectance.monte_carlo_parts(b, 50.0, 40_000, seed=11)
    assert abs(mean[0] - r) < 5 * se[0] and abs(mean[1] - t) < 5 * se[1]
    assert mean[2] == pytest.approx(mean[0] + mean[1])
    alb = views.albedo([b, RoughConductor(1.0, 0.2)], thetas=(0.0, 60.0), n=4000, seed=2)
    assert alb.any_transmission and np.all(alb.transmitted[1] == 0) and np.all(alb.transmitted[0] > 0.5)
    np.testing.assert_allclose(alb.quadrature, alb.reflected + alb.transmitted)


def test_polar_covers_the_whole_circle_for_transmission():
    t, v = views.polar([RoughDielectric(0.1, 1.5, 1.0), Diffuse(0.5)], 40.0)
    assert t[0] == -180 and t[-1] == 180
    sin_t = np.sin(np.radians(40.0)) / 1.5
    peak = t[np.argmax(np.where(np.abs(t) > 90, v[0], 0))]
    assert abs(peak - (180 - np.degrees(np.arcsin(sin_t)))) < 3  # the refracted peak, below the horizon
    assert np.all(v[1][np.abs(t) > 90.01] == 0)  # the diffuse BRDF is 0 below
    t2, _ = views.polar([Diffuse(0.5)], 40.0)
    assert t2[0] == -90 and t2[-1] == 90  # reflection only: the half circle as before
    lb = views.lobe([RoughDielectric(0.1, 1.5, 1.0)], 40.0, n_theta=10)
    assert lb.theta_o_deg[-1] == 180 and lb.values[0][lb.theta_o_deg > 90].max() > 0


@pytest.mark.parametrize(("alpha", "thetas"), [(0.05, (30.0,)), (0.3, (0.0, 60.0, 80.0))])
def test_measured_albedo_fixed_rule_matches_the_adaptive_one(alpha, thetas):
    """The fixed-order half-vector rule against the adaptive (cos θ_o, φ_o) rule on a smooth table (where the
    adaptive rule converges), and against the model the table was made from (interpolation error only)."""
    from brdflab.bsdf.measured import Measured, tabulate
    from brdflab.judges.material import furnace

    rc = RoughConductor(1.0, alpha)
    m = Measured(table=tabulate(rc))
    for theta in thetas:  # (the adaptive rule is slow on a sharp table: one angle there)
        fixed = reflectance.measured_albedo(m, theta)
        assert fixed == pytest.approx(reflectance._adaptive(m, theta, False), abs=3e-4)
        assert fixed == pytest.approx(furnace.albedo_quadrature(rc, theta), abs=1e-2)
    # the views take it for a Measured table
    assert views.albedo_quadrature(m, 30.0) == reflectance.measured_albedo(m, 30.0)
