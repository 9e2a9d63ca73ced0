"""Estimator agreement's statistics by hand: the per-block Welch test with its tolerance, and the Šidák
family-wise p-value over pairs and blocks (renders replaced by fixed replicate means)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from brdflab.judges.estimators import agreement as ag


def test_compare_blocks_by_hand():
    a = np.array([[1.0, 2.0, 3.0, 0.0], [3.0, 2.0, 3.0, 0.0], [5.0, 2.0, 3.0, 0.0]])
    b = np.array([[2.0, 2.0, 1.0, 0.0], [2.0, 2.0, 1.0, 0.0], [2.0, 2.0, 1.0, 0.0]])
    p = ag.compare_blocks(a, b)
    ma, mb = a.mean(axis=0), b.mean(axis=0)
    tol = ag.REL_TOL * 0.5 * np.abs(ma + mb) + ag.ABS_TOL * 0.5 * abs(ma.mean() + mb.mean())
    # block 0: va = 4/3 (var 4, 3 reps), vb = 0: Welch df = (4/3)² / ((4/3)²/2) = 2
    t0 = (abs(3.0 - 2.0) - tol[0]) / math.sqrt(4 / 3)
    assert p[0] == pytest.approx(2 * stats.t.sf(t0, 2), rel=1e-12)
    assert math.isnan(p[1])  # both constant and equal: no signal
    assert p[2] == 0.0  # both constant, different beyond the tolerance
    assert math.isnan(p[3])
    # Within the tolerance: no disagreement.
    c = a.copy()
    c[:, 2] = 1.0 + 0.5 * tol[2]
    assert math.isnan(ag.compare_blocks(c, b)[2])


def test_family_wise_p_over_pairs_and_blocks(monkeypatch):
    class Fake:
        emitters = []

    data = {"direct_ems": np.array([[1.0, 2.0], [1.2, 2.2], [0.8, 1.8], [1.0, 2.0]]),
            "direct_mats": np.array([[1.1, 2.0], [1.3, 2.1], [0.9, 1.9], [1.1, 2.0]]),
            "direct_mis": np.array([[1.0, 2.4], [1.2, 2.6], [0.8, 2.2], [1.0, 2.4]])}
    order = iter(ag.ESTIMATORS)
    monkeypatch.setattr(ag, "_load", lambda path, est, *args: Fake())
    monkeypatch.setattr(ag, "block_means", lambda s, spp, reps, block, seed: data[next(order)])
    r = ag.estimator_agreement("x.xml", reps=4)
    ps = np.concatenate([ag.compare_blocks(data[x], data[y]) for x, y in
                         (("direct_ems", "direct_mats"), ("direct_ems", "direct_mis"),
                          ("direct_mats", "direct_mis"))])
    m = int(np.isfinite(ps).sum())
    assert r.tests == m == 6
    assert r.p_value == pytest.approx(1 - (1 - np.nanmin(ps)) ** m, rel=1e-9)
    assert r.passed is (r.p_value > 0.01)
    assert r.means == pytest.approx({k: float(v.mean()) for k, v in data.items()})


def test_block_means_are_rec709_luminance(tmp_path):
    from brdflab.scene.loader import load_scene
    from tests.conftest import write_scene

    class Colour:
        needs_emitters = False

        def li(self, scene, o, d, tmax, rng):
            return np.tile([0.2, 0.5, 0.8], (len(d), 1)) * (1.0 + (d[:, :1] > 0))  # camera left half twice as bright

    body = ('<integrator type="normals"/><camera type="perspective"><integer name="width" value="8"/>'
            '<integer name="height" value="4"/><rfilter type="box"/></camera>')
    s = load_scene(write_scene(tmp_path, body))
    s.integrator = Colour()
    m = ag.block_means(s, spp=2, reps=2, block=4, seed=3)
    y = 0.2 * 0.212671 + 0.5 * 0.715160 + 0.8 * 0.072169
    assert m.shape == (2, 2)
    np.testing.assert_allclose(m, [[2 * y, y], [2 * y, y]], rtol=1e-6)  # camera +x is the image's left


def test_no_comparison_is_no_pass(monkeypatch):
    """Every block constant and equal in every estimator: no comparison, p = 0, not passed."""

    class Fake:
        emitters = []

    monkeypatch.setattr(ag, "_load", lambda path, est, *args: Fake())
    monkeypatch.setattr(ag, "block_means", lambda *a: np.ones((4, 3)))
    r = ag.estimator_agreement("x.xml", reps=4)
    assert r.tests == 0 and r.p_value == 0.0 and not r.passed
