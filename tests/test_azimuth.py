"""Every BSDF check runs at its own incident azimuth (issue 40): a sampler that forgets to rotate by ω_i's
azimuth passed every check made in the x–z plane (φ_i = 0), built-ins and plugins alike."""

from __future__ import annotations

import numpy as np

import brdflab as bl
from brdflab.bsdf.base import BSDFSample
from brdflab.judges.core.seeding import test_azimuth
from brdflab.judges.material.chi2 import bsdf_test, incident


class Unrotated(bl.RoughConductor):
    """Samples as if ω_i had azimuth 0 and never rotates the result back (the planted bug)."""

    def sample(self, wi, u, uv=None):
        r = np.hypot(wi[:, 0], wi[:, 1])
        flat = np.stack([r, np.zeros_like(r), wi[:, 2]], axis=1)
        s = super().sample(flat, u, uv)
        return BSDFSample(s.wo, s.weight, self.pdf(wi, s.wo, uv))


def test_azimuths_are_spread_and_reproducible():
    phis = [test_azimuth(s) for s in range(2000)]
    assert phis == [test_azimuth(s) for s in range(2000)]
    hist = np.histogram(phis, bins=8, range=(0, 360))[0]
    assert hist.min() > 180  # about 250 each
    np.testing.assert_allclose(incident(30.0, 90.0), [0.0, 0.5, np.cos(np.radians(30))], atol=1e-15)


def test_a_sampler_that_forgets_the_azimuth_fails_the_default_checks():
    bad = Unrotated(R0=0.9, alpha=0.2)
    seed = next(s for s in range(100) if 30 < test_azimuth(s) % 180 < 150)  # far from the x–z plane
    r = bsdf_test("unrotated", bad, 40.0, 40_000, seed=seed)
    assert not r.passed and r.params["phi"] == round(test_azimuth(seed), 3), r.message
    assert not bl.consistency_test(bad, theta=40.0, samples=20_000).passed
    # the old blind spot: in the x–z plane the same sampler passes
    assert bsdf_test("unrotated", bad, 40.0, 40_000, seed=seed + 100, phi_deg=0.0).passed


def test_the_measured_sampler_rotates_with_the_azimuth():
    """A second line of defence for the measured BSDF (issue 40): its sampler against its pdf at an azimuth away
    from the x–z plane, and its albedo by quadrature against Monte Carlo there."""
    from brdflab.bsdf.measured import Measured, tabulate

    m = Measured(table=tabulate(bl.RoughConductor(R0=[0.9, 0.7, 0.5], alpha=0.3)))
    seed = next(s for s in range(100) if 30 < test_azimuth(s) % 180 < 150)
    assert bsdf_test("measured", m, 35.0, 40_000, seed=seed).passed
    assert bl.furnace_test(m, thetas=(35.0,), samples=40_000).passed
