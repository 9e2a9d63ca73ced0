"""brdflab's roughconductor against values from Mitsuba 3.9's ``roughconductor`` (scalar_rgb, float32), kept as numbers
in ``tests/data/mitsuba_roughconductor.json`` by ``benchmarks/mitsuba_oracle.py --fixture`` (no Mitsuba code here).

f·cos θ_o and the pdf agree to float32 rounding (< 1e-4 relative, median ~2e-7 on 10⁵ pairs: docs/benchmarks.md),
except the pdf of Beckmann with visible normals: Mitsuba's uses the rational G1, brdflab's the exact erf G1 that
its sampler realises (they differ by ≤ 0.35 %). A model with a planted difference (α_u and α_v exchanged) must
disagree.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from brdflab import RoughConductor

DATA = json.loads((Path(__file__).parent / "data" / "mitsuba_roughconductor.json").read_text())
CASES = list(DATA["configs"])


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
