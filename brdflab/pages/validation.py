"""HTML report of a validation battery: chi-square histograms and verdicts, albedo curves, stability.

Same look as the variance reports (template ``templates/validation.html.j2`` on the shared base layout);
written to ``<dir>/index.html`` with the figures embedded, so the file opens from the file system.
Chi-square tests are shown as thumbnails of their own bins (observed | expected | residual) and, for
failures, the negative controls and one representative per sampler, as detailed (φ′, cos θ′) views with
residual maps (:mod:`brdflab.pages.chi2_views`). A rejected negative control is shown as what must happen
("rejected, as it must be"), not as a pass.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from brdflab.judges.material import chi2 as c2
from brdflab.judges.material.battery import Battery, _fmt
from brdflab.judges.material.stability import NOTES
from brdflab.outputs import write_text
from brdflab.pages import chi2_views as cv

#: The files :func:`write_validation_report` may write into its folder (glob patterns; see
#: :func:`brdflab.outputs.prepare_folder`).
VALIDATION_FILES = ("index.html", "albedo.png", "chi2_view_*.png", "furnace.png", "furnace.csv")


def _png_uri(data: bytes) -> str:
    import base64

    return "data:image/png;base64," + base64.b64encode(data).decode("ascii")


def _albedo_plot(bat: Battery, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    from brdflab.viz.mpl import safe_figures

    safe_figures()  # user text is never mathtext; log axes still read 10⁻²
    import matplotlib.pyplot as plt

    names = sorted({p.name for p in bat.albedo})
    fig, axes = plt.subplots(1, len(names), figsize=(5.2 * len(names), 3.8), dpi=100, squeeze=False)
    for ax, name in zip(axes[0], names, strict=True):
        pts = [p for p in bat.albedo if p.name == name]
        for a in sorted({p.alpha for p in pts}, key=lambda a: -1.0 if a is None else a):
            row = sorted((p for p in pts if p.alpha == a), key=lambda p: p.theta)
            th = [p.theta for p in row]
            line, = ax.plot(th, [p.quadrature for p in row], "-", label="ρ" if a is None else f"α = {a:g}")
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


def _verdict(ok: bool) -> tuple[str, str]:
    return ("pass", "pass") if ok else ("fail", "FAIL")


#: At most this many tests get a detailed (φ′, cos θ′) view (failures first, then the negative controls,
#: then the passing test with the lowest p-value of each sampler).
MAX_DETAILS = 16


def select_details(bat: Battery) -> list[tuple[c2.Chi2Result, bool]]:
    """(result, is negative control) of the tests shown in detail (see :data:`MAX_DETAILS`)."""
    chosen: list[tuple[c2.Chi2Result, bool]] = [(r, False) for r in bat.chi2 if not r.passed]
    chosen += [(r, True) for r in bat.negative_control]
    if len(bat.chi2) <= 6:
        chosen += [(r, False) for r in bat.chi2 if r.passed]
    else:
        for name in dict.fromkeys(r.name for r in bat.chi2):
            ok = [r for r in bat.chi2 if r.name == name and r.passed]
            if ok:
                chosen.append((min(ok, key=lambda r: r.p_value), False))
    return chosen[:MAX_DETAILS]


def write_validation_report(bat: Battery, out: Path, title: str = "brdflab validation",
                            view_samples: int | None = None) -> Path:
    """Write the report into ``out`` (``index.html`` plus figures); return the HTML path.

    ``view_samples``: samples drawn for each detailed (φ′, cos θ′) view (:mod:`brdflab.pages.chi2_views`);
    by default as many as the test itself counted, between 20 000 and 200 000.
    """
    from brdflab.judges.core.failures import grouped_failures
    from brdflab.pages.jinja import render
    from brdflab.viz.figures import save

    out.mkdir(parents=True, exist_ok=True)
    failures = bat.failures()
    causes = grouped_failures(bat) if failures else []  # the terminal's lines, first on the page
    tests = f"{len(bat.chi2)} chi-square test{'' if len(bat.chi2) == 1 else 's'}"
    summary = (f"{tests} at family-wise significance 0.01 (Šidák: per-test threshold "
               f"{bat.threshold:.3g}); minimum p-value "
               f"{min((r.p_value for r in bat.chi2), default=float('nan')):.3g}.")
    negative = []
    for r in bat.negative_control:
        cls, text = cv.verdict(r, True)
        shown = "" if r.name == "roughconductor without Jacobian" else f"{r.name}, "  # the classic control: as before
        negative.append({"theta": f"{r.params.get('theta', float('nan')):g}°", "p": f"{r.p_value:.2g}", "cls": cls,
                         "text": text, "name": shown})

    details, anchors = [], {}
    for k, (r, neg) in enumerate(select_details(bat)):
        n_view = view_samples or int(np.clip(np.sum(r.observed) if r.observed is not None else 0, 20_000, 200_000))
        view = cv.view_of(r, n_view, seed=_seed_of(r, k))
        if view is None:
            continue
        anchor = f"view-{k}"
        anchors[id(r)] = anchor
        save(cv.figure(r, view, neg), out / f"chi2_view_{k}", dpi=80, formats=("png",))
        cls, text = cv.verdict(r, neg)
        details.append({"png": out / f"chi2_view_{k}.png", "anchor": anchor, "cls": cls, "text": text,
                        "title": f"{r.name} {_fmt(r.params)}: p = {r.p_value:.3g}, {view.shown:.1%} of "
                                 f"{n_view} fresh samples inside the plotted range"})

    rows = []
    for r in bat.chi2 + bat.negative_control:
        neg = r in bat.negative_control
        cls, text = cv.verdict(r, neg)
        rows.append({"name": r.name + (" [negative control]" if neg else ""), "params": _fmt(r.params),
                     "stat": f"{r.statistic:.1f}", "dof": r.dof, "p": f"{r.p_value:.4g}",
                     "integral": f"{r.integral:.4f}",
                     "cls": cls, "text": text, "detail": anchors.get(id(r)),
                     "thumb": _png_uri(cv.thumbnail_png(r)) if r.observed is not None else ""})

    consistency = [{"cells": [r.name, f"{r.theta:g}", f"{r.max_weight_error:.1e}", f"{r.pdf_integral:.5f}",
                              f"{r.valid_fraction:.5f}", f"{r.max_reciprocity_error:.1e}", r.negative_or_nonfinite],
                    **dict(zip(("cls", "text"), _verdict(r.passed), strict=True))} for r in bat.consistency]

    albedo = None
    if bat.albedo:
        _albedo_plot(bat, out / "albedo.png")
        loss = []
        for name in sorted({p.name for p in bat.albedo}):
            alphas = [q.alpha for q in bat.albedo if q.name == name and q.alpha is not None]
            pts = [p for p in bat.albedo if p.name == name and p.alpha == (max(alphas) if alphas else None)]
            for th in (0.0, 60.0):
                p = next((q for q in pts if q.theta == th), None)
                if p:
                    a_txt = "" if p.alpha is None else f"α = {p.alpha:g}, "
                    loss.append(f"{name}, {a_txt}θ_i = {th:g}°: ρ = {p.quadrature:.3f} "
                                f"(energy lost by single scattering: {100 * (1 - p.quadrature):.1f} %)")
        albedo = {"png": out / "albedo.png", "loss": loss,
                  "verdict": f"All {len(bat.albedo)} points: ρ ≤ 1 and quadrature = Monte Carlo within 4σ: "
                             + ("yes." if all(p.passed for p in bat.albedo) else "NO.")}

    stab = None
    white = _white_furnace(bat, out)
    if bat.stability:
        bad = [r for r in bat.stability if not r.passed]
        stab = {"summary": f"{len(bat.stability)} extreme cases, {len(bad)} with NaN, infinity or negative values.",
                "notes": NOTES,
                "rows": [{"cells": [r.material, r.case, r.n, r.nan, r.inf, r.negative],
                          **dict(zip(("cls", "text"), _verdict(r.passed), strict=True))} for r in bat.stability]}

    page = render("validation.html.j2", title=title, summary=summary, negative=negative,
                  negative_what="the conductor's pdf without the 1/(4|ω_o·ω_h|) Jacobian, which the test must reject"
                  + ("; broken glass (η inverted, Fresnel of the wrong cosine, the transmitted half vector without "
                     "its Jacobian), which the delta judge and the chi-square test must reject"
                     if len(bat.negative_control) > 2 else ""),
                  failures=failures, causes=causes, details=details, views_note=VIEWS_NOTE, rows=rows,
                  consistency=consistency, albedo=albedo, white=white, stability=stab, light=_light_transport(bat))
    path = out / "index.html"
    write_text(path, page)
    return path


def _white_furnace(bat: Battery, out: Path) -> dict | None:
    """The path-traced white furnace (:mod:`brdflab.viz.white_furnace`): figure, furnace.csv and table rows."""
    run = bat.white_furnace
    if run is None or not run.results:
        return None
    from brdflab.viz import white_furnace as wf
    from brdflab.viz.figures import save

    save(wf.furnace_figure([r for r in run.results if not r.error], run.predicted), out / "furnace",
         formats=("png",))
    write_text(out / "furnace.csv", wf.csv_text(run.results, run.predicted, "validate"))
    rows = []
    for r in run.rows():
        p, z = r["single_scattering_loss"], r["z"]
        rows.append({"cells": [r["material"], "—" if r["alpha"] is None else f"{r['alpha']:g}",
                               r["error"] or f"{100 * r['loss']:+.2f} % ± {200 * r['stderr']:.2f}",
                               "—" if p is None else f"{100 * p:+.2f} %", "—" if z is None else f"{z:+.1f}"],
                     "cls": "fail" if r["error"] else ""})
    return {"png": out / "furnace.png", "rows": rows, "seconds": f"{run.seconds:.0f}",
            "what": f"{len(run.results)} spheres, {run.size}² pixels, {run.results[0].spp} spp each "
                    f"({wf.RUNS} independent runs), path_mis with Russian roulette only"}


VIEWS_NOTE = (
    "Each figure: top, the test's own bins (θ′ at quantiles of a pilot sample, so every θ′ row holds about the "
    "same number of samples by construction) and the sampled directions; bottom, a fresh sample binned uniformly "
    "in (φ′, cos θ′) about the test axis (equal solid angle per bin), observed | expected on a shared colour bar, "
    "and the residual (O − E)/√E: where a sampler disagrees with its pdf, the residual map is red (sampled too "
    "often) or blue (too rarely) far beyond ±3. Shown: failures, the negative controls and the passing test with "
    "the lowest p-value of each sampler.")


def _seed_of(r: c2.Chi2Result, k: int) -> int:
    import zlib

    return zlib.crc32(repr(("view", r.name, sorted((str(a), repr(b)) for a, b in (r.params or {}).items()))).encode())


def _light_transport(bat: Battery) -> dict | None:
    """Table rows of the emitter checks and the estimator agreement, with their negative controls."""
    if not (bat.emitter_chi2 or bat.emitter_pdf or bat.agreement or bat.agreement_negative):
        return None

    def row(cells, ok, negative=False):
        if negative:  # ok = the check passed, i.e. the deliberately broken version was NOT rejected
            cls, text = ("fail", "NOT rejected: the check is blind") if ok else ("rejected", "rejected, as it must be")
        else:
            cls, text = _verdict(ok)
        return {"cells": cells, "cls": cls, "text": text}

    chi = [row([r.name, " ".join(f"{k}={v}" for k, v in r.params.items()), f"{r.statistic:.1f}", r.dof,
                f"{r.p_value:.4g}"], r.passed) for r in bat.emitter_chi2]
    pdf = [row([r.name, r.compared, f"{r.max_rel_error:.2g}"], r.passed) for r in bat.emitter_pdf]
    neg = [row([name, detail], not rejected, negative=True) for name, rejected, detail in bat.emitter_negative]
    agree = [row([r.name, r.tests, f"{r.p_value:.3g}", r.worst, ", ".join(f"{k} {v:.4g}" for k, v in r.means.items())],
                 r.passed, negative=r in bat.agreement_negative) for r in bat.agreement + bat.agreement_negative]
    return {"chi2": chi, "pdf": pdf, "negative": neg, "agreement": agree}
