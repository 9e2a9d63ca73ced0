"""HTML report of a validation battery: chi-square histograms and verdicts, albedo curves, stability.

Same look as the variance reports (:mod:`brdflab.report.page`); written to ``<dir>/index.html`` with the
figures embedded, so the file opens from the file system.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from brdflab.report import page as html
from brdflab.validate.battery import Battery, _fmt
from brdflab.validate.stability import NOTES


def _histogram_png(obs: np.ndarray, exp: np.ndarray, scale: int = 4) -> bytes:
    """Observed | expected histograms side by side (θ′ rows × φ′ columns), shared colour scale."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.image

    vmax = max(float(obs.max()), float(exp.max()), 1.0)
    gap = np.full((obs.shape[0], 2), np.nan)
    img = np.concatenate([obs, gap, exp], axis=1) / vmax
    img = np.kron(img, np.ones((scale, scale)))
    buf = io.BytesIO()
    cmap = matplotlib.colormaps["viridis"].with_extremes(bad="white")
    matplotlib.image.imsave(buf, np.ma.masked_invalid(img), cmap=cmap, vmin=0, vmax=1, format="png")
    return buf.getvalue()


def _png_uri(data: bytes) -> str:
    import base64

    return "data:image/png;base64," + base64.b64encode(data).decode("ascii")


def _albedo_plot(bat: Battery, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = sorted({p.name for p in bat.albedo})
    fig, axes = plt.subplots(1, len(names), figsize=(5.2 * len(names), 3.8), dpi=100, squeeze=False)
    for ax, name in zip(axes[0], names, strict=True):
        pts = [p for p in bat.albedo if p.name == name]
        for a in sorted({p.alpha for p in pts}):
            row = sorted((p for p in pts if p.alpha == a), key=lambda p: p.theta)
            th = [p.theta for p in row]
            line, = ax.plot(th, [p.quadrature for p in row], "-", label=f"α = {a:g}")
            ax.errorbar(th, [p.monte_carlo for p in row], yerr=[2 * p.mc_stderr for p in row], fmt="o", ms=2.5,
                        color=line.get_color())
        ax.axhline(1.0, color="k", lw=0.6, ls="--")
        ax.set_title(f"directional albedo: {name}", fontsize=10)
        ax.set_xlabel("θ_i [degrees]")
        ax.set_ylabel("ρ(θ_i) = ∫ f cos θ_o dω_o")
        ax.set_ylim(0, 1.08)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, title="lines: quadrature, dots: MC ± 2σ", title_fontsize=7)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def _verdict(ok: bool) -> str:
    return '<span class="pass">pass</span>' if ok else '<span class="fail">FAIL</span>'


def write_validation_report(bat: Battery, out: Path, title: str = "brdflab validation") -> Path:
    """Write the report into ``out`` (``index.html`` plus ``albedo.png``); return the HTML path."""
    out.mkdir(parents=True, exist_ok=True)
    sections = []
    n_fail = len(bat.failures())
    summary = (f"{len(bat.chi2)} chi-square tests at family-wise significance 0.01 (Šidák: per-test threshold "
               f"{bat.threshold:.3g}); minimum p-value "
               f"{min((r.p_value for r in bat.chi2), default=float('nan')):.3g}. ")
    if bat.negative_control:
        summary += ("Negative control (conductor pdf without the 1/(4|ω_o·ω_h|) Jacobian): "
                    + ", ".join(f"p = {r.p_value:.2g}" for r in bat.negative_control)
                    + (" — rejected, so the test has power. " if all(not r.passed for r in bat.negative_control)
                       else " — NOT rejected: the harness is broken. "))
    summary += "Overall: " + ("everything passed." if n_fail == 0 else f"{n_fail} failures.")
    body = html.esc_p(summary)
    if n_fail:
        body += "<ul>" + "".join(f"<li class='fail'>{html.esc(f)}</li>" for f in bat.failures()) + "</ul>"
    sections.append(html.section("Summary", body))

    rows = []
    for r in bat.chi2 + bat.negative_control:
        neg = r in bat.negative_control
        img = f'<img src="{_png_uri(_histogram_png(r.observed, r.expected))}" alt="histograms" style="max-width:360px">'
        verdict = (_verdict(not r.passed) + " (must be rejected)") if neg else _verdict(r.passed)
        rows.append([html.esc(r.name + (" [negative control]" if neg else "")), html.esc(_fmt(r.params)),
                     f"{r.statistic:.1f}", r.dof, f"{r.p_value:.4g}", f"{r.integral:.4f}", verdict, img])
    sections.append(html.section(
        "Chi-square goodness of fit (observed | expected, rows θ′ from the lobe axis, columns φ′)",
        html.table(["sampler", "parameters", "X²", "dof", "p-value", "∫ p dω", "verdict", "histograms"], rows,
                   raw=True)))

    if bat.consistency:
        rows = [[html.esc(r.name), f"{r.theta:g}", f"{r.max_weight_error:.1e}", f"{r.pdf_integral:.5f}",
                 f"{r.valid_fraction:.5f}", f"{r.max_reciprocity_error:.1e}", r.negative_or_nonfinite,
                 _verdict(r.passed)] for r in bat.consistency]
        sections.append(html.section("Consistency: weight = eval·cos/pdf, ∫ pdf ≤ 1, reciprocity", html.table(
            ["BSDF", "θ_i", "max rel. weight error", "∫ p dω", "valid samples", "max reciprocity error",
             "negative/non-finite", "verdict"], rows, raw=True)))

    if bat.albedo:
        _albedo_plot(bat, out / "albedo.png")
        loss = []
        for name in sorted({p.name for p in bat.albedo}):
            pts = [p for p in bat.albedo if p.name == name and p.alpha == max(q.alpha for q in bat.albedo)]
            for th in (0.0, 60.0):
                p = next((q for q in pts if q.theta == th), None)
                if p:
                    loss.append(f"{name}, α = {p.alpha:g}, θ_i = {th:g}°: ρ = {p.quadrature:.3f} "
                                f"(energy lost by single scattering: {100 * (1 - p.quadrature):.1f} %)")
        body = html.image_row([(out / "albedo.png", "directional albedo by quadrature (lines) and Monte Carlo "
                                                      "(dots, ±2σ)")], cls="plot")
        body += "<ul>" + "".join(f"<li>{html.esc(x)}</li>" for x in loss) + "</ul>"
        body += html.esc_p(f"All {len(bat.albedo)} points: ρ ≤ 1 and quadrature = Monte Carlo within 4σ: "
                           + ("yes." if all(p.passed for p in bat.albedo) else "NO."))
        sections.append(html.section("White furnace and energy conservation", body))

    if bat.stability:
        bad = [r for r in bat.stability if not r.passed]
        rows = [[html.esc(r.material), html.esc(r.case), r.n, r.nan, r.inf, r.negative, _verdict(r.passed)]
                for r in bat.stability]
        body = html.esc_p(f"{len(bat.stability)} extreme cases, {len(bad)} with NaN, infinity or negative values.")
        body += "<ul>" + "".join(f"<li>{html.esc(n)}</li>" for n in NOTES) + "</ul>"
        body += "<details><summary>all cases</summary>" + html.table(
            ["material", "case", "values", "NaN", "inf", "negative", "verdict"], rows, raw=True) + "</details>"
        sections.append(html.section("Stiff and extreme cases", body))

    path = out / "index.html"
    path.write_text(html.page(title, "".join(sections)))
    return path
