"""Variance comparison studies: which estimator wins where, as error against run time.

A study renders one scene with each integrator **progressively**: one run to the largest sample count
yields every smaller checkpoint (1, 2, 4, …) with its elapsed time, without re-rendering. Each
checkpoint is compared with a reference (given, or a high-spp ``direct_mis`` render made first with an
independent seed and labelled as such) using the metrics of :mod:`brdflab.report.metrics`.

Outputs (in the study folder): ``results.csv``/``results.json`` (integrator, spp, seconds, relMSE, MSE,
MAPE, bias), log-log plots of error versus time and versus spp with a 1/N slope (PNG and SVG),
per-pixel relMSE maps per integrator (where each strategy fails), equal-spp and equal-time image
comparisons, the figures ``<stem>_<integrator>_<spp>spp.exr/.png`` and a self-contained
``report.html`` with synchronised zoom and an automatically written summary.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from brdflab.imageio import read_exr, write_exr, write_png
from brdflab.report import page as html
from brdflab.report.metrics import compare, relmse_map

#: Human-readable names of the integrators.
LABELS = {"direct_ems": "emitter sampling", "direct_mats": "BSDF sampling", "direct_mis": "MIS (balance)",
          "direct_whitted": "Whitted", "normals": "normals"}
COLORS = {"direct_ems": "#1f77b4", "direct_mats": "#d62728", "direct_mis": "#2ca02c"}


@dataclass
class Checkpoint:
    """Error of one integrator after ``spp`` samples per pixel and ``seconds`` of rendering."""

    integrator: str
    spp: int
    seconds: float
    relmse: float
    mse: float
    mape: float
    bias: float


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
    pass_images: dict[tuple[str, int], np.ndarray] = field(default_factory=dict)
    """Every pass image (float16), for the equal-time comparison."""
    resolution: tuple[int, int] = (0, 0)
    workers: int = 1

    def curve(self, integrator: str) -> list[Checkpoint]:
        """The checkpoints of one integrator, by increasing spp."""
        return sorted((c for c in self.checkpoints if c.integrator == integrator), key=lambda c: c.spp)


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


def run_study(
    scene_path: Path,
    integrators: list[str],
    spp_list: list[int],
    reference: Path | None = None,
    reference_spp: int | None = None,
    workers: int | None = None,
    seed: int = 0,
    progress: Callable[[str], None] | None = None,
    cluster=None,
) -> Study:
    """Render ``scene_path`` with each integrator up to max(spp_list) and measure error at every pass.

    Parameters
    ----------
    scene_path
        The Nori scene.
    integrators
        Integrator types to compare.
    spp_list
        Sample counts reported as figures (every pass boundary is measured for the curves).
    reference
        Reference EXR; without one, a ``direct_mis`` render at ``reference_spp`` (default 4 × max spp)
        with an independent seed is made first.
    workers, seed
        Passed to the renderer.
    progress
        Receives one-line status messages (integrator, spp, ETA).
    cluster
        A :class:`brdflab.cluster.Cluster` (or address): every render's (pass, tile) units run there. The
        renders themselves stay one after another, so each integrator's checkpoint times are measured on
        the same resources (what an equal-time comparison needs); the images, hence every error figure,
        are bit-identical to a local study.
    """
    from brdflab.render import render
    from brdflab.scene.loader import load_scene

    say = progress or (lambda msg: None)
    max_spp = max(spp_list)
    scenes = {name: load_scene(scene_path, name) for name in integrators}
    first = scenes[integrators[0]]
    cam = first.camera
    if reference is not None:
        ref = read_exr(reference)
        label = f"{reference}"
    else:
        ref_spp = reference_spp or 4 * max_spp
        say(f"reference: direct_mis at {ref_spp} spp (made by brdflab; no reference was given)")
        ref_scene = load_scene(scene_path, "direct_mis")
        ref, stats = render(ref_scene, spp=ref_spp, seed=seed + 1_000_003, workers=workers, cluster=cluster,
                            progress=_eta_printer(say, f"reference {ref_spp} spp"))
        label = f"brdflab direct_mis, {ref_spp} spp, independent seed ({stats.seconds:.1f} s)"
    study = Study(scene_path, integrators, sorted(set(spp_list)), label, ref, resolution=(cam.width, cam.height))
    for name in integrators:
        scene = scenes[name]
        say(f"{name}: rendering to {max_spp} spp")

        def on_pass(spp: int, seconds: float, film, name=name) -> None:
            img = film.image()
            m = compare(img, ref)
            study.checkpoints.append(Checkpoint(name, spp, seconds, m.relmse, m.mse, m.mape, m.bias))
            if spp in study.spp:
                study.images[(name, spp)] = img
            study.pass_images[(name, spp)] = img.astype(np.float16)

        _, stats = render(scene, spp=max_spp, seed=seed, workers=workers, on_pass=on_pass, cluster=cluster,
                          checkpoints=tuple(study.spp), progress=_eta_printer(say, f"{name} {max_spp} spp"))
        study.workers = stats.workers
    return study


def _eta_printer(say: Callable[[str], None], label: str) -> Callable:
    state = {"t": 0.0}

    def progress(frac: float, stats) -> None:
        now = stats.seconds
        if now - state["t"] >= 5.0 or frac >= 1.0:
            state["t"] = now
            eta = now * (1 - frac) / frac if frac > 0 else 0.0
            say(f"  {label}: {100 * frac:.0f}% after {now:.1f} s, ETA {eta:.1f} s")

    return progress


# -- outputs ---------------------------------------------------------------------------------------------
def write_tables(study: Study, out: Path) -> None:
    """``results.csv`` and ``results.json``."""
    rows = [c.__dict__ for c in sorted(study.checkpoints, key=lambda c: (c.integrator, c.spp))]
    with open(out / "results.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    meta = {"scene": str(study.scene), "reference": study.reference_label, "resolution": study.resolution,
            "workers": study.workers, "checkpoints": rows}
    (out / "results.json").write_text(json.dumps(meta, indent=2))


def plot_curves(study: Study, out: Path) -> list[Path]:
    """Log-log relMSE versus time and versus spp, with a 1/N slope; PNG and SVG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    paths = []
    for key, xlabel in (("seconds", "render time [s]"), ("spp", "samples per pixel")):
        fig, ax = plt.subplots(figsize=(6.4, 4.4), dpi=110)
        for name in study.integrators:
            curve = [c for c in study.curve(name) if c.relmse > 0]
            xs = [getattr(c, key) for c in curve]
            ax.loglog(xs, [c.relmse for c in curve], "o-", ms=3.5, color=COLORS.get(name),
                      label=f"{LABELS.get(name, name)} ({name})")
        allc = [c for c in study.checkpoints if c.relmse > 0 and getattr(c, key) > 0]
        if allc:
            x0 = min(getattr(c, key) for c in allc)
            x1 = max(getattr(c, key) for c in allc)
            y0 = max(c.relmse for c in allc if getattr(c, key) == x0)
            ax.loglog([x0, x1], [y0, y0 * x0 / x1], "k--", lw=0.8, label="1/N slope")
        ax.set_xlabel(xlabel)
        ax.set_ylabel("relMSE  (x − r)²/(r² + 0.01)")
        ax.set_title(f"{study.scene.stem}: error versus {'time' if key == 'seconds' else 'samples'}")
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
    """Per-pixel relMSE at the largest spp, one PNG per integrator on a shared log colour scale."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm

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
        ax.set_title(f"{LABELS.get(name, name)}: relMSE per pixel, {top} spp", fontsize=9)
        fig.colorbar(im, ax=ax, fraction=0.046, pad=0.02)
        fig.tight_layout()
        p = out / f"relmse_map_{name}.png"
        fig.savefig(p)
        plt.close(fig)
        paths[name] = p
    return paths


def equal_time(study: Study) -> tuple[float, dict[str, Checkpoint]]:
    """The largest time budget every integrator reaches, and each one's last checkpoint within it."""
    budget = min(study.curve(n)[-1].seconds for n in study.integrators)
    picks = {}
    for n in study.integrators:
        within = [c for c in study.curve(n) if c.seconds <= budget * 1.0001]
        picks[n] = within[-1] if within else study.curve(n)[0]
    return budget, picks


def summary(study: Study) -> list[str]:
    """Automatically written findings, e.g. 'MIS reaches relMSE 0.01 in 12 s, 3.1× faster than …'."""
    finals = {n: study.curve(n)[-1] for n in study.integrators}
    lines = []
    best_final = min(finals.values(), key=lambda c: c.relmse)
    lines.append(f"At {best_final.spp} spp the lowest error is {LABELS.get(best_final.integrator)} "
                 f"(relMSE {best_final.relmse:.3g}); " + ", ".join(
                     f"{LABELS.get(n)} {c.relmse:.3g}" for n, c in finals.items() if n != best_final.integrator) + ".")
    # Target: the second-worst final error, so at least two strategies reach it within their runs.
    ordered = sorted(c.relmse for c in finals.values())
    target = ordered[-2] if len(ordered) >= 2 else ordered[-1]
    times = {n: time_to_reach(study.curve(n), target) for n in study.integrators}
    reached = {n: t for n, t in times.items() if t is not None}
    if len(reached) >= 2:
        fastest = min(reached, key=reached.get)
        others = [f"{reached[n] / reached[fastest]:.1f}× faster than {LABELS.get(n)} ({reached[n]:.2f} s)"
                  for n in reached if n != fastest]
        lines.append(f"{LABELS.get(fastest)} reaches relMSE {target:.3g} in {reached[fastest]:.2f} s, "
                     + "; ".join(others) + ".")
    for n in study.integrators:
        if times[n] is None:
            lines.append(f"{LABELS.get(n)} does not reach relMSE {target:.3g} within {finals[n].spp} spp "
                         f"({finals[n].seconds:.2f} s; final relMSE {finals[n].relmse:.3g}).")
    for n, c in finals.items():
        if abs(c.bias) > 0.01:
            lines.append(f"{LABELS.get(n)}: the image mean differs from the reference by {100 * c.bias:+.2f} % "
                         "at the largest spp (more than 1 %): check for bias or an unconverged reference.")
    budget, picks = equal_time(study)
    best_eq = min(picks.values(), key=lambda c: c.relmse)
    lines.append(f"With an equal budget of {budget:.2f} s, {LABELS.get(best_eq.integrator)} has the lowest error "
                 f"(relMSE {best_eq.relmse:.3g} at {best_eq.spp} spp).")
    return lines


def write_report(study: Study, out: Path) -> Path:
    """Write every output of the study into ``out``; return the path of ``report.html``."""
    out.mkdir(parents=True, exist_ok=True)
    stem = study.scene.stem
    for (name, spp), img in sorted(study.images.items()):
        base = out / f"{stem}_{name}_{spp}spp"
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
        f"Scene {study.scene}, {study.resolution[0]}×{study.resolution[1]}, {study.workers} worker threads. "
        f"Reference: {study.reference_label}. Error metric: relMSE = mean (x − r)²/(r² + 0.01).")))
    sections.append(html.section("Error against run time", html.image_row([
        (out / "error_vs_time.svg", "relMSE versus render time (log-log)"),
        (out / "error_vs_spp.svg", "relMSE versus samples per pixel, with the 1/N slope")], cls="plot")))
    cells = [(out / f"{stem}_{n}_{top}spp.png", f"{LABELS.get(n, n)} — {top} spp, relMSE "
              f"{next(c.relmse for c in study.curve(n) if c.spp == top):.3g}") for n in study.integrators]
    cells.append((out / f"{stem}_reference.png", "reference"))
    ref_png = out / f"{stem}_reference.png"
    sections.append(html.section(f"Equal samples ({top} spp) — click an image to zoom all, A/B (or R) to flip "
                                 "with the reference", html.image_row(cells, ref=ref_png)))
    eq_cells = []
    for n, c in picks.items():
        img_path = out / f"{stem}_{n}_{c.spp}spp.png"
        if not img_path.exists():
            write_png(img_path, study.pass_images[(n, c.spp)].astype(np.float32))
        eq_cells.append((img_path, f"{LABELS.get(n, n)} — {c.spp} spp in {c.seconds:.2f} s, relMSE {c.relmse:.3g}"))
    sections.append(html.section(f"Equal time (≈ {budget:.2f} s)", html.image_row(eq_cells, ref=ref_png)))
    sections.append(html.section("Where each strategy fails: per-pixel relMSE", html.image_row(
        [(p, LABELS.get(n, n)) for n, p in maps.items()], cls="plot")))
    rows = [[c.integrator, c.spp, f"{c.seconds:.3f}", f"{c.relmse:.4g}", f"{c.mse:.4g}", f"{c.mape:.4g}",
             f"{100 * c.bias:+.3f} %"] for c in sorted(study.checkpoints, key=lambda c: (c.integrator, c.spp))]
    sections.append(html.section("All checkpoints", html.table(
        ["integrator", "spp", "seconds", "relMSE", "MSE", "MAPE", "bias"], rows)
        + html.esc_p("Also in results.csv and results.json.")))
    page = html.page(f"brdflab variance report — {stem}", "".join(sections))
    path = out / "report.html"
    path.write_text(page)
    return path

