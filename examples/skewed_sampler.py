"""A deliberately broken sampler, to see what a failing chi-square page looks like.

``SkewedAzimuthConductor`` is the rough conductor with one classic inversion bug: the half-vector azimuth is
drawn as φ_h = 2π ξ₂² instead of 2π ξ₂, so directions crowd toward small azimuths, while its pdf still
claims the correct (isotropic) density. Run

    brdflab chi2 --plugin examples/skewed_sampler.py --bsdf skewed_azimuth_conductor --alpha 0.3 --theta 45

and open the report: the test fails, and the residual map (O − E)/√E in (φ′, cos θ′) shows a red band
(sampled far too often) along the azimuth where the squared ξ₂ piles the half vectors up (φ_h → 0) and blue
(too rarely) at the other azimuths — the fault is where the map says it is.
"""

from __future__ import annotations

import brdflab as bl


class SkewedAzimuthConductor(bl.RoughConductor):
    """Rough conductor whose sampler squares ξ₂ (the half-vector azimuth); eval and pdf are correct."""

    type_name = "skewed_azimuth_conductor"

    def sample(self, wi, u, uv=None):
        """The parent's sampler with ξ₂ → ξ₂² (the bug)."""
        u = u.copy()
        u[:, 1] = u[:, 1] ** 2
        return super().sample(wi, u, uv)
