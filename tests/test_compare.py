"""``brdflab compare``: metrics against hand-computed values, errors, heatmap."""

from __future__ import annotations

import json

import numpy as np
import pytest

from brdflab.cli.main import main
from brdflab.errors import ImageError
from brdflab.imageio import write_exr
from brdflab.pages.metrics import compare


def test_hand_computed_values():
    ref = np.array([[[1.0, 2.0, 0.0], [0.5, 0.5, 0.5]]])  # 1×2 pixels
    x = np.array([[[1.5, 2.0, 0.1], [0.5, 0.0, 0.5]]])
    m = compare(x, ref)
    d2 = np.array([0.25, 0.0, 0.01, 0.0, 0.25, 0.0])
    r2 = np.array([1.0, 4.0, 0.0, 0.25, 0.25, 0.25])
    assert m.mse == pytest.approx(d2.mean(), rel=1e-12)
    assert m.rmse == pytest.approx(np.sqrt(d2.mean()), rel=1e-12)
    assert m.relmse == pytest.approx(np.mean(d2 / (r2 + 0.01)), rel=1e-12)
    assert m.mape == pytest.approx(np.mean(np.sqrt(d2) / (np.sqrt(r2) + 0.01)), rel=1e-12)
    assert m.bias == pytest.approx(x.mean() / ref.mean() - 1, rel=1e-12)
    assert m.per_channel["R"]["mse"] == pytest.approx(0.125)
    assert m.per_channel["G"]["relmse"] == pytest.approx(0.25 / 0.26 / 2)


def test_nonfinite_pixels_are_counted_and_excluded():
    ref = np.ones((2, 2, 3))
    x = np.ones((2, 2, 3))
    x[0, 0, 1] = np.nan
    x[1, 1, 0] = np.inf
    m = compare(x, ref)
    assert m.nonfinite == 2 and m.mse == 0.0


def test_mismatches_are_clear_errors():
    with pytest.raises(ImageError, match="sizes differ"):
        compare(np.zeros((2, 3, 3)), np.zeros((3, 2, 3)))
    with pytest.raises(ImageError, match="channel counts differ"):
        compare(np.zeros((2, 2, 3)), np.zeros((2, 2, 4)))


def test_cli_json_and_heatmap(tmp_path, capsys):
    rng = np.random.default_rng(0)
    ref = rng.random((16, 20, 3)).astype(np.float32) + 0.1
    test = (ref + 0.05 * rng.standard_normal(ref.shape)).astype(np.float32)
    write_exr(tmp_path / "r.exr", ref)
    write_exr(tmp_path / "t.exr", test)
    assert main(["compare", str(tmp_path / "t.exr"), str(tmp_path / "r.exr"), "--json",
                 "--heatmap", str(tmp_path / "h.png")]) == 0
    out = json.loads(capsys.readouterr().out)
    d = test.astype(np.float64) - ref
    assert out["mse"] == pytest.approx(np.mean(d * d), rel=1e-6)
    assert (tmp_path / "h.png").stat().st_size > 1000
    write_exr(tmp_path / "small.exr", ref[:8])
    assert main(["compare", str(tmp_path / "small.exr"), str(tmp_path / "r.exr")]) == 2
    assert "sizes differ" in capsys.readouterr().err
