"""Variance comparison studies: which estimator wins where, as error against run time, with intervals.

A study renders one scene with each integrator (``NAME`` or ``NAME:VARIANT``, e.g. ``direct_mis:power``)
in ``runs`` **independent runs** (own seeds, :mod:`brdflab.stats.jobs`; one function call per run, so a
cluster can map them). Each run is progressive: one render to the largest sample count yields every
smaller checkpoint (1, 2, 4, …) with its elapsed time. Every checkpoint of every run is compared with a
reference (given, or ``direct_mis`` — ``path_mis`` for the path tracers — renders made first with independent
seeds) using the metrics of :mod:`brdflab.pages.metrics`; per (integrator, spp) the runs give means and 95 % intervals:

* relMSE, MSE, MAPE, seconds: t intervals over the runs on log scale (delta method; positive);
* bias = mean(x)/mean(r) − 1 of the image mean (over R, G, B), averaged over the runs. Its variance comes
  from **within each run** (:func:`bias_variance`: the spread of x − r inside 16-pixel blocks, with the pixels'
  correlation, over hundreds of blocks — so it is known to many degrees of freedom even for 2 runs), plus the
  reference's own image-mean variance, which all runs share: Var = Σ_k v_k / K² + (1 − 1/K)·Var(r̄). The
  spread of K run biases (K − 1 degrees of freedom) made the test anticonservative at small K: two runs that
  agree by chance gave a tiny interval (a correct material was called biased at p = 1e-37 with 2 runs).
  A normal interval; ``bias_significant`` by Holm's step-down procedure over all rows at family-wise level
  :data:`BIAS_ALPHA`; false alarms measured by ``benchmarks/bias_false_alarms.py`` (docs/benchmarks.md);
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

import math
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from brdflab.imageio import read_exr
from brdflab.pages.metrics import compare
from brdflab.stats.jobs import reference_integrator

#: Human-readable names of the integrators.
LABELS = {"direct_ems": "emitter sampling", "direct_mats": "BSDF sampling", "direct_mis": "MIS (balance)",
          "direct_mis:balance": "MIS (balance)", "direct_mis:power": "MIS (power)",
          "direct_whitted": "Whitted", "normals": "normals", "path": "path: BSDF sampling",
          "path_nee": "path: next-event estimation", "path_mis": "path: MIS (balance)"}
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
    bias_var: float = math.nan
    """Variance of ``bias`` estimated within this run (:func:`bias_variance`)."""


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

    ``flip_params`` (from :func:`brdflab.pages.metrics.flip_parameters`) adds HDR-FLIP at the final
    sample count of run 0 (FLIP costs ~0.3 s per exposure step even for small images). ``cluster``: the
    run's (pass, tile) units go there (:func:`brdflab.renderer.render`).
    """
    from brdflab.renderer import render
    from brdflab.stats.jobs import load_for

    res = RunResult(job.integrator, run, [])
    figures = set(figure_spp)

    def on_pass(spp: int, seconds: float, film) -> None:
        img = film.image()
        m = compare(img, ref)
        fl = None
        if flip_params is not None and spp == job.spp and run == 0:
            from brdflab.pages.metrics import flip_error

            fl = flip_error(img, ref, flip_params)
        res.checkpoints.append(Checkpoint(job.integrator, spp, seconds, m.relmse, m.mse, m.mape, m.bias, run, fl,
                                          bias_variance(img, ref)))
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
    its own seed (integrator i, run k: stream ``run_seed(seed, 10000 i + k, "report")``). Run-major order (run 0
    of every integrator, then run 1, …): a change of the machine's load during the study then slows every
    integrator alike instead of making the ones run later look slower (a false "faster" in the time ratios)."""
    from brdflab.stats.jobs import RenderJob, run_seed

    return [(k, RenderJob(Path(scene_path), name, max_spp, run_seed(seed, 10000 * i + k, "report"), resolution,
                          workers))
            for k in range(runs) for i, name in enumerate(integrators)]


def make_reference(scene_path: Path, spp: int, runs: int, seed: int, resolution=None, workers=None,
                   map_fn: Callable = map, say: Callable[[str], None] = lambda m: None, cluster=None,
                   integrator: str = "direct_mis"):
    """brdflab's reference: ``runs`` independent renders of ``spp`` each by ``integrator``.

    Returns (mean image, relMSE of the mean against the truth (estimated), relative variance of its image
    mean, seconds).
    """
    from brdflab.stats.jobs import RenderJob, run_job, run_seed
    from brdflab.stats.render_check import _side_from_runs, _with_mean_channel

    jobs = [RenderJob(Path(scene_path), integrator, spp, run_seed(seed, k, "reference"), resolution, workers)
            for k in range(runs)]
    if cluster is not None:
        from brdflab.renderer import render
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


def bias_variance(img: np.ndarray, ref: np.ndarray, block: int = 16) -> float:
    """Variance of one render's relative bias mean(x)/mean(r) − 1, estimated from that render alone: the spread of
    d = x − r (channel mean) inside ``block``-pixel blocks, corrected for the correlation of neighbouring pixels
    (the reconstruction filter), summed over all blocks (:func:`brdflab.stats.check_scan._residual`). It contains
    the reference's per-pixel noise too. NaN when the image has no valid pixel or a zero mean."""
    from brdflab.stats.check_scan import _residual

    x = np.asarray(img, dtype=np.float64)
    r = np.asarray(ref, dtype=np.float64)
    valid = np.isfinite(x).all(axis=2) & np.isfinite(r).all(axis=2)
    if not valid.any():
        return math.nan
    mr = float(r[valid].mean())
    if mr == 0:
        return math.nan
    d = np.where(valid[..., None], x - r, 0.0).mean(axis=2, keepdims=True)
    _, _, mean_var, _ = _residual(d, valid, block)
    return float(mean_var[0]) / mr**2


def given_reference_noise(ref: np.ndarray, finals: list[np.ndarray]) -> tuple[float, float]:
    """Noise of a given reference from K runs x_k of an integrator (module docstring):
    τ² = (K·(ā − r)² − mean_k (x_k − r)²)/(K − 1) per pixel, after removing one global scale fit;
    returns (relMSE of the reference, relative variance of its image mean)."""
    from brdflab.stats.render_check import _side_from_runs, _with_mean_channel

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
        Reference EXR; without one, :data:`REF_RUNS` renders of ``reference_spp`` by ``direct_mis`` (``path_mis``
        when a path tracer is compared: :func:`reference_integrator`)
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
        ref_int = reference_integrator(integrators)
        say(f"reference: {REF_RUNS} × {ref_spp} spp of {ref_int} (made by brdflab; no reference was given)")
        ref, ref_noise, ref_var, secs = make_reference(scene_path, ref_spp, REF_RUNS, seed, resolution, workers,
                                                       map_fn, say, cluster, ref_int)
        label_ = (f"brdflab {ref_int}, {REF_RUNS} runs × {ref_spp} spp, independent seeds ({secs:.1f} s); "
                  f"its own relMSE ≈ {ref_noise:.3g}")
    study = Study(scene_path, integrators, spp_list, label_, ref, resolution=(width, height), runs=runs,
                  reference_noise=ref_noise, reference_mean_var=ref_var,
                  reference_integrator=None if reference is not None else reference_integrator(integrators))
    flip_params = None
    if flip:
        from brdflab.pages.metrics import flip_parameters

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
        from brdflab.pages.mis_weights import mis_weight_image

        for name in integrators:
            if name.split(":")[0] == "direct_mis":
                say(f"MIS weight image of {name}")
                study.mis_weights[name] = mis_weight_image(scene_path, name, min(max_spp, 64), seed, resolution,
                                                           workers)
    return study


def aggregate(study: Study) -> list[Row]:
    """Per (integrator, spp) reached by every run: means and intervals over the runs (module docstring)."""
    from scipy import stats as st

    from brdflab.stats.intervals import mean_interval, positive_interval

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
            within = np.array([c.bias_var for c in cs])
            # the runs' own variances (each contains the shared reference noise once) + the rest of the shared part
            var = float(within.sum() / k**2 + (1.0 - 1.0 / k) * study.reference_mean_var)
            bias = float(b.mean())
            if name == study.reference_integrator or not (np.isfinite(var) and var > 0):
                lo = hi = math.nan  # measured against itself (a shared bias cannot show), or nothing to judge by
                p = math.nan
            else:
                lo, hi = mean_interval(bias, var, np.inf, LEVEL)
                p = float(2 * st.norm.sf(abs(bias) / math.sqrt(var)))
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

