"""Confidence intervals and corrections of :mod:`brdflab.stats.intervals`, computed here by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from brdflab.stats import intervals as iv

VALUES = [1.0, 2.0, 4.0, 5.0]  # mean 3, sample variance (4 + 1 + 1 + 4)/3 = 10/3


def test_t_interval_by_hand():
    m, lo, hi = iv.t_interval(VALUES)  # default level 0.95
    half = stats.t.ppf(0.975, 3) * math.sqrt(10 / 3) / 2
    assert (m, lo, hi) == pytest.approx((3.0, 3.0 - half, 3.0 + half), rel=1e-12)
    m, lo, hi = iv.t_interval(VALUES, 0.99)
    half = stats.t.ppf(0.995, 3) * math.sqrt(10 / 3) / 2
    assert (lo, hi) == pytest.approx((3.0 - half, 3.0 + half), rel=1e-12)
    m, lo, hi = iv.t_interval([2.5])
    assert m == 2.5 and math.isnan(lo) and math.isnan(hi)


def test_positive_interval_by_hand():
    m, lo, hi = iv.positive_interval(VALUES)  # default level 0.95, log scale: half = t·s/(√K·X̄)
    half = stats.t.ppf(0.975, 3) * math.sqrt(10 / 3) / 2 / 3
    assert (m, lo, hi) == pytest.approx((3.0, 3.0 * math.exp(-half), 3.0 * math.exp(half)), rel=1e-12)
    assert lo * hi == pytest.approx(9.0)  # symmetric on log scale
    assert math.isnan(iv.positive_interval([1.0])[1]) and math.isnan(iv.positive_interval([-1.0, 0.5])[2])


def test_welch_df_by_hand():
    # v = (2, 1), df = (4, 9): (3)² / (4/4 + 1/9) = 9 / (10/9) = 8.1
    assert float(iv.welch_df([2.0, 1.0], [4.0, 9.0])) == pytest.approx(8.1, rel=1e-12)
    assert float(iv.welch_df([2.0, 1.0], [np.inf, 9.0])) == pytest.approx(81.0, rel=1e-12)
    assert float(iv.welch_df([0.0, 0.0], [3.0, 3.0])) == math.inf


def test_mean_interval_by_hand():
    lo, hi = iv.mean_interval(1.0, 4.0, 5.0, 0.9)
    q = stats.t.ppf(0.95, 5)
    assert (lo, hi) == pytest.approx((1 - 2 * q, 1 + 2 * q), rel=1e-12)
    lo, hi = iv.mean_interval(1.0, 4.0, math.inf, 0.9)
    assert (lo, hi) == pytest.approx((1 - 2 * stats.norm.ppf(0.95), 1 + 2 * stats.norm.ppf(0.95)), rel=1e-12)


def test_log_ratio_interval_by_hand():
    a, b = [2.0, 4.0, 6.0], [1.0, 3.0]
    ratio, lo, hi = iv.log_ratio_interval(a, b)  # default level 0.95
    va = 4.0 / 3 / 16  # var(a)/K/mean² = 4/3/4²
    vb = 2.0 / 2 / 4  # 2/2/2²
    df = (va + vb) ** 2 / (va**2 / 2 + vb**2 / 1)
    half = stats.t.ppf(0.975, df) * math.sqrt(va + vb)
    assert ratio == pytest.approx(2.0)
    assert (lo, hi) == pytest.approx((2 * math.exp(-half), 2 * math.exp(half)), rel=1e-12)
    assert math.isnan(iv.log_ratio_interval([1.0], [2.0, 3.0])[1])


def test_holm_by_hand():
    p = np.array([0.04, 0.001, 0.03, 0.2, 0.011])
    rej, adj = iv.holm(p, 0.05)
    # sorted: 0.001·5, 0.011·4, 0.03·3, 0.04·2, 0.2·1 → running max
    assert adj.tolist() == pytest.approx([0.09, 0.005, 0.09, 0.2, 0.044])
    assert rej.tolist() == [False, True, False, False, True]
    rej, adj = iv.holm(np.array([[0.5, 0.6], [0.3, 0.9]]), 0.05)  # m·p > 1: capped at 1, shape kept
    assert adj.tolist() == [[1.0, 1.0], [1.0, 1.0]] and not rej.any()
    rej, adj = iv.holm(np.array([]), 0.05)
    assert rej.size == 0 and adj.size == 0


def test_block_statistics_by_hand():
    from brdflab.stats import blocks as B

    # eq. (1): F = Σ_d ρ(d)(1 − |d_x|/s)(1 − |d_y|/s) over the lag window, F∞ = Σ_d ρ(d), at least 1.
    rho = {(0, 1): np.array([0.5]), (0, -1): np.array([0.5]), (1, 1): np.array([0.2]), (-1, -1): np.array([0.2])}
    assert B.correlation_factor(rho, 4, 1)[0] == pytest.approx(1 + 2 * 0.5 * 0.75 + 2 * 0.2 * 0.75 * 0.75)
    assert B.correlation_factor(rho, None, 1)[0] == pytest.approx(1 + 2 * 0.5 + 2 * 0.2)
    neg = {(0, 1): np.array([-0.4]), (0, -1): np.array([-0.4])}
    assert B.correlation_factor(neg, 4, 1)[0] == 1.0  # conservative floor
    # Centred on n-pixel block means: F = S_c / (1 + (S_c − W)/n), W = Σ weights.
    s_c, w = 1 + 2 * 0.5 * 0.75, 1 + 2 * 0.75
    half = {(0, 1): np.array([0.5]), (0, -1): np.array([0.5])}
    assert B.correlation_factor(half, 4, 1, centred_in=16)[0] == pytest.approx(s_c / (1 + (s_c - w) / 16))
    # eq. (2): κ = n Σe⁴ / (Σe²)², at least 3; df = 2 n_eff / (κ − 1).
    e = np.array([4.0, 0.0, 0.0, 0.0]).reshape(1, 2, 2, 1)  # κ = 4 · 256 / 16² = 4
    valid = np.ones((2, 2), bool)
    assert B.kurtosis_df(e, valid, 2, np.array([[[6.0]]]))[0, 0, 0] == pytest.approx(2 * 6 / 3)
    small = np.array([0.4, 0.0, 0.0, 0.0]).reshape(1, 2, 2, 1)  # the same κ = 4 at any scale (Σe² < 1 too)
    assert B.kurtosis_df(small, valid, 2, np.array([[[6.0]]]))[0, 0, 0] == pytest.approx(2 * 6 / 3)
    e = np.array([1.0, -1.0, 3.0, -3.0]).reshape(1, 2, 2, 1)  # κ = 4 · 164 / 400 < 3 → 3
    assert B.kurtosis_df(e, valid, 2, np.array([[[6.0]]]))[0, 0, 0] == pytest.approx(6.0)
    # Blocks of a 5 × 7 image with side 4: 2 × 2 blocks, edge blocks partial, expand back to pixels.
    assert B.grid((5, 7), 4) == (2, 2)
    a = np.arange(35, dtype=float).reshape(5, 7, 1)
    s = B.block_sum(a, 4)
    assert s[:, :, 0].tolist() == [[a[:4, :4].sum(), a[:4, 4:].sum()], [a[4:, :4].sum(), a[4:, 4:].sum()]]
    assert B.expand(s, 4, (5, 7))[4, 6, 0] == s[1, 1, 0] and B.expand(s, 4, (5, 7)).shape == (5, 7, 1)
    for shape in ((8, 7), (5, 8), (8, 8)):  # only one side (or neither) a multiple of the block
        a = np.arange(shape[0] * shape[1], dtype=float).reshape(*shape, 1)
        s = B.block_sum(a, 4)
        assert s.shape == (-(-shape[0] // 4), -(-shape[1] // 4), 1) and s.sum() == a.sum()
        assert s[-1, -1, 0] == a[4:, 4:].sum()
    # A block without residual (a black region): the normal-theory count, finite.
    zero = np.zeros((1, 2, 2, 1))
    assert B.kurtosis_df(zero, valid, 2, np.array([[[6.0]]]))[0, 0, 0] == pytest.approx(6.0)
