"""Is a render an unbiased estimate of what its scene describes? (``brdflab check``)

Let x̄ be the user's image (the mean of J ≥ 1 renders with different seeds) and ȳ brdflab's estimate
(the mean of K independent runs with their own seeds, or a given reference). The two are independent,
so for every block b (side s pixels) and channel c the difference of block means

    D_b = mean_b(x̄) − mean_b(ȳ),   Var D_b = Var mean_b(x̄) + Var mean_b(ȳ)

has expectation 0 when the user's renderer is unbiased. Var D_b is estimated in one of three ways:

``welch`` (J ≥ 2 user renders and K ≥ 2 runs, or a given variance image of the reference)
    each side from its own run-to-run pixel variance pooled over the block with the correlation factor
    of :mod:`brdflab.stats.blocks` eq. (1); the statistic D_b/√Var D_b is referred to Student's t with
    Welch–Satterthwaite degrees of freedom (few runs per side).
``model`` (one user render, K ≥ 2 brdflab runs)
    the larger of two estimates, each of which alone can fail:

    * brdflab's run-to-run block variance V_y, scaled to the user's spp, times one global factor η ≥ 1
      (the median over blocks of residual / model variance), plus V_y itself;
    * the *residual* estimate below, made on r with each block's mean **and** its least-squares slope on ȳ
      removed (so a bias proportional to the image inside a block — a wall 10 % too dark — is not
      taken for spread), with n − 2F in place of n − F.

    The model alone is not enough: K = 4 runs see too few of the rare large samples of a scene (a BSDF
    sample finding a small light) to estimate every block's variance — where they drew none, V_y = 0
    while the user's render, with one such sample, is "infinitely" significant. Measured on the course
    Cornell box (direct_mats, 800 × 600, 64 spp), 6 of 1 900 blocks were flagged in an unbiased render
    for this reason. The residual spread of the user's own render contains its rare samples, so it
    bounds the variance from below exactly there. Degrees of freedom: the smaller of the two estimates'.
``residual`` (one user render, a given reference without variance)
    from the spread of the pixel residuals r = x̄ − ȳ around their block mean:
    Var D_b = F · Σ_b (r − r̄_b)² / ((n − F) n). This needs neither the user's sample count nor their
    integrator, contains brdflab's own noise, and is **conservative**: a bias that varies inside a block
    (or with the image content) only widens it, heavy tails lower the degrees of freedom (eq. (2) there),
    and each block's variance is raised to its 3 × 3 neighbourhood's median relative variance (a render
    that happened to draw none of its rare large samples in a block cannot show their variance).

Scales: blocks of s = 16, 32, 64 and 128 pixels (``levels``; sizes up to half the image's smaller
side) are tested. A 16 × 16 block localises a defect; on a noisy render (BSDF sampling only, 64 spp)
its smallest detectable bias is ~60 %, while a 64 × 64 block detects ~4 × smaller relative biases, e.g. a
75-pixel patch 15 % too bright. With one render (``model``) the coarser sizes are a **scan**: every
window of 2 × 2, 4 × 4 and 8 × 8 base blocks at every 16-pixel offset, so that some window lies inside
any patch of ~1.25 window sides (aligned blocks can straddle it: measured, a 64-pixel grid missed the
+15 % patch that a shifted window finds). Window statistics come from additive per-block sums (means,
squares, fourth powers, cross-products with ȳ; :func:`_scan_sums`), and the correlation factor of each
size from the correlations measured once at the base block, so the scan costs little. The family then
holds ~3.5 × more tests than the 16 × 16 grid alone: the per-test threshold rises from z ≈ 4.9 to
z ≈ 5.2. (``welch`` and ``residual``: aligned blocks of each size.) Every variance is at least
(ROUNDING · block mean)² — a region brdflab renders exactly (a light seen directly) differs in another
renderer's float32 output by rounding, which is not a bias.

Decision (one family at level α, default 0.01): the whole-image mean test (scalar (R+G+B)/3, normal
reference distribution; the relative bias (mean x̄ / mean ȳ − 1) with its 99 % interval) gets α/2, the
3 × (number of blocks of every scale) block tests share α/2 by Holm's step-down procedure; the
verdict's p-value is the Bonferroni combination min(1, 2 · min(p_mean, min Holm-adjusted p_block)).
The false-alarm rate is therefore at most α whatever the dependence between blocks and scales; it is
measured in tests/test_check.py (synthetic and rendered images, exact binomial bounds) and
benchmarks/check_power.py (≥ 50 seeds at 800 × 600). The signed map is drawn on the 16 × 16 grid: a
block flagged only at a coarser scale marks the 16 × 16 blocks it covers.

Power: the smallest relative bias of the image mean detected with 80 % probability is
(z_{1−α/4} + z_{0.8}) · sd(mean D)/mean ȳ; per block the same with the block's t-quantile at the first
Holm level α/(2m); the median over 16 × 16 blocks is reported.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np
from scipy import stats

from brdflab.errors import ImageError
from brdflab.stats.check_scan import (  # noqa: F401 (re-exported: the module's former contents)
    ROUNDING,
    Estimate,
    _block_level,
    _covered,
    _paint_coarse,
    _pool_neighbours,
    _residual,
    _scan_level,
    _scan_sums,
    _side_from_runs,
    _single_render_var,
    _t_tests,
    _uncentred,
    _window_sum,
    _with_mean_channel,
)
from brdflab.stats.intervals import holm
from brdflab.stats.jobs import RenderJob, run_job, run_seed

#: Family-wise false-alarm level of a check.
ALPHA = 0.01
#: Default block side in pixels (see :mod:`brdflab.stats.blocks`).
BLOCK = 16
#: Block sizes tested: BLOCK · 2^i for i < LEVELS (16, 32, 64, 128 px), one Holm family.
LEVELS = 4
#: Power reported for the smallest detectable bias.
POWER = 0.8


@dataclass
class CheckResult:
    """Everything ``brdflab check`` decided and measured (JSON via :meth:`to_dict`)."""

    consistent: bool
    p_value: float
    bias: float
    bias_ci: tuple[float, float]
    bias_p: float
    method: str
    block: int
    alpha: float
    blocks: int
    dark_blocks: int
    bright_blocks: int
    min_detectable_bias: float
    min_detectable_block_bias: float
    correlation_factor: float
    nonfinite: int
    signed_map: np.ndarray = field(repr=False)
    """(By, Bx): −1 significantly too dark, +1 too bright, 0 consistent."""
    z_map: np.ndarray = field(repr=False)
    """(By, Bx): signed z-score of the most significant channel."""
    flagged: list[dict] = field(default_factory=list)
    user_renders: int = 1
    reference_runs: int = 0
    reference_spp: int = 0
    seconds: float = 0.0
    reference_label: str = ""
    estimate_integrator: str = ""
    """The integrator of brdflab's estimate ("" with a given reference)."""
    estimate_note: str = ""
    """Which of a user's BSDF methods the estimate ran (what a shared bug hides), set by ``bl.check``."""
    estimate: np.ndarray | None = field(default=None, repr=False)
    """brdflab's estimate (mean image), set by :func:`run_check`."""
    runs: np.ndarray | None = field(default=None, repr=False)
    """brdflab's individual runs, set by :func:`run_check`."""
    scales: list[int] = field(default_factory=list)
    """Block sizes tested (pixels), one Holm family over all of them."""
    attribution: dict | None = field(default=None, repr=False)
    """Where and what, for a biased render (:mod:`brdflab.stats.attribution`; set by :func:`brdflab.check`)."""

    def verdict(self) -> str:
        """One line: consistent/biased, p-value, mean bias with its 99 % interval, block counts."""
        word = "consistent" if self.consistent else "BIASED"
        lo, hi = self.bias_ci
        p = "p > 0.99" if self.p_value > 0.99 else f"p = {self.p_value:.3g}"  # a Holm-adjusted p caps at 1
        s = (f"{word}: {p}; image mean {100 * self.bias:+.2f} % "
             f"(99 % CI {100 * lo:+.2f} … {100 * hi:+.2f} %)")
        if self.dark_blocks or self.bright_blocks:
            s += f"; {self.dark_blocks} blocks too dark, {self.bright_blocks} too bright of {self.blocks}"
        else:
            s += f"; no block of {self.blocks} differs"
        s += (f"; detectable: mean bias ≥ {100 * self.min_detectable_bias:.2g} %, one {self.block}×{self.block} "
              f"block ≥ {100 * self.min_detectable_block_bias:.2g} %")
        return s

    def to_dict(self) -> dict:
        """Plain-dict form (maps as nested lists)."""
        d = {f.name: getattr(self, f.name) for f in fields(self) if f.name not in ("estimate", "runs", "attribution")}
        d["signed_map"] = self.signed_map.astype(int).tolist()
        d["z_map"] = np.round(self.z_map, 3).tolist()
        d["bias_ci"] = list(self.bias_ci)
        d["verdict"] = self.verdict()
        return d


def check_inputs(user: list[np.ndarray], ref_var: np.ndarray | None = None, user_spp: int | None = None,
                 names: list[str] | None = None, block: int | None = None, ref: np.ndarray | None = None) -> None:
    """Refuse inputs that would give a p-value without meaning, before any work.

    Two user renders that are the same image (the same file given twice, or a copy) are not independent
    estimates: their zero difference would be read as a variance of zero and any difference from brdflab's
    estimate as a bias; nor is a reference that is one of the renders. A variance must be finite and ≥ 0;
    a sample count ≥ 1; a block at least 2 pixels and no larger than the image.

    Raises
    ------
    ImageError
        Naming the renders or the variance image.
    """
    names = names or [f"render {i + 1}" for i in range(len(user))]
    for i, u in enumerate(user):
        j = next((j for j in range(i) if np.shape(user[j]) == np.shape(u)
                  and np.array_equal(user[j], u, equal_nan=True)), None)
        if j is not None:
            raise ImageError(f"'{names[i]}' and '{names[j]}' are the same image: several renders must be "
                             "independent (different seeds); give one of them only")
    if ref is not None:
        same = next((i for i, u in enumerate(user) if np.shape(u) == np.shape(ref)
                     and np.array_equal(u, ref, equal_nan=True)), None)
        if same is not None:
            raise ImageError(f"the reference is the same image as '{names[same]}': a render cannot be checked "
                             "against itself")
    if ref_var is not None:
        v = np.asarray(ref_var)
        bad = ~np.isfinite(v) | (v < 0)
        if bad.any():
            y, x = np.argwhere(bad)[0][:2]
            raise ImageError(f"the reference variance must be finite and ≥ 0; pixel ({x}, {y}) is "
                             f"{v[y, x].ravel()[0]:g} ({int(bad.sum())} such values)")
    if user_spp is not None and not (isinstance(user_spp, (int, np.integer)) and user_spp >= 1):
        raise ImageError(f"the user's samples per pixel must be an integer ≥ 1, got {user_spp}")
    if block is not None and user:
        h, w = np.shape(user[0])[:2]
        if not 2 <= block <= min(h, w):
            raise ImageError(f"the block side must be between 2 and the image's smaller side ({min(h, w)} px), "
                             f"got {block}")


def check_images(user: list[np.ndarray], estimate: Estimate, block: int = BLOCK, alpha: float = ALPHA,
                 user_spp: int | None = None, levels: int = LEVELS) -> CheckResult:
    """Test whether the user's render(s) ``user`` and brdflab's ``estimate`` have the same expectation.

    Parameters
    ----------
    user
        One or more (H, W, 3) renders of the same scene with different seeds.
    estimate
        brdflab's independent estimate (see :class:`Estimate`).
    block
        Block side in pixels.
    alpha
        Family-wise false-alarm level.
    user_spp
        Samples per pixel of each user render, if known: with one render, the variance is then also
        predicted from brdflab's run-to-run variance scaled to that sample count, and the larger of the
        two estimates is used (see module docstring).
    levels
        Block sizes ``block · 2^i`` for i < ``levels`` (those up to half the image's smaller side) are
        tested in one family; 1 tests ``block``-sized blocks only.

    Examples
    --------
    >>> rng = np.random.default_rng(5)
    >>> truth = np.full((64, 64, 3), 0.5)
    >>> draw = lambda: truth * rng.gamma(4.0, 0.25, truth.shape)
    >>> ok = check_images([draw()], Estimate.from_runs([draw() for _ in range(4)]))
    >>> ok.consistent
    True
    >>> check_images([0.9 * draw()], Estimate.from_runs([draw() for _ in range(4)])).consistent
    False
    """
    if not user:
        raise ImageError("no user render given")
    check_inputs(user, estimate.pixel_var, user_spp, block=block)
    shape = estimate.mean.shape
    for u in user:
        if u.shape != shape:
            raise ImageError(f"image is {u.shape[1]}×{u.shape[0]}, but the scene renders "
                             f"{shape[1]}×{shape[0]}")
    xs = np.stack([np.asarray(u, dtype=np.float64) for u in user])
    finite = np.isfinite(xs).all(axis=(0, 3)) & np.isfinite(estimate.mean).all(axis=2)
    nonfinite = int((~finite).sum())
    if not finite.any():
        raise ImageError("every pixel of the image is NaN or infinite")
    xs[:, ~finite] = 0.0
    xs4 = _with_mean_channel(xs)
    y4 = _with_mean_channel(np.where(finite[..., None], estimate.mean, 0.0))
    x4 = xs4.mean(axis=0)
    # Residuals for variance estimation, with one global multiplicative fit r ≈ c·ȳ removed per channel:
    # an image uniformly too dark would otherwise pass its bias, through the variation of ȳ inside
    # each block, for noise. (One coefficient over all pixels absorbs a negligible part of the noise.)
    r4 = x4 - y4
    with np.errstate(invalid="ignore", divide="ignore"):
        yy = np.einsum("hwc,hwc->c", y4, y4)
        c_fit = np.where(yy > 0, np.einsum("hwc,hwc->c", r4, y4) / np.where(yy > 0, yy, 1.0), 0.0)
    r_var = r4 - c_fit * y4
    sides = (xs4, x4, y4, r_var, finite, estimate, user_spp)
    h, w = shape[:2]
    scales = [block << i for i in range(max(levels, 1)) if i == 0 or block << i <= min(h, w) // 2]
    info: dict = {}
    base = _block_level(sides, block, info)
    if "eta" in info:  # single-render model: every window of 2, 4, 8 blocks at every block offset
        sums = _scan_sums(_with_mean_channel(estimate.runs), x4, y4, r_var, finite, block)
        tiers = [base] + [_scan_level(sums, b // block, info, block) for b in scales[1:]]
    else:  # aligned blocks of each size
        tiers = [base] + [_block_level(sides, b) for b in scales[1:]]
    # One Holm family over the blocks of every scale and R, G, B.
    p_all = np.concatenate([lv["p"].ravel() for lv in tiers])
    rej_all, adj_all = holm(p_all, alpha / 2)
    offs = np.cumsum([0] + [lv["p"].size for lv in tiers])
    for i, lv in enumerate(tiers):
        lv["rej"] = rej_all[offs[i]:offs[i + 1]].reshape(lv["p"].shape)
        lv["adj"] = adj_all[offs[i]:offs[i + 1]].reshape(lv["p"].shape)
    # Whole-image mean test on (R+G+B)/3.
    mean_var = base["mean_var"]
    m_ref = float(y4[..., 3][finite].mean())
    m_diff = float((x4[..., 3] - y4[..., 3])[finite].mean())
    sd = math.sqrt(max(float(mean_var[3]), 0.0))
    z_mean = m_diff / sd if sd > 0 else (math.inf if m_diff else 0.0)
    p_mean = float(2 * stats.norm.sf(abs(z_mean)))
    q99 = stats.norm.ppf(0.995)
    bias = m_diff / m_ref if m_ref != 0 else math.nan
    ci = ((m_diff - q99 * sd) / m_ref, (m_diff + q99 * sd) / m_ref) if m_ref > 0 else (math.nan, math.nan)
    p_value = float(min(1.0, 2 * min(p_mean, float(adj_all.min()) if adj_all.size else 1.0)))
    consistent = not (p_mean <= alpha / 2 or rej_all.any())
    # Signed map on the base grid: the most significant rejected channel of each block; a block flagged only
    # at a coarser scale marks the base blocks it covers.
    tb = base["t"]
    best = np.argmax(np.abs(tb), axis=-1)
    zbest = np.take_along_axis(tb, best[..., None], axis=-1)[..., 0]
    signed = np.where(base["rej"].any(axis=-1), np.sign(zbest), 0).astype(np.int8)
    base["shown"] = base["rej"].any(axis=-1)
    for lv in tiers[1:]:
        signed = _paint_coarse(signed, lv, block)
    # Power.
    zp = stats.norm.ppf(POWER)
    mdb = (stats.norm.ppf(1 - alpha / 4) + zp) * sd / m_ref if m_ref > 0 else math.nan
    m_tests = max(p_all.size, 1)
    var, df, refb = base["var"], base["df"], base["refb"]
    tcrit = stats.t.isf(alpha / 2 / m_tests / 2, df[..., :3])
    with np.errstate(invalid="ignore", divide="ignore"):
        rel = (tcrit + zp) * np.sqrt(var[..., :3]) / np.abs(refb[..., :3])
    rel_best = np.where((refb[..., :3] > 0) & np.isfinite(rel), rel, np.inf).min(axis=-1)
    mdbb = float(np.median(rel_best[np.isfinite(rel_best)])) if np.isfinite(rel_best).any() else math.nan
    flagged = []
    for lv in tiers:
        b, step = lv["size"], lv["step"]
        lb = np.argmax(np.where(lv["rej"], np.abs(lv["t"]), -1.0), axis=-1)
        for by, bx in zip(*np.nonzero(lv["shown"]), strict=True):
            c = int(lb[by, bx])
            tv, rb = float(lv["t"][by, bx, c]), lv["refb"][by, bx, c]
            flagged.append({"x": int(bx * step), "y": int(by * step), "w": int(min(b, w - bx * step)),
                            "h": int(min(b, h - by * step)), "channel": "RGB"[c],
                            "sign": "too bright" if tv > 0 else "too dark", "t": tv,
                            "p_adjusted": float(lv["adj"][by, bx, c]),
                            "relative_difference": float(lv["diff"][by, bx, c] / rb) if rb else None})
    return CheckResult(
        consistent=consistent, p_value=p_value, bias=bias, bias_ci=ci, bias_p=p_mean,
        method=base["method"], block=block, alpha=alpha, blocks=int(signed.size),
        dark_blocks=int((signed < 0).sum()), bright_blocks=int((signed > 0).sum()),
        min_detectable_bias=float(mdb), min_detectable_block_bias=mdbb, correlation_factor=base["fac"],
        nonfinite=nonfinite, signed_map=signed, z_map=np.where(base["cnt"][..., 0] > 0, zbest, 0.0),
        flagged=flagged, user_renders=len(user), scales=scales)


def reference_jobs(scene: Path, integrator: str, spp: int, runs: int, seed: int,
                   resolution: tuple[int, int] | None = None, workers: int | None = None) -> list[RenderJob]:
    """The independent brdflab runs of a check: ``runs`` jobs of ``spp`` samples with their own seeds."""
    return [RenderJob(Path(scene), integrator, spp, run_seed(seed, k, "check"), resolution, workers)
            for k in range(runs)]


def run_check(user: list[np.ndarray], scene: Path, integrator: str, spp: int = 32, runs: int = 4,
              seed: int = 0, ref: np.ndarray | None = None, ref_var: np.ndarray | None = None,
              block: int = BLOCK, alpha: float = ALPHA, workers: int | None = None,
              map_fn: Callable = map, progress: Callable[[str], None] | None = None,
              resolution: tuple[int, int] | None = None, user_spp: int | None = None,
              levels: int = LEVELS) -> CheckResult:
    """Render brdflab's estimate (unless ``ref`` is given) and run :func:`check_images`.

    The ``runs`` renders are independent jobs (:func:`reference_jobs`) evaluated by ``map_fn``;
    ``resolution`` (width, height) replaces the scene camera's (quick checks, tests).
    """
    say = progress or (lambda msg: None)
    check_inputs(user, ref_var, user_spp, block=block, ref=ref)
    if ref is None and map_fn is map:  # the estimate's cost, said before it starts (a cluster's jobs: by each)
        import os

        from brdflab.limits import check_spp, check_work

        h, w = resolution[::-1] if resolution else user[0].shape[:2]
        check_work(runs * check_spp(spp) * h * w, workers or os.cpu_count() or 1,
                   f"brdflab's estimate ({runs} runs × {spp:,} spp at {w}×{h})", limit_option=None)
    t0 = time.perf_counter()
    if ref is not None:
        est = Estimate(np.asarray(ref, dtype=np.float64), None,
                       None if ref_var is None else np.asarray(ref_var, dtype=np.float64), "given reference")
        k = 0
    else:
        h, w = user[0].shape[:2]
        jobs = reference_jobs(scene, integrator, spp, runs, seed, resolution, workers)
        images = []
        for i, (img, secs) in enumerate(map_fn(run_job, jobs)):
            images.append(img)
            say(f"brdflab run {i + 1}/{runs}: {integrator}, {spp} spp, {secs:.1f} s")
        if images[0].shape[:2] != (h, w):
            raise ImageError(f"the image is {w}×{h} pixels but the scene renders "
                             f"{images[0].shape[1]}×{images[0].shape[0]}")
        est = Estimate.from_runs(images, f"brdflab {integrator}, {runs} runs × {spp} spp, independent seeds", spp)
        k = runs
    res = check_images(user, est, block, alpha, user_spp, levels)
    res.reference_runs, res.reference_spp = k, spp if k else 0
    res.reference_label = est.label
    res.seconds = time.perf_counter() - t0
    res.estimate = est.mean.astype(np.float32)  # for the page
    res.runs = est.runs
    return res
