"""The chi-square and furnace machinery on exact small cases computed by hand.

Pearson's X² with pooling of small expected counts and its degrees of freedom; the failed-sample category;
the Šidák per-test level; the pass/fail boundaries; the furnace's Monte Carlo standard error, luminance,
combined error bar and its agreement and energy bounds.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

import brdflab as bl
from brdflab.judges.material import chi2 as c2
from brdflab.judges.material.furnace import LUMINANCE, AlbedoPoint, albedo_monte_carlo
from brdflab.stats import intervals


# -- Pearson ------------------------------------------------------------------------------------------------
def test_pearson_pools_small_bins_into_one_and_merges_a_small_pool():
    # Expected 3 + 0.5 = 3.5 < 5: the pool is merged into the last regular bin (30 + 3.5).
    obs = np.array([10.0, 20.0, 30.0, 2.0, 1.0])
    exp = np.array([12.0, 18.0, 30.0, 3.0, 0.5])
    stat, dof, p = c2.pearson(obs, exp)
    hand = (10 - 12) ** 2 / 12 + (20 - 18) ** 2 / 18 + (33 - 33.5) ** 2 / 33.5
    assert dof == 2 and stat == pytest.approx(hand, rel=1e-12)
    assert p == pytest.approx(stats.chi2.sf(hand, 2), rel=1e-12)
    # A pool of expected 3 + 3 = 6 ≥ 5 stays a bin of its own: 3 bins, dof 2.
    stat, dof, p = c2.pearson(np.array([12.0, 8.0, 1.0, 6.0]), np.array([10.0, 10.0, 3.0, 3.0]))
    hand = 4 / 10 + 4 / 10 + (7 - 6) ** 2 / 6
    assert dof == 2 and stat == pytest.approx(hand, rel=1e-12) and p == pytest.approx(stats.chi2.sf(hand, 2))
    # No small bin: k bins, k − 1 degrees of freedom; a bin of exactly 5 is not small.
    stat, dof, _ = c2.pearson(np.array([5.0, 9.0, 7.0]), np.array([5.0, 8.0, 8.0]))
    assert dof == 2 and stat == pytest.approx(1 / 8 + 1 / 8)
    stat, dof, _ = c2.pearson(np.array([3.0, 7.0, 10.0]), np.array([5.0, 5.0, 10.0]))
    assert dof == 2 and stat == pytest.approx(4 / 5 + 4 / 5)
    # Shape does not matter (2-D histograms are flattened).
    assert c2.pearson(obs.reshape(5, 1), exp.reshape(1, 5))[:2] == c2.pearson(obs, exp)[:2]


def test_pearson_edge_cases():
    # Observations where nothing is expected are pooled like any small bin: into the last regular bin.
    stat, dof, p = c2.pearson(np.array([10.0, 10.0, 3.0]), np.array([10.0, 10.0, 0.0]))
    assert dof == 1 and stat == pytest.approx(9 / 10) and p == pytest.approx(stats.chi2.sf(0.9, 1))
    # Everything pooled into one bin: no degree of freedom left, p undefined (never a pass).
    stat, dof, p = c2.pearson(np.array([4.0, 6.0]), np.array([0.0, 10.0]))
    assert dof == 0 and math.isnan(p)
    # Nothing to test: no samples, a non-finite pdf, everything in one bin — never a pass.
    for obs, exp in ((np.zeros(3), np.ones(3) * 10), (np.ones(3), np.array([1.0, np.nan, 1.0])),
                     (np.array([3.0, 1.0]), np.array([2.0, 2.0]))):
        stat, dof, p = c2.pearson(obs, exp)
        assert dof == 0 and not (p > 0)  # nan or 0
        assert not c2.Chi2Result("x", {}, stat, dof, p).passed


def test_pearson_calibration_on_multinomial_draws():
    """Exact multinomial draws from the expected counts: the p-values are uniform (fraction below 0.05 inside
    the binomial range over 400 draws), so pooling and dof are neither too strict nor too lax."""
    rng = np.random.default_rng(1234)
    probs = np.array([0.3, 0.25, 0.2, 0.15, 0.06, 0.02, 0.01, 0.005, 0.005])
    n = 200
    ps = np.array([c2.pearson(rng.multinomial(n, probs).astype(float), n * probs)[2] for _ in range(400)])
    low = int((ps < 0.05).sum())
    assert stats.binom.ppf(1e-3, 400, 0.05) <= low <= stats.binom.isf(1e-3, 400, 0.05), low
    assert stats.kstest(ps[ps < 0.5], "uniform", args=(0, 0.5)).pvalue > 1e-3


# -- Šidák and the pass boundary ---------------------------------------------------------------------------
@pytest.mark.parametrize("sidak", [c2.sidak, intervals.sidak])
def test_sidak_exponent_by_hand(sidak):
    # 1 − 0.99^(1/10) = 1 − exp(ln 0.99 / 10)
    assert sidak(0.01, 10) == pytest.approx(0.0010045287, rel=1e-7)
    assert sidak(0.01, 1) == pytest.approx(0.01) and sidak(0.01, 0) == pytest.approx(0.01)
    assert sidak(0.05, 3) == pytest.approx(1 - 0.95 ** (1 / 3), rel=1e-12)
    # Family-wise level of m independent tests at the Šidák level is exactly α; Bonferroni's α/m is below.
    for m in (2, 7, 100):
        a = sidak(0.01, m)
        assert 1 - (1 - a) ** m == pytest.approx(0.01, rel=1e-9) and 0.01 / m < a < 0.01 / m * 1.01


def test_pass_boundary_is_strict():
    r = c2.Chi2Result("x", {}, 3.0, 5, 0.001, threshold=0.001)
    assert not r.passed  # p must exceed the threshold
    assert c2.Chi2Result("x", {}, 3.0, 5, 0.0010001, threshold=0.001).passed
    assert not c2.Chi2Result("x", {}, 3.0, 5, 0.5, threshold=0.001, fault="broken").passed
    assert not c2.Chi2Result("x", {}, 3.0, 0, 0.5).passed


# -- the failed-sample category and the degrees of freedom of a real test ---------------------------------
def _sphere_sampler(fail: float):
    def sample(u):
        w = bl.warps.square_to_uniform_sphere(u[:, :2])
        ok = u[:, 2] >= fail
        return w, np.where(ok, 1 / (4 * np.pi), 0.0)
    return sample


@pytest.mark.parametrize("fail", [0.0, 0.2])
def test_failed_samples_are_one_more_category(fail):
    """Uniform-sphere directions, a fraction ``fail`` of samples failing (pdf 0): with the honest pdf
    (1 − fail)/4π the test passes with dof = bins − 1 (+ 1 for the failure bin when it is populated), X² is
    Pearson's formula over the bins and the failure bin (recomputed here), ∫p = 1 − fail; claiming unit
    mass while samples fail is rejected."""
    n, shape = 20_000, (4, 8)
    honest = c2.sampler_test("sphere", _sphere_sampler(fail), lambda w: np.full(len(w), (1 - fail) / (4 * np.pi)),
                             n=n, seed=5, shape=shape)
    assert honest.passed, honest.message
    assert honest.dof == shape[0] * shape[1] - 1 + (1 if fail else 0)
    assert honest.integral == pytest.approx(1 - fail, abs=1e-6)
    o = np.append(honest.observed.ravel(), n - honest.observed.sum())
    e = np.append(honest.expected.ravel(), n * (1 - honest.integral))
    if not fail:
        o, e = o[:-1], e[:-1]
        o[-1] += n - honest.observed.sum()
        e[-1] += n * (1 - honest.integral)
    assert honest.valid_fraction == pytest.approx(honest.observed.sum() / n)
    assert honest.statistic == pytest.approx(np.sum((o - e) ** 2 / e), rel=1e-9)
    assert honest.p_value == pytest.approx(stats.chi2.sf(honest.statistic, honest.dof), rel=1e-9)
    if fail:
        liar = c2.sampler_test("sphere", _sphere_sampler(fail), lambda w: np.full(len(w), 1 / (4 * np.pi)),
                               n=n, seed=5, shape=shape)
        assert not liar.passed and liar.p_value < 1e-12


# -- furnace error bars ------------------------------------------------------------------------------------
class _Weights(bl.BSDF):
    """Sample weight (2, 0, 0) where u₀ < ½, else (0, 0, 0) — a Bernoulli weight of known mean and spread."""

    type_name = "furnace_weights_test"

    def eval(self, wi, wo, uv=None):
        return np.zeros((len(wi), 3))

    def pdf(self, wi, wo, uv=None):
        return np.full(len(wi), 1 / (2 * np.pi))

    def sample(self, wi, u, uv=None):
        wo = bl.warps.square_to_uniform_hemisphere(u[:, 1:3])
        w = np.zeros((len(u), 3))
        w[:, 0] = np.where(u[:, 0] < 0.5, 2.0, 0.0)
        return bl.BSDFSample(wo, w, np.full(len(u), 1 / (2 * np.pi)))


def test_furnace_monte_carlo_mean_and_standard_error_by_hand():
    n, seed = 1000, 3
    m, se = albedo_monte_carlo(_Weights(), 30.0, n=n, seed=seed)
    u = np.random.default_rng(seed).random((n, 3))
    k = int((u[:, 0] < 0.5).sum())
    lum = 2.0 * LUMINANCE[0]  # only the red channel carries weight
    mean = lum * k / n
    var = (k * (lum - mean) ** 2 + (n - k) * mean**2) / (n - 1)  # sample variance (ddof = 1)
    assert m == pytest.approx(mean, rel=1e-12) and se == pytest.approx(math.sqrt(var / n), rel=1e-12)
    assert LUMINANCE.sum() == pytest.approx(1.0, abs=1e-6)


def test_albedo_point_error_bar_and_bounds_by_hand():
    p = AlbedoPoint("x", None, 0.0, quadrature=0.9, monte_carlo=0.9, mc_stderr=3e-3, quad_error=4e-3)
    assert p.sigma == pytest.approx(5e-3)
    # Agreement: |q − m| ≤ 4σ + 5e-4 = 0.0205.
    for diff, agree in ((0.0204, True), (0.0206, False), (-0.0204, True), (-0.0206, False)):
        q = AlbedoPoint("x", None, 0.0, 0.9 + diff, 0.9, 3e-3, 4e-3)
        assert q.agree is agree and q.passed is agree, diff
    # Energy: quadrature ≤ 1 + 1e-3 + 3·quad_error; Monte Carlo ≤ 1 + 4·stderr + 1e-3.
    for quad, ok in ((1.0129, True), (1.0131, False)):
        q = AlbedoPoint("x", None, 0.0, quad, quad, 3e-3, 4e-3)
        assert q.energy_ok is ok and q.passed is ok, quad
    for mc, ok in ((1.0129, True), (1.0131, False)):
        q = AlbedoPoint("x", None, 0.0, 0.99, mc, 3e-3, 0.0)
        assert q.energy_ok is ok, mc
    # A fault fails whatever the numbers.
    assert not AlbedoPoint("x", None, 0.0, 0.5, 0.5, 1e-3, fault="broken").passed
    msg = AlbedoPoint("x", None, 0.0, 0.95, 0.9, 3e-3, 4e-3).summary()
    assert "DISAGREE by 10σ" in msg


# -- binning and quadrature on exact cases -----------------------------------------------------------------
def test_sphere_bin_integrals_by_hand():
    """∫ dω and ∫ cos θ dω over wide (θ, φ) bins: (cos θ_a − cos θ_b)(φ_b − φ_a) and
    ½(sin² θ_b − sin² θ_a)(φ_b − φ_a) (cells split, graded and refined inside each bin)."""
    te = np.array([0.0, 0.4, np.pi / 2, 2.5, np.pi])
    pe = np.array([[0.0, 1.0, 2 * np.pi], [0.0, 4.0, 2 * np.pi], [0.0, 0.5, 2 * np.pi], [0.0, 3.0, 2 * np.pi]])
    one, err = c2.integrate_sphere_bins(lambda w: np.ones(len(w)), te, pe)
    hand = (np.cos(te[:-1]) - np.cos(te[1:]))[:, None] * np.diff(pe, axis=1)
    np.testing.assert_allclose(one, hand, rtol=1e-9)
    assert one.shape == (4, 2) and np.all(err >= 0) and one.sum() == pytest.approx(4 * np.pi)
    cos, _ = c2.integrate_sphere_bins(lambda w: np.maximum(w[:, 2], 0.0), te, pe)
    hand = 0.5 * (np.sin(np.minimum(te[1:], np.pi / 2)) ** 2 - np.sin(np.minimum(te[:-1], np.pi / 2)) ** 2)
    np.testing.assert_allclose(cos, hand[:, None] * np.diff(pe, axis=1), rtol=1e-7, atol=1e-12)
    assert cos.sum() == pytest.approx(np.pi, rel=1e-7)
    # About another axis (not normalised): the same bins measured from +x.
    lobe, _ = c2.integrate_sphere_bins(lambda w: np.maximum(w[:, 0], 0.0), te, pe, axis=np.array([2.0, 0, 0]))
    np.testing.assert_allclose(lobe, hand[:, None] * np.diff(pe, axis=1), rtol=1e-7, atol=1e-12)


def test_angles_bins_and_counts_by_hand():
    w = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])
    th, ph = c2.to_angles(w, np.array([0.0, 0.0, 1.0]))
    np.testing.assert_allclose(th, [0, np.pi / 2, np.pi / 2, np.pi / 2, np.pi], atol=1e-12)
    np.testing.assert_allclose(ph[1:4], [0, np.pi / 2, 3 * np.pi / 2], atol=1e-12)
    # About +x given as a non-unit vector: θ′ is the angle to +x.
    th, _ = c2.to_angles(w, np.array([3.0, 0.0, 0.0]))
    np.testing.assert_allclose(th, [np.pi / 2, 0.0, np.pi / 2, np.pi / 2, np.pi / 2], atol=1e-12)
    back = c2.from_angles(np.array([0.3, 2.0]), np.array([1.0, 5.0]), np.array([0.0, 3.0, 0.0]))
    np.testing.assert_allclose(c2.to_angles(back, np.array([0.0, 3.0, 0.0]))[0], [0.3, 2.0], atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(back, axis=1), 1.0)
    # Rectangles of 2 strips × 3 φ bins, flattened strip by strip.
    te = np.array([0.0, 1.0, np.pi])
    pe = np.array([[0.0, 1.0, 2.0, 2 * np.pi], [0.0, 3.0, 4.0, 2 * np.pi]])
    ta, tb, pa, pb = c2.bin_rects(te, pe)
    assert ta.tolist() == [0, 0, 0, 1, 1, 1] and tb.tolist() == [1, 1, 1, np.pi, np.pi, np.pi]
    assert pa.tolist() == [0, 1, 2, 0, 3, 4] and pb.tolist() == [1, 2, 2 * np.pi, 3, 4, 2 * np.pi]
    counts = c2.bin_counts(np.array([0.5, 0.5, 0.5, 2.0, 2.0, 2.0, 2.0]), np.array([0.5, 1.5, 6.0, 0.1, 3.5, 3.9, 5.0]),
                           te, pe)
    assert counts.tolist() == [[1, 1, 1], [1, 2, 1]]


@pytest.mark.parametrize("geometric", [False, True])
def test_adaptive_grid_integral_by_hand(geometric):
    """∫∫ x² y dx dy over every cell of a grid: (x_b³ − x_a³)/3 · (y_b² − y_a²)/2 (the point-warp test's
    expected counts), also with the cells graded geometrically away from x = 0."""
    xe, ye = np.array([0.0, 0.1, 0.5, 1.0, 3.0]), np.array([-1.0, 0.0, 2.0])
    got = c2.adaptive_integrate(lambda x, y: x * x * y, xe, ye, geometric_x=geometric)
    hand = np.diff(xe**3)[:, None] / 3 * np.diff(ye**2)[None, :] / 2
    np.testing.assert_allclose(got, hand, rtol=1e-10, atol=1e-14)


def test_albedo_curve_of_a_lambertian():
    """ρ(θ_i) of a Lambertian of albedo 0.6 is 0.6 at every angle, by quadrature and Monte Carlo (exactly:
    cosine sampling gives every sample the weight 0.6)."""
    from brdflab.bsdf.diffuse import Diffuse
    from brdflab.judges.material.furnace import albedo_curve

    pts = albedo_curve("diffuse", lambda a: Diffuse(np.array([0.6, 0.6, 0.6])), None, [0.0, 60.0], n=2000)
    assert [p.theta for p in pts] == [0.0, 60.0] and all(p.passed for p in pts)
    for p in pts:
        assert p.quadrature == pytest.approx(0.6, rel=1e-6) and p.monte_carlo == pytest.approx(0.6, rel=1e-12)
        assert p.mc_stderr == pytest.approx(0.0, abs=1e-12) and p.params == {} and p.alpha is None


def test_failed_samples_may_return_any_direction():
    """A sample with pdf 0 (failed) may return ω_o = 0; only directions of valid samples must be unit."""
    from brdflab.judges.core.guard import CheckedBSDF, PluginFault

    class Half(bl.BSDF):
        def eval(self, wi, wo, uv=None):
            return np.zeros((len(wi), 3))

        def pdf(self, wi, wo, uv=None):
            return np.full(len(wi), 1 / (2 * np.pi))

        def sample(self, wi, u, uv=None):
            wo = bl.warps.square_to_uniform_hemisphere(u[:, :2])
            fail = u[:, 2] < 0.5
            wo[fail] = 0.0
            return bl.BSDFSample(wo, np.zeros((len(u), 3)), np.where(fail, 0.0, 1 / (2 * np.pi)))

    b = CheckedBSDF(Half(), "half", {})
    u = np.random.default_rng(0).random((100, 3))
    s = b.sample(np.tile([0.0, 0.0, 1.0], (100, 1)), u)
    assert (s.pdf == 0).sum() == (u[:, 2] < 0.5).sum()

    class Short(Half):
        def sample(self, wi, u, uv=None):
            r = super().sample(wi, u, uv)
            return bl.BSDFSample(r.wo * 0.5, r.weight, r.pdf)

    with pytest.raises(PluginFault, match="unit|norm|length"):
        CheckedBSDF(Short(), "short", {}).sample(np.tile([0.0, 0.0, 1.0], (100, 1)), u)


def test_pilot_bins_by_hand():
    """θ edges at the pilot's quantiles (0 and π at the ends), φ edges at the quantiles inside each strip, and
    a regular φ grid in a strip with fewer than 2·n_phi pilot points."""
    theta = np.array([0.1, 0.2, 0.3, 0.4, 0.5, 2.0, 2.1])
    phi = np.array([0.5, 1.0, 4.0, 5.0, 1.0, 2.0, 6.0])
    te, pe = c2.pilot_bins(theta, phi, 2, 2)
    assert te.tolist() == pytest.approx([0.0, 0.4, np.pi])  # the median; θ = 0.4 belongs to the upper strip
    assert pe[0].tolist() == pytest.approx([0.0, np.pi, 2 * np.pi])  # 3 points < 2 · 2: regular
    assert pe[1].tolist() == pytest.approx([0.0, float(np.quantile(phi[3:], 0.5)), 2 * np.pi])
