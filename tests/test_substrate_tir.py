"""roughsubstrate seen from the denser side (extIOR > intIOR): beyond the critical angle the coating's
Fresnel term is 1, yet the diffuse lobe still reflects. BSDF sampling must still reach it, or every
BSDF-sampled estimate (direct_mats, the BSDF half of direct_mis) is biased low there."""

from __future__ import annotations

import numpy as np
import pytest

from brdflab.bsdf.roughsubstrate import RoughSubstrate
from brdflab.math import warps


@pytest.mark.parametrize("theta_deg", [60.0, 80.0])
def test_bsdf_sampling_reaches_the_diffuse_lobe_under_total_internal_reflection(theta_deg):
    bsdf = RoughSubstrate(kd=np.array([0.8, 0.8, 0.8]), alpha=0.2, intIOR=1.0, extIOR=1.5)
    t = np.radians(theta_deg)  # critical angle asin(1/1.5) = 41.8°: both angles are beyond it
    n = 400_000
    rng = np.random.default_rng(7)
    wi = np.tile([np.sin(t), 0.0, np.cos(t)], (n, 1))
    # Albedo ∫ f cos dω by BSDF sampling (mean of the sample weights) ...
    s = bsdf.sample(wi, rng.random((n, 3)))
    est_bsdf = s.weight[:, 0]
    # ... and by uniform hemisphere sampling, which cannot miss a lobe.
    wo = warps.square_to_uniform_hemisphere(rng.random((n, 2)))
    est_uni = bsdf.eval(wi, wo)[:, 0] * wo[:, 2] * 2 * np.pi
    diff = est_bsdf.mean() - est_uni.mean()
    se = np.sqrt(est_bsdf.var() / n + est_uni.var() / n)
    assert abs(diff) < 5 * se, (est_bsdf.mean(), est_uni.mean(), se)
