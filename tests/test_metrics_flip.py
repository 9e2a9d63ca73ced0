"""compare: HDR-FLIP (exposures fixed by the reference), --crop region statistics, signed difference maps."""

from __future__ import annotations

import json

import numpy as np
import pytest

from brdflab.cli.main import main
from brdflab.imageio import write_exr
from brdflab.pages.metrics import compare, flip_error, flip_parameters, signed_difference


def test_flip_orders_errors_and_fixes_exposure_by_reference():
    rng = np.random.default_rng(1616)
    ref = (rng.random((24, 32, 3)) * 4).astype(np.float32)
    params = flip_parameters(ref)
    assert params["startExposure"] <= params["stopExposure"] and params["numExposures"] >= 1
    small = ref * (1 + 0.05 * rng.standard_normal(ref.shape)).astype(np.float32)
    large = ref * (1 + 0.5 * rng.standard_normal(ref.shape)).clip(0).astype(np.float32)
    assert flip_error(ref, ref, params) == pytest.approx(0.0, abs=1e-6)
    e_small, e_large = flip_error(small, ref, params), flip_error(large, ref, params)
    assert 0 < e_small < e_large <= 1
    assert flip_error(small, ref) == pytest.approx(e_small, rel=1e-6)  # default: the reference's exposures


def test_signed_difference_by_hand():
    ref = np.array([[[1.0, 1.0, 1.0], [0.0, 0.0, 0.0]]])
    x = np.array([[[0.5, 0.5, 0.5], [0.01, 0.01, 0.01]]])
    assert signed_difference(x, ref)[0].tolist() == pytest.approx([-0.5 / 1.01, 1.0])


def test_compare_crop_and_maps(tmp_path, capsys):
    rng = np.random.default_rng(1617)
    ref = (rng.random((20, 30, 3)) + 0.1).astype(np.float32)
    test = ref.copy()
    test[5:10, 10:20] *= 0.8  # a darker region
    write_exr(tmp_path / "r.exr", ref)
    write_exr(tmp_path / "t.exr", test)
    assert main(["compare", str(tmp_path / "t.exr"), str(tmp_path / "r.exr"), "--crop", "10,5,10,5", "--json",
                 "--signed", str(tmp_path / "s.png"), "--no-flip"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["bias"] == pytest.approx(-0.2, rel=1e-5) and out["pixels"] == 50 and out["crop"] == [10, 5, 10, 5]
    assert out["mse"] == pytest.approx(compare(test[5:10, 10:20], ref[5:10, 10:20]).mse, rel=1e-9)
    assert (tmp_path / "s.png").stat().st_size > 1000
    assert main(["compare", str(tmp_path / "t.exr"), str(tmp_path / "r.exr"), "--crop", "25,0,10,5"]) == 2
    assert "not inside" in capsys.readouterr().err
    assert main(["compare", str(tmp_path / "t.exr"), str(tmp_path / "r.exr"), "--crop", "1,2,3"]) == 2
