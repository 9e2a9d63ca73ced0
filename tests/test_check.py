"""``brdflab check``: false-alarm rate (exact binomial bounds), power against known biases, CLI contract."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from scipy import stats
from scipy.ndimage import gaussian_filter

from brdflab.cli.main import main
from brdflab.imageio import write_exr
from brdflab.stats import blocks as B
from brdflab.stats.intervals import holm
from brdflab.stats.jobs import RenderJob, run_job, run_seed
from brdflab.stats.render_check import Estimate, check_images
from tests.conftest import ROOT

CBOX = ROOT / "scenes" / "cbox" / "cbox_diffuse.xml"
H, W = 64, 96


def _truth() -> np.ndarray:
    yy, xx = np.mgrid[0:H, 0:W]
    t = np.stack([0.2 + 0.8 * xx / W, 0.5 + 0.3 * np.sin(yy / 9.0), 0.1 + 0 * xx], -1)
    t[:, :20] = 0.0  # a black region: zero variance on both sides
    return t


TRUTH = _truth()


def _draw(rng: np.random.Generator, spp: int = 16) -> np.ndarray:
    """A synthetic MC image: per-pixel means of heavy-tailed (Gamma(½)) samples, then a Gaussian filter
    (correlates neighbouring pixels like Nori's reconstruction filter)."""
    img = TRUTH * rng.gamma(0.5, 2.0, (spp, H, W, 1)).mean(axis=0)
    return np.stack([gaussian_filter(img[..., c], 0.6) for c in range(3)], -1)


def _binom_max(n: int, rate: float = 0.01, risk: float = 0.02) -> int:
    """Largest false-alarm count compatible with ``rate`` over n trials (exceeded with prob. < risk)."""
    return int(stats.binom.isf(risk, n, rate))


def test_holm_and_blocks_by_hand():
    rej, adj = holm(np.array([0.01, 0.04, 0.03, 0.5]), 0.05)
    assert adj.tolist() == pytest.approx([0.04, 0.09, 0.09, 0.5])
    assert rej.tolist() == [True, False, False, False]
    a = np.arange(5 * 7, dtype=float).reshape(5, 7, 1)
    s = B.block_sum(a, 4)
    assert s.shape == (2, 2, 1) and s.sum() == a.sum() and s[0, 0, 0] == a[:4, :4].sum()
    # Independent unit noise: F = 1; a 3-tap box filter along x: F∞ = 3 (1 + 2·2/3).
    rng = np.random.default_rng(run_seed(16, 0, "check"))
    z = rng.standard_normal((1, 200, 200, 1))
    valid = np.ones((200, 200), bool)
    assert B.correlation_factor(B.correlation(z, valid), None, 1)[0] == pytest.approx(1.0, abs=0.1)
    zb = (z + np.roll(z, 1, axis=2) + np.roll(z, -1, axis=2)) / np.sqrt(3)
    assert B.correlation_factor(B.correlation(zb, valid), None, 1)[0] == pytest.approx(3.0, abs=0.15)


@pytest.mark.parametrize("renders", [1, 2])
def test_false_alarm_rate_synthetic(renders):
    """Unbiased synthetic images, 60 (40) independent trials: at most the binomial bound for α = 1 %."""
    warnings.simplefilter("ignore", RuntimeWarning)
    n, alarms = 60 if renders == 1 else 40, 0
    for t in range(n):
        rng = np.random.default_rng(run_seed(1600 + renders, t, "check"))
        user = [_draw(rng) for _ in range(renders)]
        est = Estimate.from_runs([_draw(rng) for _ in range(4)], run_spp=16)
        alarms += not check_images(user, est, user_spp=16).consistent
    assert alarms <= _binom_max(n), f"{alarms} false alarms of {n}"


def test_power_synthetic():
    """Known biases are found, in the right direction and place."""
    rng = np.random.default_rng(run_seed(1610, 0, "check"))
    est = Estimate.from_runs([_draw(rng, 64) for _ in range(4)], run_spp=64)
    x = _draw(rng, 64)
    assert check_images([x], est, user_spp=64).consistent
    dark = check_images([0.97 * x], est, user_spp=64)
    assert not dark.consistent and dark.bias_ci[1] < 0 and dark.bright_blocks == 0
    wall = x.copy()
    wall[:, 48:80] *= 0.9
    r = check_images([wall], est, user_spp=64)
    assert not r.consistent and r.bright_blocks == 0
    # Every flagged block (of any scale) overlaps the darkened columns 48–79.
    assert r.flagged and all(f["x"] < 80 and f["x"] + f["w"] > 48 for f in r.flagged)
    assert {f["x"] for f in r.flagged if f["w"] == 16} <= {48, 64}
    patch = x.copy()
    patch[32:48, 64:80] *= 1.15
    r = check_images([patch], est, user_spp=64)
    assert not r.consistent and r.dark_blocks == 0 and (64, 32, 16) in {(f["x"], f["y"], f["w"]) for f in r.flagged}
    assert all(f["x"] <= 64 < f["x"] + f["w"] and f["y"] <= 32 < f["y"] + f["h"] for f in r.flagged)
    assert 0 < r.min_detectable_bias < 0.03 and 0 < r.min_detectable_block_bias < 0.15


RARE = np.zeros((H, W), bool)
RARE[8:56, 24:72] = True


def _draw_rare(rng: np.random.Generator, spp: int, q: float = 2e-4) -> np.ndarray:
    """Like :func:`_draw`, but a 48 × 48 region is lit only through rare samples (probability q, value
    0.5/q: a small light found by BSDF sampling), so that brdflab's 4 runs often see nothing at all in a
    16 × 16 block where the user's render drew a few of them."""
    img = TRUTH * rng.gamma(4.0, 0.25, (spp, H, W, 1)).mean(axis=0)
    hits = rng.binomial(spp, q, (H, W)) * (0.5 / q) / spp
    img = img * ~RARE[..., None] + np.where(RARE, hits, 0.0)[..., None] * np.array([1.0, 0.9, 0.8])
    return np.stack([gaussian_filter(img[..., c], 0.6) for c in range(3)], -1)


def test_rare_samples_no_false_alarm():
    """Regression (issue 16): one user render against 4 brdflab runs with rare large samples. The former
    single-render model (brdflab's block variance from 4 runs only) gave a zero variance to blocks where
    those runs drew no rare sample and flagged 24 of these 30 unbiased trials; the residual floor and the
    neighbourhood pooling bring it to the binomial bound of α = 1 %. A bias is still found."""
    warnings.simplefilter("ignore", RuntimeWarning)
    n, alarms = 30, 0
    for t in range(n):
        rng = np.random.default_rng(run_seed(1620, t, "check"))
        user = _draw_rare(rng, 32)
        est = Estimate.from_runs([_draw_rare(rng, 16) for _ in range(4)], run_spp=16)
        alarms += not check_images([user], est, user_spp=32).consistent
    assert alarms <= _binom_max(n), f"{alarms} false alarms of {n}"
    dark = user.copy()
    dark[:, 72:] *= 0.9  # the smooth region right of the rare one
    r = check_images([dark], est, user_spp=32)
    assert not r.consistent and r.dark_blocks >= 1 and all(f["x"] + f["w"] > 72 for f in r.flagged)


def test_scan_windows_and_constant_regions():
    """The scan's window sums are exact (an empty window stays exactly 0) and its 1 × 1 windows are the
    16 × 16 block tests; a region brdflab renders exactly (a light seen directly) tolerates float32
    rounding but not a 1 % darker light, which is reported too dark (the sign of an infinite t)."""
    from brdflab.stats import render_check as C

    rng = np.random.default_rng(run_seed(1630, 0, "check"))
    a = rng.random((6, 7, 4))
    a[:3, :3] = 0.0
    ws = C._window_sum(a, 2)
    assert ws.shape == (5, 6, 4) and np.allclose(ws[2, 3], a[2:4, 3:5].sum(axis=(0, 1)))
    assert (C._window_sum(a, 2)[:2, :2] == 0.0).all()
    user = _draw(rng)
    est = Estimate.from_runs([_draw(rng) for _ in range(4)], run_spp=16)
    user[40:56, 80:96] = est.mean[40:56, 80:96] = est.runs[:, 40:56, 80:96] = 3.0  # an emitter
    r = check_images([user * np.float32(1 + 3e-7)], est, user_spp=16)
    assert r.consistent and r.scales == [16, 32]
    dim = user.copy()
    dim[40:56, 80:96] *= 0.99
    r = check_images([dim], est, user_spp=16)
    assert not r.consistent and r.bright_blocks == 0 and r.signed_map[2, 5] == -1
    # 1 × 1 windows of the scan = the block tests of the base level.
    x4, y4 = C._with_mean_channel(user), C._with_mean_channel(est.mean)
    finite = np.ones(user.shape[:2], bool)
    info: dict = {}
    base = C._block_level((x4[None], x4, y4, x4 - y4, finite, est, 16), 16, info)
    one = C._scan_level(C._scan_sums(C._with_mean_channel(est.runs), x4, y4, x4 - y4, finite, 16), 1, info, 16)
    assert np.allclose(one["var"], base["var"]) and np.allclose(one["t"], base["t"])


def _render(integrator: str, seed: int, spp: int = 32) -> np.ndarray:
    return run_job(RenderJob(CBOX, integrator, spp, seed, (64, 64), 1))[0]


@pytest.fixture(scope="module")
def cbox_trials():
    """Eight independent trials on the bundled Cornell box (64×64, 32 spp): brdflab's estimate (3 runs of
    the scene's direct_ems) and one user render each by direct_ems (another seed) and direct_mis."""
    trials = []
    for t in range(8):
        runs = [_render("direct_ems", run_seed(t, k, "reference")) for k in range(3)]
        trials.append((Estimate.from_runs(runs, run_spp=32), _render("direct_ems", run_seed(t, 0, "check")),
                       _render("direct_mis", run_seed(t, 1, "check"))))
    return trials


def test_cbox_unbiased_renders_pass(cbox_trials):
    alarms = sum(not check_images([u], est, user_spp=32).consistent
                 for est, ems, mis in cbox_trials for u in (ems, mis))
    assert alarms <= _binom_max(2 * len(cbox_trials)), alarms


def test_cbox_biased_renders_flagged(cbox_trials):
    """Uniformly darker, one wall darker, a bright patch: each flagged in every trial (at this tiny size
    the biases are larger than the benchmark's 3 % / 10 %: see benchmarks/check_power.py)."""
    for est, ems, _ in cbox_trials:
        assert not check_images([0.9 * ems], est, user_spp=32).consistent
        wall = ems.copy()
        wall[8:56, 2:14] *= 0.7  # the red wall
        r = check_images([wall], est, user_spp=32)
        assert not r.consistent and r.dark_blocks >= 1 and r.bright_blocks == 0
        patch = ems.copy()
        patch[32:48, 16:32] *= 1.5
        r = check_images([patch], est, user_spp=32)
        assert not r.consistent and r.bright_blocks >= 1 and r.dark_blocks == 0


def test_check_cli(tmp_path, cbox_trials, capsys):
    scene = tmp_path / "cb.xml"
    scene.write_text(CBOX.read_text().replace('"512"', '"64"').replace("meshes/", str(CBOX.parent / "meshes") + "/"))
    est, ems, mis = cbox_trials[0]
    write_exr(tmp_path / "ok.exr", ems, extra={"brdflab_spp": "32"})
    write_exr(tmp_path / "ok2.exr", mis, extra={"brdflab_spp": "32"})
    write_exr(tmp_path / "bad.exr", ems * np.where(np.arange(64) < 32, 0.6, 1.0)[:, None, None])
    assert main(["check", str(tmp_path / "ok.exr"), str(tmp_path / "ok2.exr"), "--scene", str(scene), "--spp",
                 "32", "--runs", "3", "-o", str(tmp_path / "c1"), "--quiet"]) == 0
    line = capsys.readouterr().out
    assert line.startswith(("consistent: p = ", "consistent: p > 0.99")) and "99 % CI" in line
    d = json.loads((tmp_path / "c1" / "check.json").read_text())
    assert d["consistent"] and d["method"] == "welch" and d["user_renders"] == 2 and d["reference_runs"] == 3
    assert (tmp_path / "c1" / "check.html").stat().st_size > 10_000
    assert main(["check", str(tmp_path / "bad.exr"), "--scene", str(scene), "--spp", "32", "--runs", "3",
                 "--levels", "1", "-o", str(tmp_path / "c2"), "--quiet"]) == 1
    d = json.loads((tmp_path / "c2" / "check.json").read_text())
    assert d["method"].startswith("model") and d["dark_blocks"] >= 1 and not d["consistent"] and d["scales"] == [16]
    assert all(f["sign"] == "too dark" and f["y"] < 32 for f in d["flagged"])
    # Usage errors: exit 2, nothing written.
    write_exr(tmp_path / "small.exr", ems[:32])
    assert main(["check", str(tmp_path / "small.exr"), "--scene", str(scene), "-o", str(tmp_path / "c3")]) == 2
    assert main(["check", str(tmp_path / "none.exr"), "--scene", str(scene), "-o", str(tmp_path / "c3")]) == 2
    assert not (tmp_path / "c3").exists()
    assert "too small" not in capsys.readouterr().err


def test_docstring_examples_run():
    import doctest

    import brdflab.stats.render_check as mod

    res = doctest.testmod(mod)
    assert res.attempted >= 3 and res.failed == 0
