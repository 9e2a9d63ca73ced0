"""brdflab's roughconductor and roughdielectric against values from Mitsuba 3.9's ``roughconductor`` and
``roughdielectric`` (scalar_rgb, float32, radiance mode), kept as numbers in ``tests/data/mitsuba_rough*.json`` by
``benchmarks/mitsuba_oracle.py --fixture`` (no Mitsuba code here).

f·cos θ_o and the pdf agree to float32 rounding (< 1e-4 relative, median ~2e-7 on 10⁵ pairs: docs/benchmarks.md),
except the pdf of Beckmann with visible normals: Mitsuba's uses the rational G1, brdflab's the exact erf G1 that
its sampler realises (they differ by ≤ 0.35 %). A model with a planted difference (α_u and α_v exchanged) must
disagree. The dielectric's pairs cover reflection and transmission from both sides; without visible normals
Mitsuba's roughdielectric samples D cos θ_h of α widened by s = 1.2 − 0.2 √|cos θ_i|, so its pdf is brdflab's pdf of
that widened α (the rest of the density — F or 1 − F, the Jacobians — is compared).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from brdflab import RoughConductor, RoughDielectric

DATA = json.loads((Path(__file__).parent / "data" / "mitsuba_roughconductor.json").read_text())
CASES = list(DATA["configs"])
GLASS = json.loads((Path(__file__).parent / "data" / "mitsuba_roughdielectric.json").read_text())


def _values(params: dict, case: dict) -> tuple[np.ndarray, np.ndarray]:
    wi, wo = np.array(case["wi"]), np.array(case["wo"])
    f, p = RoughConductor(**params).eval_pdf(wi, wo)
    return f * wo[:, 2:], p


@pytest.mark.parametrize("name", CASES)
def test_agrees_with_mitsuba(name):
    case = DATA["configs"][name]
    fc, p = _values(case["params"], case)
    np.testing.assert_allclose(fc, case["f_cos"], rtol=1e-4, atol=1e-30)
    beckmann_visible = case["params"]["distribution"] == "beckmann" and case["params"]["sample_visible"]
    np.testing.assert_allclose(p, case["pdf"], rtol=4e-3 if beckmann_visible else 1e-4, atol=1e-30)


def test_a_planted_difference_disagrees():
    name = "ggx aniso 0.2/0.45 visible Cu"
    case = DATA["configs"][name]
    swapped = {**case["params"], "alpha_u": case["params"]["alpha_v"], "alpha_v": case["params"]["alpha_u"]}
    fc, _ = _values(swapped, case)
    assert np.max(np.abs(fc - case["f_cos"]) / np.abs(case["f_cos"])) > 1e-2


def _glass(params: dict, case: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """f·|cos θ_o|, the pdf, and the pdf of Mitsuba's sampler (the widened α without visible normals)."""
    wi, wo = np.array(case["wi"]), np.array(case["wo"])
    f, p = RoughDielectric(**GLASS["iors"], **params).eval_pdf(wi, wo)
    if params["sample_visible"]:
        return f * np.abs(wo[:, 2:]), p, p
    s = 1.2 - 0.2 * np.sqrt(np.abs(wi[:, 2]))
    widened = [RoughDielectric(**GLASS["iors"], **{**params, "alpha_u": params["alpha_u"] * k,
                                                   "alpha_v": params["alpha_v"] * k}) for k in s]
    pw = np.array([m.pdf(wi[i:i + 1], wo[i:i + 1])[0] for i, m in enumerate(widened)])
    return f * np.abs(wo[:, 2:]), p, pw


@pytest.mark.parametrize("name", list(GLASS["configs"]))
def test_roughdielectric_agrees_with_mitsuba(name):
    case = GLASS["configs"][name]
    wi, wo = np.array(case["wi"]), np.array(case["wo"])
    assert (wi[:, 2] < 0).sum() >= 8 and (wi[:, 2] * wo[:, 2] < 0).sum() >= 8  # both sides, both lobes
    fc, p, pw = _glass(case["params"], case)
    np.testing.assert_allclose(fc, case["f_cos"], rtol=1e-4, atol=1e-30)
    beckmann_visible = case["params"]["distribution"] == "beckmann" and case["params"]["sample_visible"]
    np.testing.assert_allclose(pw, case["pdf"], rtol=4e-3 if beckmann_visible else 1e-4, atol=1e-30)
    if not case["params"]["sample_visible"]:  # the widening is real: brdflab's own density differs
        nz = np.array(case["pdf"]) > 0
        assert np.max(np.abs(p[nz] - np.array(case["pdf"])[nz]) / np.array(case["pdf"])[nz]) > 1e-2


def test_roughdielectric_planted_difference_disagrees():
    case = GLASS["configs"]["ggx aniso 0.15/0.45 visible"]
    swapped = {**case["params"], "alpha_u": case["params"]["alpha_v"], "alpha_v": case["params"]["alpha_u"]}
    fc, _, _ = _glass(swapped, case)
    ref = np.array(case["f_cos"])
    nz = ref > 0
    assert np.max(np.abs(fc[nz] - ref[nz]) / ref[nz]) > 1e-2
