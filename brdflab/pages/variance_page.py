"""The variance study's page (``brdflab report``): tables (``results.csv``/``results.json``), error-against-time and
-spp plots with their bands, per-pixel error maps, MIS weight images, equal-spp and equal-time rows and
``report.html``. The study itself (runs, reference, statistics, statements) is :mod:`brdflab.pages.variance`.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np

from brdflab.imageio import write_exr, write_png
from brdflab.pages import page as html
from brdflab.pages.metrics import relmse_map
from brdflab.pages.variance import BIAS_ALPHA, LEVEL, Study, label, untested_for_bias
from brdflab.pages.variance_summary import _fmt_ci, equal_time, reference_warning, speedup, summary

COLORS = {"direct_ems": "#1f77b4", "direct_mats": "#d62728", "direct_mis": "#2ca02c",
          "direct_mis:balance": "#2ca02c", "direct_mis:power": "#9467bd", "path": "#8c564b", "path_nee": "#e377c2",
          "path_mis": "#17becf"}


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
    from brdflab.viz.mpl import safe_figures

    safe_figures()  # user text is never mathtext; log axes still read 10⁻²
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
    from brdflab.viz.mpl import safe_figures

    safe_figures()  # user text is never mathtext; log axes still read 10⁻²
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm

    from brdflab.pages.metrics import write_signed_map

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
        from brdflab.pages.mis_weights import write_weight_image

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
             f"{100 * r.bias:+.3f} %",
             _fmt_ci(r.bias_ci, 100, "+.2f", unit=" %",
                     why="the reference's own estimator" if r.integrator == study.reference_integrator else "one run"),
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
