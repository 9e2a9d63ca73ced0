"""Variance comparison studies: which estimator wins where, as error against run time, with intervals.

A study renders one scene with each integrator (``NAME`` or ``NAME:VARIANT``, e.g. ``direct_mis:power``)
in ``runs`` **independent runs** (own seeds, :mod:`brdflab.stats.jobs`; one function call per run, so a
cluster can map them). Each run is progressive: one render to the largest sample count yields every
smaller checkpoint (1, 2, 4, …) with its elapsed time. Every checkpoint of every run is compared with a
reference (given, or ``direct_mis`` renders made first with independent seeds) using the metrics of
:mod:`brdflab.report.metrics`; per (integrator, spp) the runs give means and 95 % intervals:

* relMSE, MSE, MAPE, seconds: t intervals over the runs on log scale (delta method; positive);
* bias = mean(x)/mean(r) − 1 of the image mean (over R, G, B): t interval whose variance adds the
  reference's own image-mean variance (Welch–Satterthwaite df); ``bias_significant`` by Holm's
  step-down procedure over all rows at family-wise level :data:`BIAS_ALPHA`;
* efficiency = 1/(relMSE · seconds), from the per-run products p_k = relMSE_k · seconds_k as
  1/mean(p) with a delta-method interval on log scale; speed-ups are ratios of mean products
  (:func:`brdflab.stats.intervals.log_ratio_interval`), stated only when the interval excludes 1;
* time to reach a target relMSE: per run by log-log interpolation of its curve, t interval on log scale.

The reference's own noise (its relMSE against the truth) is estimated from its runs (self-made) or by
τ² = (K·(ā − r)² − mean_k (x_k − r)²)/(K − 1) from the K runs of the best integrator (given reference);
the report warns when it exceeds :data:`REF_NOISE_WARN` of the smallest error at the largest spp. The
self-made reference has :data:`REF_RUNS` runs of 4 × the largest spp each (16 × in total).

Outputs (in the study folder): ``results.csv``/``results.json`` (one row per integrator and spp),
log-log plots of error versus time and versus spp with 95 % bands (PNG and SVG), per-pixel relMSE maps
and signed difference maps per integrator, MIS weight images (for ``direct_mis``), equal-spp and
equal-time image comparisons, the figures ``<stem>_<integrator>_<spp>spp.exr/.png`` and a
self-contained ``report.html`` with synchronised zoom and an automatically written summary.
"""

from __future__ import annotations

import csv
import json
import math
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from brdflab.imageio import read_exr, write_exr, write_png
from brdflab.report import page as html
from brdflab.report.metrics import compare, relmse_map

#: Human-readable names of the integrators.
LABELS = {"direct_ems": "emitter sampling", "direct_mats": "BSDF sampling", "direct_mis": "MIS (balance)",
          "direct_mis:balance": "MIS (balance)", "direct_mis:power": "MIS (power)",
          "direct_whitted": "Whitted", "normals": "normals"}
COLORS = {"direct_ems": "#1f77b4", "direct_mats": "#d62728", "direct_mis": "#2ca02c",
          "direct_mis:balance": "#2ca02c", "direct_mis:power": "#9467bd"}
#: Confidence level of the report's intervals.
LEVEL = 0.95
#: Family-wise level of the bias flags.
BIAS_ALPHA = 0.01
#: Warn when the reference's own relMSE exceeds this share of the smallest error at the largest spp.
REF_NOISE_WARN = 0.1
#: Runs of the self-made reference.
REF_RUNS = 4

#: Files of :func:`write_report` besides ``<stem>_*`` (glob patterns; see :func:`brdflab.outputs.prepare_folder`).
REPORT_PATTERNS = ("report.html", "results.csv", "results.json", "error_vs_*.png", "error_vs_*.svg",
                   "relmse_map_*.png", "signed_map_*.png", "mis_weights_*.png")


def label(name: str) -> str:
    """Human-readable name of an integrator spec."""
    return LABELS.get(name, name)


@dataclass
class Checkpoint:
    """Error of one integrator after ``spp`` samples per pixel and ``seconds`` of rendering (one run)."""

    integrator: str
    spp: int
    seconds: float
    relmse: float
    mse: float
    mape: float
    bias: float
    run: int = 0
    flip: float | None = None


@dataclass
class Row:
    """Statistics over the runs of one integrator at one sample count (intervals are [low, high])."""

    integrator: str
    spp: int
    runs: int
    seconds: float
    seconds_ci: list[float]
    relmse: float
    relmse_ci: list[float]
    mse: float
    mse_ci: list[float]
    mape: float
    mape_ci: list[float]
    bias: float
    bias_ci: list[float]
    bias_p: float
    bias_significant: bool
    efficiency: float
    efficiency_ci: list[float]
    flip: float | None = None
    flip_ci: list[float] | None = None


@dataclass
class Study:
    """Everything a variance comparison measured."""

    scene: Path
    integrators: list[str]
    spp: list[int]
    reference_label: str
    reference: np.ndarray
    checkpoints: list[Checkpoint] = field(default_factory=list)
    images: dict[tuple[str, int], np.ndarray] = field(default_factory=dict)
    """Run 0's image at every figure spp."""
    pass_images: dict[tuple[str, int], np.ndarray] = field(default_factory=dict)
    """Run 0's image at every pass (float16), for the equal-time comparison."""
    resolution: tuple[int, int] = (0, 0)
    workers: int = 1
    runs: int = 1
    reference_noise: float = math.nan
    """Estimated relMSE of the reference against the truth."""
    reference_mean_var: float = 0.0
    """Variance of the reference's image mean, relative (divided by its mean²)."""
    rows: list[Row] = field(default_factory=list)
    """Rows at the figure sample counts (tables, bias flags)."""
    all_rows: list[Row] = field(default_factory=list)
    """Rows at every pass boundary (curves, equal time)."""
    mis_weights: dict[str, np.ndarray] = field(default_factory=dict)
    """Per MIS integrator: (H, W) fraction of the estimate carried by emitter samples."""
    reference_integrator: str | None = None
    """The estimator brdflab rendered the reference with (None for a given ``--ref``): its own rows are not
    tested for bias, since a bias they share with the reference cannot show (:func:`aggregate`)."""

    def curve(self, integrator: str, run: int = 0) -> list[Checkpoint]:
        """The checkpoints of one integrator's run, by increasing spp."""
        return sorted((c for c in self.checkpoints if c.integrator == integrator and c.run == run),
                      key=lambda c: c.spp)

    def row_curve(self, integrator: str) -> list[Row]:
        """The statistics rows of one integrator, by increasing spp."""
        return sorted((r for r in self.rows if r.integrator == integrator), key=lambda r: r.spp)


def time_to_reach(curve: list[Checkpoint], target: float) -> float | None:
    """Seconds an integrator needs to reach relMSE ≤ ``target`` (log-log interpolation), or None."""
    prev = None
    for c in curve:
        if c.relmse <= target:
            if prev is None or prev.relmse <= 0 or c.relmse <= 0 or prev.seconds <= 0:
                return c.seconds
            # Interpolate log(time) linearly in log(error) between the two checkpoints.
            a = (math.log(target) - math.log(prev.relmse)) / (math.log(c.relmse) - math.log(prev.relmse))
            return math.exp(math.log(prev.seconds) + a * (math.log(c.seconds) - math.log(prev.seconds)))
        prev = c
    return None


@dataclass
class RunResult:
    """What one independent run of one integrator measured (small: sent back by a cluster worker)."""

    integrator: str
    run: int
    checkpoints: list[Checkpoint]
    images: dict[int, np.ndarray] = field(default_factory=dict)
    """Images at the figure sample counts (run 0 only) and the final image (every run)."""
    pass_images: dict[int, np.ndarray] = field(default_factory=dict)
    """Run 0: every pass image (float16), for the equal-time comparison."""
    seconds: float = 0.0
    workers: int = 1


def measure_run(job, ref: np.ndarray, figure_spp: tuple[int, ...], run: int, flip_params: dict | None = None,
                cluster=None) -> RunResult:
    """Render ``job`` progressively and measure every pass boundary against ``ref`` (one independent run).

    ``flip_params`` (from :func:`brdflab.report.metrics.flip_parameters`) adds HDR-FLIP at the final
    sample count of run 0 (FLIP costs ~0.3 s per exposure step even for small images). ``cluster``: the
    run's (pass, tile) units go there (:func:`brdflab.render.render`).
    """
    from brdflab.render import render
    from brdflab.stats.jobs import load_for

    res = RunResult(job.integrator, run, [])
    figures = set(figure_spp)

    def on_pass(spp: int, seconds: float, film) -> None:
        img = film.image()
        m = compare(img, ref)
        fl = None
        if flip_params is not None and spp == job.spp and run == 0:
            from brdflab.report.metrics import flip_error

            fl = flip_error(img, ref, flip_params)
        res.checkpoints.append(Checkpoint(job.integrator, spp, seconds, m.relmse, m.mse, m.mape, m.bias, run, fl))
        if spp == job.spp or (run == 0 and spp in figures):
            res.images[spp] = img
        if run == 0:
            res.pass_images[spp] = img.astype(np.float16)

    _, stats = render(load_for(job), spp=job.spp, seed=job.seed, workers=job.workers, on_pass=on_pass,
                      checkpoints=tuple(sorted(figures)), cluster=cluster)
    res.seconds, res.workers = stats.seconds, stats.workers
    return res


def study_jobs(scene_path: Path, integrators: list[str], max_spp: int, runs: int, seed: int,
               resolution: tuple[int, int] | None = None, workers: int | None = None) -> list[tuple[int, object]]:
    """The (run index, :class:`~brdflab.stats.jobs.RenderJob`) list of a study: every integrator × run has
    its own seed (integrator i, run k: stream ``run_seed(seed, 10000 i + k, "report")``)."""
    from brdflab.stats.jobs import RenderJob, run_seed

    return [(k, RenderJob(Path(scene_path), name, max_spp, run_seed(seed, 10000 * i + k, "report"), resolution,
                          workers))
            for i, name in enumerate(integrators) for k in range(runs)]


def make_reference(scene_path: Path, spp: int, runs: int, seed: int, resolution=None, workers=None,
                   map_fn: Callable = map, say: Callable[[str], None] = lambda m: None, cluster=None):
    """brdflab's reference: ``runs`` independent ``direct_mis`` renders of ``spp`` each.

    Returns (mean image, relMSE of the mean against the truth (estimated), relative variance of its image
    mean, seconds).
    """
    from brdflab.stats.check import _side_from_runs, _with_mean_channel
    from brdflab.stats.jobs import RenderJob, run_job, run_seed

    jobs = [RenderJob(Path(scene_path), "direct_mis", spp, run_seed(seed, k, "reference"), resolution, workers)
            for k in range(runs)]
    if cluster is not None:
        from brdflab.render import render
        from brdflab.stats.jobs import load_for

        def run_job(job):  # noqa: F811 - the same run, its units on the cluster
            img, stats = render(load_for(job), spp=job.spp, seed=job.seed, workers=job.workers, cluster=cluster)
            return img, stats.seconds
    images, secs = [], 0.0
    for k, (img, t) in enumerate(map_fn(run_job, jobs)):
        images.append(np.asarray(img, dtype=np.float64))
        secs += t
        say(f"  reference run {k + 1}/{runs}: {spp} spp in {t:.1f} s")
    a = np.stack(images)
    ref = a.mean(axis=0)
    var_mean = a.var(axis=0, ddof=1) / runs
    noise = float(np.mean(var_mean / (ref * ref + 0.01)))
    valid = np.isfinite(ref).all(axis=2)
    _, _, mean_var, _ = _side_from_runs(_with_mean_channel(a), valid, 16)
    rel_var = float(mean_var[3]) / float(ref[valid].mean()) ** 2
    return ref.astype(np.float32), noise, rel_var, secs


def given_reference_noise(ref: np.ndarray, finals: list[np.ndarray]) -> tuple[float, float]:
    """Noise of a given reference from K runs x_k of an integrator (module docstring):
    τ² = (K·(ā − r)² − mean_k (x_k − r)²)/(K − 1) per pixel, after removing one global scale fit;
    returns (relMSE of the reference, relative variance of its image mean)."""
    from brdflab.stats.check import _side_from_runs, _with_mean_channel

    x = np.stack([np.asarray(f, dtype=np.float64) for f in finals])
    k = x.shape[0]
    r = np.asarray(ref, dtype=np.float64)
    d = x - r
    # A bias of the reference (or of the integrator) would pass for noise: remove one global multiplicative
    # fit d ≈ c·r first (one coefficient over all pixels).
    c = float(np.sum(d.mean(axis=0) * r) / max(float(np.sum(r * r)), 1e-30))
    d = d - c * r
    tau2 = (k * d.mean(axis=0) ** 2 - (d * d).mean(axis=0)) / (k - 1)
    noise = max(0.0, float(np.mean(tau2 / (r * r + 0.01))))
    valid = np.isfinite(r).all(axis=2)
    _, _, _, fac = _side_from_runs(_with_mean_channel(x), valid, 16)
    ry = r.mean(axis=2)
    dy = d.mean(axis=3)
    tau2y = (k * dy.mean(axis=0) ** 2 - (dy * dy).mean(axis=0)) / (k - 1)
    rel_var = max(0.0, fac * float(tau2y[valid].mean()) / valid.sum()) / float(ry[valid].mean()) ** 2
    return noise, rel_var


def run_study(
    scene_path: Path,
    integrators: list[str],
    spp_list: list[int],
    reference: Path | None = None,
    reference_spp: int | None = None,
    workers: int | None = None,
    seed: int = 0,
    progress: Callable[[str], None] | None = None,
    runs: int = 4,
    resolution: tuple[int, int] | None = None,
    map_fn: Callable = map,
    flip: bool = True,
    mis_weights: bool = True,
    cluster=None,
) -> Study:
    """Render ``scene_path`` with each integrator in ``runs`` independent progressive runs up to
    max(spp_list) and measure the error of every pass against a reference.

    Parameters
    ----------
    scene_path
        The Nori scene.
    integrators
        Integrator specs to compare (``NAME`` or ``NAME:VARIANT``).
    spp_list
        Sample counts of the table rows and figures (every pass boundary is measured for the curves).
    reference
        Reference EXR; without one, :data:`REF_RUNS` ``direct_mis`` renders of ``reference_spp``
        (default 4 × max spp) with independent seeds are averaged first.
    workers, seed
        Passed to the renderer; run seeds derive from ``seed`` (:func:`study_jobs`).
    progress
        Receives one-line status messages.
    runs
        Independent runs per integrator (≥ 2 for intervals).
    resolution
        (width, height) replacing the camera's.
    map_fn
        ``map``-like function evaluating the independent runs (default: the built-in ``map``).
    flip
        Also measure HDR-FLIP at the largest sample count (run 0).
    mis_weights
        Render the MIS weight images of the MIS integrators (one extra run each).
    cluster
        A :class:`brdflab.cluster.Cluster` (or address): every render's (pass, tile) units run there, the runs
        one after another (checkpoint times measured on the same resources); images bit-identical to local.
    """
    from brdflab.scene.loader import load_scene
    from brdflab.stats.jobs import validate_specs

    say = progress or (lambda msg: None)
    integrators = validate_specs(integrators)
    spp_list = sorted(set(spp_list))
    max_spp = max(spp_list)
    cam = load_scene(scene_path).camera
    width, height = resolution or (cam.width, cam.height)
    from brdflab.limits import check_spp, check_work

    for count in spp_list:
        check_spp(count, "--spp")
    if cluster is None:  # the study's cost, said before it starts (on a cluster each render checks its own)
        total = len(integrators) * max_spp * max(runs, 1) + (0 if reference is not None
                                                              else REF_RUNS * (reference_spp or 4 * max_spp))
        check_work(total * width * height, workers or os.cpu_count() or 1,
                   f"the study ({len(integrators)} integrators × {runs} runs × {max_spp:,} spp and the reference "
                   f"at {width}×{height})", limit_option=None)
    ref_noise, ref_var = math.nan, 0.0
    if reference is not None:
        ref = read_exr(reference)
        if ref.shape[:2] != (height, width):
            from brdflab.errors import ImageError

            raise ImageError(f"reference is {ref.shape[1]}×{ref.shape[0]} pixels, the scene renders "
                             f"{width}×{height}", reference)
        label_ = f"{reference}"
    else:
        ref_spp = reference_spp or 4 * max_spp
        say(f"reference: {REF_RUNS} × {ref_spp} spp of direct_mis (made by brdflab; no reference was given)")
        ref, ref_noise, ref_var, secs = make_reference(scene_path, ref_spp, REF_RUNS, seed, resolution, workers,
                                                       map_fn, say, cluster)
        label_ = (f"brdflab direct_mis, {REF_RUNS} runs × {ref_spp} spp, independent seeds ({secs:.1f} s); "
                  f"its own relMSE ≈ {ref_noise:.3g}")
    study = Study(scene_path, integrators, spp_list, label_, ref, resolution=(width, height), runs=runs,
                  reference_noise=ref_noise, reference_mean_var=ref_var,
                  reference_integrator=None if reference is not None else "direct_mis")
    flip_params = None
    if flip:
        from brdflab.report.metrics import flip_parameters

        flip_params = flip_parameters(ref)
    jobs = study_jobs(scene_path, integrators, max_spp, runs, seed, resolution, workers)
    say(f"{len(jobs)} runs: {', '.join(integrators)} × {runs} runs × {max_spp} spp")
    results: list[RunResult] = list(map_fn(
        lambda kj: measure_run(kj[1], ref, tuple(spp_list), kj[0], flip_params, cluster), jobs))
    for r in results:
        say(f"  {r.integrator} run {r.run + 1}/{runs}: {max_spp} spp in {r.seconds:.1f} s")
        study.checkpoints.extend(r.checkpoints)
        if r.run == 0:
            for spp, img in r.images.items():
                if spp in spp_list:
                    study.images[(r.integrator, spp)] = img
            study.pass_images.update({(r.integrator, spp): img for spp, img in r.pass_images.items()})
        study.workers = r.workers
    if reference is not None and runs >= 2:
        finals = {n: [r.images[max_spp] for r in results if r.integrator == n] for n in integrators}
        best = min(integrators, key=lambda n: float(np.mean([compare(f, ref).relmse for f in finals[n]])))
        study.reference_noise, study.reference_mean_var = given_reference_noise(ref, finals[best])
    study.all_rows = aggregate(study)
    study.rows = [r for r in study.all_rows if r.spp in spp_list]
    flag_bias(study.rows)
    if mis_weights:
        from brdflab.report.mis_weights import mis_weight_image

        for name in integrators:
            if name.split(":")[0] == "direct_mis":
                say(f"MIS weight image of {name}")
                study.mis_weights[name] = mis_weight_image(scene_path, name, min(max_spp, 64), seed, resolution,
                                                           workers)
    return study


def aggregate(study: Study) -> list[Row]:
    """Per (integrator, spp) reached by every run: means and intervals over the runs (module docstring)."""
    from scipy import stats as st

    from brdflab.stats.intervals import mean_interval, positive_interval, welch_df

    rows = []
    for name in study.integrators:
        by_spp: dict[int, list[Checkpoint]] = {}
        for c in study.checkpoints:
            if c.integrator == name:
                by_spp.setdefault(c.spp, []).append(c)
        for spp, cs in sorted(by_spp.items()):
            k = len(cs)
            if k < study.runs:
                continue

            def tci(vals):
                m, lo, hi = positive_interval(vals, LEVEL)
                return m, [lo, hi]

            sec, sec_ci = tci([c.seconds for c in cs])
            rel, rel_ci = tci([c.relmse for c in cs])
            mse, mse_ci = tci([c.mse for c in cs])
            mape, mape_ci = tci([c.mape for c in cs])
            b = np.array([c.bias for c in cs])
            vb = (b.var(ddof=1) / k if k > 1 else 0.0)
            var = vb + study.reference_mean_var
            df = float(welch_df([vb, study.reference_mean_var], [max(k - 1, 1), np.inf])) if var > 0 else np.inf
            bias = float(b.mean())
            if name == study.reference_integrator:  # measured against itself: a shared bias cannot show
                lo = hi = math.nan
                p = math.nan
            elif var > 0 and k > 1:
                lo, hi = mean_interval(bias, var, df, LEVEL)
                tstat = bias / math.sqrt(var)
                p = float(2 * (st.t.sf(abs(tstat), df) if np.isfinite(df) else st.norm.sf(abs(tstat))))
            else:
                lo = hi = math.nan
                p = math.nan
            prod = np.array([c.relmse * c.seconds for c in cs])
            eff = 1.0 / prod.mean() if prod.mean() > 0 else math.inf
            _, plo, phi = positive_interval(prod, LEVEL)
            eff_ci = [1.0 / phi, 1.0 / plo] if k > 1 and plo > 0 else [math.nan, math.nan]
            flips = [c.flip for c in cs if c.flip is not None]
            fl, fl_ci = (flips[0], None) if len(flips) == 1 else tci(flips) if len(flips) == k else (None, None)
            rows.append(Row(name, spp, k, sec, sec_ci, rel, rel_ci, mse, mse_ci, mape, mape_ci, bias, [lo, hi], p,
                            False, eff, eff_ci, fl, fl_ci))
    return rows


def untested_for_bias(study: Study) -> list[str]:
    """The compared integrators whose bias is not tested: the estimator the reference was rendered with."""
    return [n for n in study.integrators if n == study.reference_integrator]


def flag_bias(rows: list[Row]) -> None:
    """Set ``bias_significant`` by Holm's procedure over all rows at level :data:`BIAS_ALPHA`."""
    from brdflab.stats.intervals import holm

    idx = [i for i, r in enumerate(rows) if np.isfinite(r.bias_p)]
    if not idx:
        return
    rej, _ = holm(np.array([rows[i].bias_p for i in idx]), BIAS_ALPHA)
    for i, flag in zip(idx, rej, strict=True):
        rows[i].bias_significant = bool(flag)


# -- statements -----------------------------------------------------------------------------------------
def _fmt_ci(ci, scale: float = 1.0, fmt: str = ".3g") -> str:
    lo, hi = ci
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return "no interval (one run)"
    return f"{format(scale * lo, fmt)} … {format(scale * hi, fmt)}"


def products(study: Study, name: str, spp: int) -> np.ndarray:
    """Per-run relMSE · seconds of one integrator at ``spp`` (the inverse efficiency)."""
    return np.array([c.relmse * c.seconds for c in study.checkpoints if c.integrator == name and c.spp == spp])


def speedup(study: Study, a: str, b: str, spp: int | None = None) -> tuple[float, float, float]:
    """How many times more efficient ``a`` is than ``b`` at ``spp`` (default: the largest): the ratio of
    mean relMSE·seconds of b to a, with its 95 % interval (delta method on log scale)."""
    from brdflab.stats.intervals import log_ratio_interval

    spp = spp or max(study.spp)
    return log_ratio_interval(products(study, b, spp), products(study, a, spp), LEVEL)


def relmse_ratio(study: Study, a: str, b: str, spp: int | None = None) -> tuple[float, float, float]:
    """relMSE of ``b`` over ``a`` at equal spp (default the largest) with its 95 % interval (time-free)."""
    from brdflab.stats.intervals import log_ratio_interval

    spp = spp or max(study.spp)
    get = lambda n: np.array([c.relmse for c in study.checkpoints if c.integrator == n and c.spp == spp])  # noqa: E731
    return log_ratio_interval(get(b), get(a), LEVEL)


def times_to_reach(study: Study, name: str, target: float) -> list[float | None]:
    """Per run: seconds to reach relMSE ≤ ``target`` (None when a run does not)."""
    return [time_to_reach(study.curve(name, k), target) for k in range(study.runs)]


def equal_time(study: Study) -> tuple[float, dict[str, Row]]:
    """The largest mean time budget every integrator reaches, and each one's last row within it."""
    rows = {n: sorted((r for r in study.all_rows if r.integrator == n), key=lambda r: r.spp)
            for n in study.integrators}
    budget = min(rs[-1].seconds for rs in rows.values())
    picks = {}
    for n, rs in rows.items():
        within = [r for r in rs if r.seconds <= budget * 1.0001]
        picks[n] = within[-1] if within else rs[0]
    return budget, picks


def biased(study: Study) -> dict[str, Row]:
    """Integrators with a significant bias (Holm-corrected) and their most significant row."""
    out = {}
    for n in study.integrators:
        sig = [r for r in study.rows if r.integrator == n and r.bias_significant]
        if sig:
            out[n] = min(sig, key=lambda r: r.bias_p)
    return out


def reference_warning(study: Study) -> str | None:
    """A warning when the reference's own noise is a noticeable part of the error at the largest spp."""
    top = [r for r in study.rows if r.spp == max(study.spp)]
    if not top or not np.isfinite(study.reference_noise):
        return None
    best = min(r.relmse for r in top)
    if best > 0 and study.reference_noise > REF_NOISE_WARN * best:
        return (f"The reference's own noise (relMSE ≈ {study.reference_noise:.3g}) is "
                f"{100 * study.reference_noise / best:.0f} % of the smallest error at {max(study.spp)} spp "
                f"({best:.3g}): errors there are overstated; use a reference with more samples.")
    return None


def summary(study: Study) -> list[str]:
    """Automatically written findings; every comparison with its 95 % interval, claims only when significant."""
    top = max(study.spp)
    finals = {r.integrator: r for r in study.rows if r.spp == top}
    lines = []
    best = min(finals.values(), key=lambda r: r.relmse)
    lines.append(f"At {top} spp ({study.runs} runs each) the lowest error is {label(best.integrator)} "
                 f"(relMSE {best.relmse:.3g}, 95 % CI {_fmt_ci(best.relmse_ci)}); " + ", ".join(
                     f"{label(n)} {r.relmse:.3g} ({_fmt_ci(r.relmse_ci)})" for n, r in finals.items()
                     if n != best.integrator) + ".")
    if study.runs >= 2:
        lead = max(finals, key=lambda n: finals[n].efficiency)
        for n in finals:
            if n == lead:
                continue
            ratio, lo, hi = speedup(study, lead, n)
            if lo > 1:
                lines.append(f"{label(lead)} is {ratio:.2g}× faster than {label(n)} (efficiency 1/(relMSE·time) at "
                             f"{top} spp, 95 % CI {lo:.2g}–{hi:.2g}×).")
            else:
                lines.append(f"{label(lead)} and {label(n)} do not differ significantly in efficiency at {top} spp "
                             f"(ratio {ratio:.2g}, 95 % CI {lo:.2g}–{hi:.2g}).")
        ordered = sorted(r.relmse for r in finals.values())
        target = ordered[-2] if len(ordered) >= 2 else ordered[-1]
        for n in finals:
            ts = times_to_reach(study, n, target)
            if all(t is not None for t in ts):
                m, lo, hi = _log_t([t for t in ts if t is not None])
                lines.append(f"{label(n)} reaches relMSE {target:.3g} in {m:.3g} s (95 % CI {_fmt_ci((lo, hi))} s).")
            else:
                reached = sum(t is not None for t in ts)
                lines.append(f"{label(n)} reaches relMSE {target:.3g} in {reached} of {study.runs} runs within "
                             f"{top} spp.")
    flagged = biased(study)
    for n, r in flagged.items():
        lines.append(f"{label(n)} is biased: its image mean differs from the reference by {100 * r.bias:+.2f} % "
                     f"(95 % CI {_fmt_ci(r.bias_ci, 100, '+.2f')} %) at {r.spp} spp, p = {r.bias_p:.2g} "
                     f"(significant after Holm's correction over {len(study.rows)} comparisons, α = {BIAS_ALPHA}).")
    untested = untested_for_bias(study)
    tested = [r for r in study.rows if r.integrator not in untested]
    if not flagged and study.runs >= 2 and tested:
        lines.append(f"No integrator's image mean differs significantly from the reference (Holm over "
                     f"{len(tested)} comparisons, α = {BIAS_ALPHA}).")
    for n in untested:
        lines.append(f"{label(n)} is not tested for bias: the reference is brdflab's own {n} (independent seeds), "
                     "so a bias they share cannot show; give --ref (a reference from another renderer) to test it.")
    warn = reference_warning(study)
    if warn:
        lines.append(warn)
    budget, picks = equal_time(study)
    best_eq = min(picks.values(), key=lambda r: r.relmse)
    line = (f"With an equal budget of {budget:.3g} s, {label(best_eq.integrator)} has the lowest error "
            f"(relMSE {best_eq.relmse:.3g}, 95 % CI {_fmt_ci(best_eq.relmse_ci)} at {best_eq.spp} spp)")
    if study.runs >= 2 and len(picks) > 1:
        from brdflab.stats.intervals import log_ratio_interval

        second = sorted(picks.values(), key=lambda r: r.relmse)[1]
        get = lambda r: np.array([c.relmse for c in study.checkpoints  # noqa: E731
                                  if c.integrator == r.integrator and c.spp == r.spp])
        ratio, lo, hi = log_ratio_interval(get(second), get(best_eq), LEVEL)
        line += (f"; {ratio:.2g}× lower than {label(second.integrator)} (95 % CI {lo:.2g}–{hi:.2g})" if lo > 1
                 else f"; not significantly lower than {label(second.integrator)} (ratio {ratio:.2g}, "
                      f"95 % CI {lo:.2g}–{hi:.2g})")
    lines.append(line + ".")
    return lines


def _log_t(values: list[float]) -> tuple[float, float, float]:
    """Geometric mean of positive values with a t interval on log scale."""
    from brdflab.stats.intervals import t_interval

    logs = np.log(np.asarray(values, dtype=np.float64))
    m, lo, hi = t_interval(logs, LEVEL)
    return math.exp(m), math.exp(lo) if np.isfinite(lo) else math.nan, math.exp(hi) if np.isfinite(hi) else math.nan


# -- outputs ---------------------------------------------------------------------------------------------
FIELDS = ["integrator", "spp", "runs", "seconds", "seconds_ci", "relmse", "relmse_ci", "mse", "mse_ci", "mape",
          "mape_ci", "flip", "flip_ci", "bias", "bias_ci", "bias_p", "bias_significant", "efficiency",
          "efficiency_ci"]


def _clean(v):
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, list):
        return [_clean(x) for x in v]
    return v


def write_tables(study: Study, out: Path) -> None:
    """``results.csv`` and ``results.json``: one row per (integrator, spp) with [low, high] intervals."""
    rows = [{k: _clean(getattr(r, k)) for k in FIELDS} for r in sorted(study.rows, key=lambda r: (r.integrator,
                                                                                                 r.spp))]
    with open(out / "results.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=FIELDS)
        w.writeheader()
        for r in rows:
            w.writerow({k: json.dumps(v) if isinstance(v, list) else v for k, v in r.items()})
    top = max(study.spp)
    speed = {}
    if study.runs >= 2:
        for a in study.integrators:
            for b in study.integrators:
                if a != b:
                    ratio, lo, hi = speedup(study, a, b)
                    speed[f"{a} vs {b}"] = {"spp": top, "speedup": _clean(ratio), "ci": _clean([lo, hi])}
    meta = {"scene": str(study.scene), "reference": study.reference_label,
            "reference_relmse": _clean(study.reference_noise), "reference_warning": reference_warning(study),
            "resolution": study.resolution, "workers": study.workers, "runs": study.runs, "level": LEVEL,
            "bias_alpha": BIAS_ALPHA, "relmse": "mean over pixels and channels of (x − r)²/(r² + 0.01)",
            "rows": rows, "speedups": speed, "summary": summary(study),
            "checkpoints": [_clean_dict(c.__dict__) for c in sorted(study.checkpoints,
                                                                  key=lambda c: (c.integrator, c.run, c.spp))]}
    from brdflab.outputs import json_text, write_text

    write_text(out / "results.json", json_text(meta, indent=2))


def _clean_dict(d: dict) -> dict:
    return {k: _clean(v) for k, v in d.items()}


def plot_curves(study: Study, out: Path) -> list[Path]:
    """Log-log relMSE versus time and versus spp with 95 % bands over the runs, a 1/N slope; PNG and SVG."""
    import matplotlib

    matplotlib.use("Agg")
    matplotlib.rcParams["text.parse_math"] = False  # user text (a $ in a name) is never mathtext
    import matplotlib.pyplot as plt

    paths = []
    for key, xlabel in (("seconds", "render time [s] (mean over runs)"), ("spp", "samples per pixel")):
        fig, ax = plt.subplots(figsize=(6.4, 4.4), dpi=110)
        for name in study.integrators:
            rows = [r for r in study.all_rows if r.integrator == name and r.relmse > 0]
            rows.sort(key=lambda r: r.spp)
            xs = [getattr(r, key) for r in rows]
            color = COLORS.get(name)
            ax.loglog(xs, [r.relmse for r in rows], "o-", ms=3.5, color=color, label=f"{label(name)} ({name})")
            lo = [r.relmse_ci[0] for r in rows]
            hi = [r.relmse_ci[1] for r in rows]
            if study.runs >= 2:
                ax.fill_between(xs, np.maximum(lo, [r.relmse / 10 for r in rows]), hi, color=color, alpha=0.2,
                                lw=0)
        allr = [r for r in study.all_rows if r.relmse > 0 and getattr(r, key) > 0]
        if allr:
            x0 = min(getattr(r, key) for r in allr)
            x1 = max(getattr(r, key) for r in allr)
            y0 = max(r.relmse for r in allr if getattr(r, key) == x0)
            ax.loglog([x0, x1], [y0, y0 * x0 / x1], "k--", lw=0.8, label="1/N slope")
        if np.isfinite(study.reference_noise) and study.reference_noise > 0:
            ax.axhline(study.reference_noise, color="0.5", lw=0.8, ls=":", label="reference's own relMSE")
        ax.set_xlabel(xlabel)
        ax.set_ylabel("relMSE  (x − r)²/(r² + 0.01)")
        ax.set_title(f"{study.scene.stem}: error versus {'time' if key == 'seconds' else 'samples'}"
                     + (f" ({study.runs} runs, 95 % bands)" if study.runs >= 2 else ""), fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
        fig.tight_layout()
        for ext in ("png", "svg"):
            p = out / f"error_vs_{'time' if key == 'seconds' else 'spp'}.{ext}"
            fig.savefig(p)
            paths.append(p)
        plt.close(fig)
    return paths


def plot_error_maps(study: Study, out: Path) -> dict[str, Path]:
    """Per-pixel relMSE (log scale) and the signed difference at the largest spp, per integrator."""
    import matplotlib

    matplotlib.use("Agg")
    matplotlib.rcParams["text.parse_math"] = False  # user text (a $ in a name) is never mathtext
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm

    from brdflab.report.metrics import write_signed_map

    top = max(study.spp)
    maps = {n: relmse_map(study.images[(n, top)], study.reference) for n in study.integrators}
    pos = np.concatenate([m[m > 0].ravel() for m in maps.values()])
    lo = max(float(np.percentile(pos, 1)), 1e-8) if pos.size else 1e-8
    hi = max(float(np.percentile(pos, 99.5)), 10 * lo) if pos.size else 1.0
    paths = {}
    h, w = study.reference.shape[:2]
    for name, m in maps.items():
        fig, ax = plt.subplots(figsize=(5.2, 5.2 * h / w + 0.5), dpi=100)
        im = ax.imshow(np.clip(m, lo, hi), cmap="inferno", norm=LogNorm(lo, hi))
        ax.set_axis_off()
        ax.set_title(f"{label(name)}: relMSE per pixel, {top} spp", fontsize=9)
        fig.colorbar(im, ax=ax, fraction=0.046, pad=0.02)
        fig.tight_layout()
        p = out / f"relmse_map_{_slug(name)}.png"
        fig.savefig(p)
        plt.close(fig)
        paths[name] = p
        sp = out / f"signed_map_{_slug(name)}.png"
        write_signed_map(sp, study.images[(name, top)], study.reference,
                         title=f"{label(name)}: (x − r)/(r + 0.01), {top} spp")
        paths[name + "#signed"] = sp
    return paths


def _slug(name: str) -> str:
    return name.replace(":", "_")


def write_report(study: Study, out: Path) -> Path:
    """Write every output of the study into ``out``; return the path of ``report.html``."""
    out.mkdir(parents=True, exist_ok=True)
    stem = study.scene.stem
    for (name, spp), img in sorted(study.images.items()):
        base = out / f"{stem}_{_slug(name)}_{spp}spp"
        write_exr(base.with_suffix(".exr"), img, extra={"brdflab_spp": str(spp), "brdflab_integrator": name})
        write_png(base.with_suffix(".png"), img)
    write_png(out / f"{stem}_reference.png", study.reference)
    write_tables(study, out)
    plot_curves(study, out)
    maps = plot_error_maps(study, out)
    top = max(study.spp)
    budget, picks = equal_time(study)

    sections = []
    sections.append(html.section("Summary", "<ul>" + "".join(f"<li>{html.esc(s)}</li>" for s in summary(study))
                                 + "</ul>" + html.esc_p(
        f"Scene {study.scene}, {study.resolution[0]}×{study.resolution[1]}, {study.runs} independent runs per "
        f"integrator, {study.workers} workers. Reference: {study.reference_label}. Error metrics: relMSE = mean "
        "over pixels and channels of (x − r)²/(r² + 0.01); MSE; MAPE = mean |x − r|/(|r| + 0.01); HDR-FLIP "
        "(NVIDIA flip-evaluator, exposure range fixed by the reference). Intervals are 95 % (t over runs); "
        f"bias flags are Holm-corrected at α = {BIAS_ALPHA}.")))
    sections.append(html.section("Error against run time", html.image_row([
        (out / "error_vs_time.svg", "relMSE versus render time (log-log), 95 % bands over runs"),
        (out / "error_vs_spp.svg", "relMSE versus samples per pixel, with the 1/N slope")], cls="plot")))
    row_at = {(r.integrator, r.spp): r for r in study.all_rows}
    cells = [(out / f"{stem}_{_slug(n)}_{top}spp.png", f"{label(n)} — {top} spp, relMSE "
              f"{row_at[(n, top)].relmse:.3g}") for n in study.integrators]
    cells.append((out / f"{stem}_reference.png", "reference"))
    ref_png = out / f"{stem}_reference.png"
    sections.append(html.section(f"Equal samples ({top} spp) — click an image to zoom all, A/B (or R) to flip "
                                 "with the reference", html.image_row(cells, ref=ref_png)))
    eq_cells = []
    for n, r in picks.items():
        img_path = out / f"{stem}_{_slug(n)}_{r.spp}spp.png"
        if not img_path.exists():
            write_png(img_path, study.pass_images[(n, r.spp)].astype(np.float32))
        eq_cells.append((img_path, f"{label(n)} — {r.spp} spp in {r.seconds:.2f} s, relMSE {r.relmse:.3g}"))
    sections.append(html.section(f"Equal time (≈ {budget:.2f} s)", html.image_row(eq_cells, ref=ref_png)))
    sections.append(html.section("Where each strategy fails: per-pixel relMSE and signed difference", html.image_row(
        [(p, label(n.split("#")[0]) + (" — signed (blue: too dark, red: too bright)" if "#" in n else ""))
         for n, p in maps.items()], cls="plot")))
    if study.mis_weights:
        from brdflab.report.mis_weights import write_weight_image

        items = []
        for n, wimg in study.mis_weights.items():
            p = out / f"mis_weights_{_slug(n)}.png"
            write_weight_image(p, wimg, f"{label(n)}: share of the estimate from emitter samples")
            items.append((p, f"{label(n)}: emitter (blue) vs BSDF (red) samples' share of the estimate"))
        sections.append(html.section("MIS weights: where each strategy carries the estimate", html.image_row(
            items, cls="plot")))
    untested = untested_for_bias(study)
    rows = [[r.integrator, r.spp, r.runs, f"{r.seconds:.3g}", f"{r.relmse:.4g}", _fmt_ci(r.relmse_ci, fmt=".3g"),
             f"{r.mse:.4g}", f"{r.mape:.4g}", "" if r.flip is None else f"{r.flip:.4f}",
             f"{100 * r.bias:+.3f} %", _fmt_ci(r.bias_ci, 100, "+.2f") + " %",
             "—" if not np.isfinite(r.bias_p) else f"{r.bias_p:.2g}",
             "biased" if r.bias_significant else ("not tested: the reference is this estimator"
                                                  if r.integrator in untested else ""),
             f"{r.efficiency:.4g}", _fmt_ci(r.efficiency_ci, fmt=".3g")]
            for r in sorted(study.rows, key=lambda r: (r.integrator, r.spp))]
    sections.append(html.section("All checkpoints (means over runs, 95 % intervals)", html.table(
        ["integrator", "spp", "runs", "seconds", "relMSE", "relMSE CI", "MSE", "MAPE", "FLIP", "bias", "bias CI",
         "bias p", "flag", "efficiency", "efficiency CI"], rows)
        + html.esc_p("Also in results.csv and results.json.")))
    page = html.page(f"brdflab variance report — {stem}", "".join(sections))
    path = out / "report.html"
    path.write_text(page)
    return path
