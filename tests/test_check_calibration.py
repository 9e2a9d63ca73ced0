"""Calibration of ``brdflab check``'s statistics, pinned without relying on ``check`` itself.

(a) **Exact cases by hand.** Every pixel's noise is ±a on a checkerboard (the J user renders, or the K runs,
    are m ± a·s with s = ±1 alternating): every block holds as many + as − pixels, so a planted difference D
    is exactly the difference of block means; the per-pixel run-to-run variance is known exactly; the
    measured neighbour correlations are exactly ±1, which makes the correlation factor of
    :mod:`brdflab.stats.blocks` eq. (1) (Σ_d (−1)^(dx+dy) w(d) = 0.5625 < 1 for 16-pixel blocks) exactly
    1; the kurtosis of ±a is 1 < 3, so eq. (2) gives exactly n_eff degrees of freedom. The t of every block,
    its two-sided p, the Holm adjustment, the image-mean z and the verdict's p-value are then computed here
    by hand for each of the three variance methods (welch from runs or from a variance image, the
    single-render model with the spp scaling, the residual), and cases sit on either side of the
    threshold so that a one-sided p, a lost factor 2, a wrong spp or run-count scaling flips the verdict.
(b) **Measured calibration.** Synthetic images with a known per-pixel variance (Gaussian and heavy-tailed
    Gamma noise, pixels independent): the hand z of the image mean (from the true variance) against the z
    that ``check`` reports; the false-alarm rate of the mean test and of the blocks at the nominal level,
    and the power against a planted bias whose expected z is known, within exact binomial bounds.
"""

from __future__ import annotations

import math
import re
import warnings

import numpy as np
import pytest
from scipy import stats

from brdflab.stats.jobs import run_seed
from brdflab.stats.render_check import Estimate, check_images

S = 32  # image side: 2 × 2 blocks of 16 pixels, one scale only (32 > S / 2)
N_BLOCK = 256
N_IMAGE = S * S
M_TESTS = 4 * 3  # blocks × RGB in the Holm family
ALPHA = 0.01
#: Per-test threshold of the first Holm step when the three channels of one block tie.
FIRST_STEP = ALPHA / 2 / M_TESTS


def _checker() -> np.ndarray:
    yy, xx = np.mgrid[0:S, 0:S]
    return np.where((yy + xx) % 2 == 0, 1.0, -1.0)[..., None] * np.ones(3)


CHECK = _checker()
BASE = np.full((S, S, 3), 0.75)  # dyadic, as are the spreads: the runs' mean is exactly BASE


def _planted(d: float, block: tuple[int, int] = (0, 1)) -> np.ndarray:
    out = np.zeros((S, S, 3))
    by, bx = block
    out[16 * by:16 * by + 16, 16 * bx:16 * bx + 16] = d
    return out


def _pair(mean: np.ndarray, a: float) -> list[np.ndarray]:
    return [mean + a * CHECK, mean - a * CHECK]


def _t_for_p(p_two: float, df: float) -> float:
    """|t| whose two-sided p-value is ``p_two``."""
    return float(stats.t.isf(p_two / 2, df))


# -- (a) exact cases ------------------------------------------------------------------------------------------
A, B_ = 0.375, 0.25  # user and reference half-spreads (per-run pixel variance 2a², 2b² from two runs)
WELCH_VAR = (A * A + B_ * B_) / N_BLOCK  # Var D_b = Var mean_b(x̄) + Var mean_b(ȳ) = a²/n + b²/n
WELCH_DF = N_BLOCK * (A * A + B_ * B_) ** 2 / (A**4 + B_**4)  # Welch–Satterthwaite, n_eff = n per side


def _welch(d: float, block=(0, 1), alpha: float = ALPHA):
    user = _pair(BASE + _planted(d, block), A)
    return check_images(user, Estimate.from_runs(_pair(BASE, B_)), alpha=alpha, levels=1)


def test_welch_block_t_p_holm_and_mean_z_by_hand():
    t_hand = _t_for_p(2e-4, WELCH_DF)  # flagged: 12 · 2e-4 = 2.4e-3 ≤ α/2
    d = t_hand * math.sqrt(WELCH_VAR)
    r = _welch(d)
    assert r.method == "welch" and r.correlation_factor == pytest.approx(1.0, abs=1e-12)
    assert r.z_map[0, 1] == pytest.approx(t_hand, rel=1e-9) and r.z_map[0, 0] == r.z_map[1, 1] == 0.0
    assert len(r.flagged) == 1 and r.bright_blocks == 1 and r.dark_blocks == 0
    f = r.flagged[0]
    assert (f["x"], f["y"], f["w"], f["sign"]) == (16, 0, 16, "too bright")
    assert f["t"] == pytest.approx(t_hand, rel=1e-9)
    assert f["p_adjusted"] == pytest.approx(M_TESTS * 2e-4, rel=1e-6)  # Holm: 12 · p for the three tied RGB
    assert f["relative_difference"] == pytest.approx(d / 0.75, rel=1e-12)
    # Image mean: D/4 over the image, Var = (a² + b²)/N, normal reference distribution, two-sided.
    z_mean = d / 4 / math.sqrt((A * A + B_ * B_) / N_IMAGE)
    assert z_mean == pytest.approx(t_hand / 2)
    assert r.bias_p == pytest.approx(2 * stats.norm.sf(z_mean), rel=1e-9)
    assert r.bias == pytest.approx(d / 4 / 0.75, rel=1e-12)
    half = stats.norm.ppf(0.995) * math.sqrt((A * A + B_ * B_) / N_IMAGE) / 0.75
    assert r.bias_ci == pytest.approx((r.bias - half, r.bias + half), rel=1e-9)
    # Verdict p: Bonferroni of the two halves, min(1, 2 · min(p_mean, min adjusted block p)).
    assert r.p_value == pytest.approx(2 * min(r.bias_p, M_TESTS * 2e-4), rel=1e-6)
    assert not r.consistent
    # Smallest detectable biases at 80 % power: the mean test at α/4 per side (its α/2, two-sided), a block
    # at the first Holm level α/(2m) two-sided, with the block's t quantile (every block alike here).
    z80 = stats.norm.ppf(0.8)
    sd_mean = math.sqrt((A * A + B_ * B_) / N_IMAGE)
    assert r.min_detectable_bias == pytest.approx((stats.norm.isf(ALPHA / 4) + z80) * sd_mean / 0.75, rel=1e-9)
    t_crit = stats.t.isf(ALPHA / 2 / M_TESTS / 2, WELCH_DF)
    assert r.min_detectable_block_bias == pytest.approx((t_crit + z80) * math.sqrt(WELCH_VAR) / 0.75, rel=1e-6)
    lo, hi = r.bias_ci
    assert r.verdict().startswith(f"BIASED: p = {r.p_value:.3g}; image mean {100 * r.bias:+.2f} % "
                                  f"(99 % CI {100 * lo:+.2f} … {100 * hi:+.2f} %); 0 blocks too dark, "
                                  "1 too bright of 4; detectable: mean bias ≥ ")


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_two_sided_block_p_decides_the_verdict(sign):
    """Two-sided p = 6e-4 is not significant (12 · 6e-4 > α/2), its one-sided half 3e-4 would be;
    two-sided 3e-4 is significant in either direction (a one-sided test of the wrong side never is)."""
    t_miss, t_hit = _t_for_p(6e-4, WELCH_DF), _t_for_p(3e-4, WELCH_DF)
    assert M_TESTS * 3e-4 <= ALPHA / 2 < M_TESTS * 6e-4
    miss = _welch(sign * t_miss * math.sqrt(WELCH_VAR))
    assert miss.consistent and not miss.flagged and miss.z_map[0, 1] == pytest.approx(sign * t_miss, rel=1e-9)
    assert miss.p_value == pytest.approx(min(1.0, 2 * min(miss.bias_p, M_TESTS * 6e-4)), rel=1e-6)
    hit = _welch(sign * t_hit * math.sqrt(WELCH_VAR), block=(1, 0))
    assert not hit.consistent and hit.signed_map[1, 0] == int(sign) and hit.signed_map.sum() == int(sign)
    assert hit.flagged[0]["sign"] == ("too bright" if sign > 0 else "too dark")


def test_two_sided_mean_test_decides_the_verdict():
    """The image-mean test gets α/2 two-sided: z with 2·sf(|z|) just above α/2 passes, just below fails,
    for either sign (the blocks, at t = 2z spread over all four, stay far from their threshold)."""
    sd = math.sqrt((A * A + B_ * B_) / N_IMAGE)
    for sign in (1.0, -1.0):
        for p_two, consistent in ((0.0075, True), (0.004, False)):
            z = stats.norm.isf(p_two / 2)
            d = sign * z * sd
            user = _pair(BASE + d, A)  # uniform offset: every block t = 2z, two-sided block p ≫ α/24
            r = check_images(user, Estimate.from_runs(_pair(BASE, B_)), levels=1)
            assert r.bias_p == pytest.approx(p_two, rel=1e-6)
            assert not r.flagged and bool(r.consistent) == consistent, (sign, p_two)
            assert (r.bias_ci[1] < 0 if sign < 0 else r.bias_ci[0] > 0)  # |z| > z_0.995 in both cases


def test_welch_with_a_reference_variance_image():
    """A given reference with its per-pixel variance v (no runs): Var D_b = a²/n + v/n, df from the user's
    side only (the reference's are infinite): (a²/n + v/n)² / ((a²/n)² / n)."""
    v = 0.05
    d = 0.06
    user = _pair(BASE + _planted(d), A)
    est = Estimate(BASE.copy(), None, np.full((S, S, 3), v))
    r = check_images(user, est, levels=1)
    var = (A * A + v) / N_BLOCK
    df = N_BLOCK * ((A * A + v) / A**2) ** 2
    assert r.z_map[0, 1] == pytest.approx(d / math.sqrt(var), rel=1e-9)
    assert r.bias_p == pytest.approx(2 * stats.norm.sf(d / 4 / math.sqrt((A * A + v) / N_IMAGE)), rel=1e-9)
    p = 2 * stats.t.sf(d / math.sqrt(var), df)
    assert (not r.consistent) == bool(M_TESTS * p <= ALPHA / 2)


def _model(d: float, user_spp: int, run_spp: int, runs: int = 2, b: float = B_):
    """One user render x = m + D + a·s against ``runs`` runs m ± b·s (in pairs), with a² = the per-run
    pixel variance (Σ_k e²/(K − 1) = K b²/(K − 1)) · run_spp / user_spp: the noise the model predicts."""
    a = b * math.sqrt(runs / (runs - 1) * run_spp / user_spp)
    user = [BASE + _planted(d) + a * CHECK]
    ys = _pair(BASE, b) * (runs // 2)
    return check_images(user, Estimate.from_runs(ys, run_spp=run_spp), levels=1, user_spp=user_spp), a


@pytest.mark.parametrize(("user_spp", "run_spp"), [(64, 16), (16, 64), (32, 32)])
def test_model_scales_the_reference_variance_to_the_users_spp(user_spp, run_spp):
    """Single render, K = 2 runs: V_y = b²/n (two runs ±b: per-run variance 2b², mean of 2); the user's
    block variance is V_y · K · run_spp/user_spp (η = 1: the residual spread agrees with it), plus V_y.
    The t, the reported η and the mean test's z are pinned, so any other scaling (user/run inverted, K
    dropped, V_y not added) changes them."""
    k = 2
    scale = k * run_spp / user_spp
    var = (scale + 1.0) * B_ * B_ / N_BLOCK
    d = 0.05
    r, a = _model(d, user_spp, run_spp)
    assert r.method.startswith("model")
    assert float(re.search(r"η = ([0-9.]+)", r.method).group(1)) == pytest.approx(1.0)
    # The residual estimate a²/(n − 2) (mean and slope removed per block) is below the model here.
    assert a * a / (N_BLOCK - 2) < var
    assert r.z_map[0, 1] == pytest.approx(d / math.sqrt(var), rel=1e-9)
    # Image mean: the larger of the model, (K·run/user + 1)·b²/N, and the residual spread of the whole image,
    # F∞ · a² n/(n − 2) / N with F∞ of eq. (1) from the block-centred checkerboard (Σ ρ_c = 1 over the 7 × 7
    # lag window of W = 49 ones: F∞ = 1/(1 + (1 − 49)/n), see blocks.correlation_factor).
    f_inf = 1.0 / (1.0 + (1.0 - 49.0) / N_BLOCK)
    mean_var = max((scale + 1.0) * B_ * B_, f_inf * a * a * N_BLOCK / (N_BLOCK - 2)) / N_IMAGE
    z_mean = d / 4 / math.sqrt(mean_var)
    assert r.bias_p == pytest.approx(2 * stats.norm.sf(z_mean), rel=1e-9)


def test_model_spp_scaling_decides_the_verdict():
    """user 64 spp, runs 16 spp: Var D_b = (2·16/64 + 1) b²/n. A block at two-sided p = 1e-4 (df = n − 2,
    the residual's) is flagged; one at 6e-4 is not. Inverting the spp ratio (scale 8: 6× the variance)
    loses the first; dropping K (scale 0.25) flags the second."""
    var = 1.5 * B_ * B_ / N_BLOCK
    df = N_BLOCK - 2
    hit, _ = _model(_t_for_p(1e-4, df) * math.sqrt(var), 64, 16)
    miss, _ = _model(_t_for_p(6e-4, df) * math.sqrt(var), 64, 16)
    assert not hit.consistent and hit.bright_blocks == 1
    assert hit.flagged[0]["p_adjusted"] == pytest.approx(M_TESTS * 1e-4, rel=1e-3)
    assert miss.consistent and not miss.flagged


def test_model_variance_falls_with_more_reference_runs():
    """K = 4 runs (each pair ±b): per-run variance (4b²)/3, V_y = that/(4n); the user's variance is
    K · run_spp/user_spp · V_y, which does not depend on K."""
    k, user_spp, run_spp = 4, 32, 32
    vy = (4 * B_ * B_ / 3) / (k * N_BLOCK)
    var = (k * run_spp / user_spp + 1.0) * vy
    d = 0.05
    r, _ = _model(d, user_spp, run_spp, runs=4)
    assert r.z_map[0, 1] == pytest.approx(d / math.sqrt(var), rel=1e-9)


def test_residual_method_by_hand():
    """One render against a given reference without variance: Var D_b = Σ(r − r̄_b)² / ((n − 1) n) = a²/(n − 1),
    df = n − 1; a bias constant over the block is not spread."""
    var = A * A / (N_BLOCK - 1)
    d = _t_for_p(1e-4, N_BLOCK - 1) * math.sqrt(var)
    r = check_images([BASE + _planted(d) + A * CHECK], Estimate(BASE.copy()), levels=1)
    assert r.method == "residual"
    t = d / math.sqrt(var)
    assert r.z_map[0, 1] == pytest.approx(t, rel=1e-9)
    p = 2 * stats.t.sf(t, N_BLOCK - 1)
    assert (not r.consistent) == bool(M_TESTS * p <= ALPHA / 2)
    assert r.flagged and r.flagged[0]["p_adjusted"] == pytest.approx(M_TESTS * p, rel=1e-6)


# -- (b) measured calibration ----------------------------------------------------------------------------------
H = W = 32
_yy, _xx = np.mgrid[0:H, 0:W]
TRUTH = np.stack([0.5 + 0.4 * _xx / W, 0.8 + 0.1 * np.sin(_yy / 7.0), 0.6 + 0 * _xx], -1)


def _draw(rng: np.random.Generator, spp: int, kind: str) -> np.ndarray:
    """Mean of ``spp`` samples per pixel, each truth · X with E X = 1, Var X = 2 (independent pixels):
    Gaussian, or Gamma(½, 2) (heavy-tailed; the mean of spp of them is Gamma(spp/2, 2/spp))."""
    if kind == "gauss":
        return TRUTH * (1.0 + rng.standard_normal((H, W, 3)) * math.sqrt(2.0 / spp))
    return TRUTH * rng.gamma(0.5 * spp, 2.0 / spp, (H, W, 3))


#: Variance of the image mean of the channel average for one render at 1 spp: Σ_p Σ_c truth² · 2 / 9 / N².
MEAN_VAR_1SPP = float((TRUTH**2 * 2.0).sum() / 9.0 / (H * W) ** 2)


def _trials(kind: str, renders: int, n: int, bias: float = 0.0, alpha: float = ALPHA):
    """(hand z, reported z, mean rejected, any block flagged) over n seeded trials: user 32 spp, 4 runs × 8 spp."""
    warnings.simplefilter("ignore", RuntimeWarning)
    user_spp, run_spp, k = 32, 8, 4
    sd = math.sqrt(MEAN_VAR_1SPP * (1.0 / (user_spp * renders) + 1.0 / (run_spp * k)))
    out = []
    for t in range(n):
        rng = np.random.default_rng(run_seed(3000 + renders + (10 if kind == "gamma" else 0), t, "check"))
        xs = [_draw(rng, user_spp, kind) * (1.0 + bias) for _ in range(renders)]
        runs = [_draw(rng, run_spp, kind) for _ in range(k)]
        r = check_images(xs, Estimate.from_runs(runs, run_spp=run_spp), alpha=alpha, levels=1, user_spp=user_spp)
        d = float(np.mean(xs, axis=0).mean() - np.mean(runs, axis=0).mean())
        z_rep = math.copysign(stats.norm.isf(r.bias_p / 2), r.bias)
        out.append((d / sd, z_rep, r.bias_p <= alpha / 2, bool(r.flagged)))
    return np.array(out, dtype=float)


def _inside(count: int, n: int, rate: float, risk: float = 1e-3) -> bool:
    lo, hi = stats.binom.ppf(risk / 2, n, rate), stats.binom.isf(risk / 2, n, rate)
    return lo <= count <= hi


#: (noise, user renders, the lowest allowed ratio reported z / hand z). Welch (two user renders) estimates
#: each side's variance without a floor: calibrated. The single-render model takes the larger of two
#: variance estimates, η ≥ 1 and correlation factors F = max(1, F̂) measured on only 32 × 32 pixels:
#: conservative by design (measured median ratio ≈ 0.82 here, ≈ 0.96 at 64 × 64).
CASES = [("gauss", 2, 0.9), ("gamma", 1, 0.7)]


@pytest.mark.parametrize(("kind", "renders", "low"), CASES)
def test_false_alarm_rate_at_the_nominal_level(kind, renders, low):
    """150 unbiased trials at α = 0.2 (the mean test at α/2 = 0.1, the 12 block tests sharing 0.1):
    the reported z of the image mean is the hand z (true variance) within its band (median ratio: a
    variance scaled by 2 moves it by 30 %); the mean test's alarm count is inside the two-sided binomial
    range of 0.1 for the calibrated method (a one-sided test doubles it) and below its upper end for the
    conservative one; the block alarms stay below the hand-computed rate 1 − (1 − 0.1/12)^12."""
    n, alpha = 150, 0.2
    res = _trials(kind, renders, n, alpha=alpha)
    ratio = np.median(res[:, 1] / res[:, 0])
    assert low < ratio < 1.1, ratio
    assert abs(np.std(res[:, 0]) - 1.0) < 0.2  # the hand z is itself a unit normal (the test's own control)
    alarms = int(res[:, 2].sum())
    if low >= 0.9:
        assert _inside(alarms, n, alpha / 2), alarms
    else:
        assert alarms <= stats.binom.isf(1e-3, n, alpha / 2), alarms
    block_rate = 1 - (1 - alpha / 2 / M_TESTS) ** M_TESTS
    assert res[:, 3].sum() <= stats.binom.isf(1e-3, n, block_rate), res[:, 3].sum()


def _power(delta: float) -> float:
    zc = stats.norm.isf(ALPHA / 4)
    return float(stats.norm.sf(zc - delta) + stats.norm.cdf(-zc - delta))


@pytest.mark.parametrize(("kind", "renders", "low"), CASES)
def test_power_against_a_planted_bias(kind, renders, low):
    """User renders 1.7 % too bright (hand z ≈ 3): the mean test's power P(|N(δ, 1)| > z_{1−α/4}) is
    computed here from the hand δ; the detections over 100 trials are inside its binomial range
    (conservative method: between the power at δ · low and at δ), all in the right direction."""
    n, bias = 100, 0.017
    res = _trials(kind, renders, n, bias=bias)
    delta = float(np.mean(res[:, 0]))  # the mean hand z of the biased trials (its noise part averages out)
    assert 0.3 < _power(delta) < 0.8, _power(delta)  # a discriminating operating point
    hits = int(res[:, 2].sum())
    assert stats.binom.ppf(5e-4, n, _power(low * delta)) <= hits <= stats.binom.isf(5e-4, n, _power(delta)), hits
    assert np.all(res[res[:, 2] > 0, 1] > 0)  # every rejection in the right direction


def test_non_finite_pixels_are_left_out_by_hand():
    """Two adjacent pixels (one + and one − of the checkerboard) NaN in one user render: the block keeps
    n − 2 pixels and its planted difference D; Var D_b = (a² + b²)/(n − 2); the image mean is D (n − 2)/(N − 2)
    with variance (a² + b²)/(N − 2)."""
    d = 0.05
    user = _pair(BASE + _planted(d), A)
    user[0][3, 20:22] = np.nan
    r = check_images(user, Estimate.from_runs(_pair(BASE, B_)), levels=1)
    assert r.nonfinite == 2
    assert r.z_map[0, 1] == pytest.approx(d / math.sqrt((A * A + B_ * B_) / (N_BLOCK - 2)), rel=1e-9)
    z_mean = d * (N_BLOCK - 2) / (N_IMAGE - 2) / math.sqrt((A * A + B_ * B_) / (N_IMAGE - 2))
    assert r.bias_p == pytest.approx(2 * stats.norm.sf(z_mean), rel=1e-9)
    assert r.bias == pytest.approx(d * (N_BLOCK - 2) / (N_IMAGE - 2) / 0.75, rel=1e-9)


@pytest.mark.parametrize("noisier", [1.0, 2.0])
def test_scan_window_by_hand(noisier):
    """64 × 64, one render (model): a +D patch on exactly 2 × 2 base blocks at (16, 16). Each base block has
    t = D/√((K·run/user + 1) b²/256) ≈ 2.1 (not significant among the 75 tests: 16 blocks + 9 windows of 32,
    × RGB); the 32-pixel window of the scan has n = 1024, t twice that (df = n − 2, the residual's), and is
    the one flagged, with Holm's 75 · p. ``noisier`` = 2: the user's render has twice the predicted spread,
    so η = (a²/254)/((K·run/user + 1) b²/256) > 1 and the residual a²/(n − 2) is the variance of every
    block and window."""
    s, k, user_spp, run_spp, b = 64, 2, 64, 16, B_
    yy, xx = np.mgrid[0:s, 0:s]
    checker = np.where((yy + xx) % 2 == 0, 1.0, -1.0)[..., None] * np.ones(3)
    base = np.full((s, s, 3), 0.75)
    a = noisier * b * math.sqrt(k / (k - 1) * run_spp / user_spp)
    scale = k * run_spp / user_spp
    t_window = _t_for_p(2.9e-5, 1022)
    model = (scale + 1) * b * b
    d = t_window * math.sqrt((model if noisier == 1 else a * a * 1024 / 1022) / 1024)
    x = base + a * checker
    x[16:48, 16:48] += d
    r = check_images([x], Estimate.from_runs([base + b * checker, base - b * checker], run_spp=run_spp),
                     user_spp=user_spp)
    assert r.scales == [16, 32] and r.method.startswith("model")
    eta = float(re.search(r"η = ([0-9.]+)", r.method).group(1))
    if noisier == 1:
        np.testing.assert_allclose(r.z_map[1:3, 1:3], t_window / 2, rtol=1e-9)
        assert eta == 1.0
    else:
        np.testing.assert_allclose(r.z_map[1:3, 1:3], d / math.sqrt(a * a / 254), rtol=1e-9)
        assert eta == pytest.approx((a * a / 254) / (model / 256), abs=0.006)
    assert len(r.flagged) == 1
    f = r.flagged[0]
    assert (f["x"], f["y"], f["w"], f["h"], f["sign"]) == (16, 16, 32, 32, "too bright")
    assert f["t"] == pytest.approx(t_window, rel=1e-9)
    assert f["p_adjusted"] == pytest.approx(75 * 2.9e-5, rel=1e-6)
    assert r.bright_blocks == 4 and r.dark_blocks == 0  # the window marks the base blocks it covers


@pytest.mark.parametrize("level", [1.0, 0.01])
def test_residual_method_removes_one_global_gain_by_hand(level):
    """A given reference ȳ that varies inside every block (the same ramp in each), a user render
    (1 + ε)·ȳ + a·s: the one global fit r ≈ c·ȳ takes c = ε exactly (the checkerboard is orthogonal to the
    ramp), so the spread left is a·s alone: Var D_b = a²/(n − 1) with D_b = ε·mean(ȳ); the uniform bias is not
    taken for noise. ``level`` 0.01: a dim image (Σ ȳ² < 1) is fitted alike."""
    yy, xx = np.mgrid[0:S, 0:S]
    ref = level * (0.75 + 0.02 * ((xx % 16) - 7.5))[..., None] * np.ones(3)
    eps = 0.01
    user = (1 + eps) * ref + level * A * CHECK
    r = check_images([user], Estimate(ref.copy()), levels=1)
    assert r.method == "residual"
    t = eps * 0.75 / math.sqrt(A * A / (N_BLOCK - 1))
    np.testing.assert_allclose(r.z_map, t, rtol=1e-9)


def test_a_black_image_and_a_given_reference_are_reported_as_such():
    """All-black reference and render: no bias ratio, no interval (not ±∞), consistent; a given reference
    reports no runs and no spp."""
    from brdflab.stats.render_check import run_check

    black = np.zeros((S, S, 3))
    r = check_images([black], Estimate(black.copy()), levels=1)
    assert r.consistent and math.isnan(r.bias) and all(math.isnan(v) for v in r.bias_ci)
    lit = black.copy()
    lit[:2, :2] = 0.5  # light where the reference is black: still no ratio to a mean of 0
    r = check_images([lit], Estimate(black.copy()), levels=1)
    assert math.isnan(r.bias) and all(math.isnan(v) for v in r.bias_ci)
    res = run_check([BASE + A * CHECK], "unused.xml", "direct_ems", ref=BASE.copy(), levels=1)
    assert (res.reference_runs, res.reference_spp, res.reference_label) == (0, 0, "given reference")


def test_partial_edge_block_by_hand():
    """40 × 32 image: the bottom row of blocks is 8 pixels high (n = 128). A difference D there has
    t = D/√((a² + b²)/128) and is reported as a 16 × 8 block."""
    h = 40
    yy, xx = np.mgrid[0:h, 0:S]
    checker = np.where((yy + xx) % 2 == 0, 1.0, -1.0)[..., None] * np.ones(3)
    base = np.full((h, S, 3), 0.75)
    t = _t_for_p(1e-5, 200)
    d = t * math.sqrt((A * A + B_ * B_) / 128)
    shifted = base.copy()
    shifted[32:, :16] += d
    r = check_images([shifted + A * checker, shifted - A * checker],
                     Estimate.from_runs([base + B_ * checker, base - B_ * checker]), levels=1)
    assert r.z_map.shape == (3, 2) and r.z_map[2, 0] == pytest.approx(t, rel=1e-9)
    assert [(f["x"], f["y"], f["w"], f["h"]) for f in r.flagged] == [(0, 32, 16, 8)]


def test_degrees_of_freedom_follow_the_correlation_factor():
    """Noise constant on 4 × 4 squares (neighbours correlated: F > 1). Whatever F the image gives, a block's
    degrees of freedom in the residual method are n_eff = n/F − 1 (eq. (2), κ = 1 < 3): the Holm-adjusted p of
    the flagged block is 12 · 2·sf(t, n_eff)."""
    yy, xx = np.mgrid[0:S, 0:S]
    squares = np.where((yy // 4 + xx // 4) % 2 == 0, 1.0, -1.0)[..., None] * np.ones(3)
    d = 0.2
    user = BASE + _planted(d) + A * squares
    r = check_images([user], Estimate(BASE.copy()), levels=1)
    f = r.correlation_factor
    assert f > 1.1
    t = r.z_map[0, 1]
    assert r.flagged[0]["p_adjusted"] == pytest.approx(M_TESTS * 2 * stats.t.sf(t, N_BLOCK / f - 1), rel=1e-6)
