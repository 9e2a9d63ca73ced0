"""HTML report of ``brdflab chi2 --samples FILE --against NAME`` (a file of another renderer's samples).

The same page as the other chi-square reports (template ``validation.html.j2``): the verdict and the hints
of every ω_i group at the top, a table with one row per group (thumbnail of the test bins: observed |
expected | residual), and for every group a figure with both tests in their own bins:

* top, the **self-consistency** test (:mod:`brdflab.judges.samples.selfconsistency`): observed = Σ_k r(ω_k)/p_k
  per bin (the file's directions weighted by brdflab's density over the file's pdf column), expected =
  N ∫_bin r dω, and the residual (O − E)/√E; this decides the verdict when the file has a pdf column;
* bottom, the chi-square test against **brdflab's own sampler** (plain counts against N ∫_bin p dω): it
  tells whether the file uses brdflab's sampling *method*; a correct sampler of another method fails it
  and still passes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from brdflab.judges.material import chi2 as c2


def _panel(fig, axes, obs: np.ndarray, exp: np.ndarray, theta_edges: np.ndarray, label: str) -> None:
    import matplotlib
    from matplotlib.colors import TwoSlopeNorm

    from brdflab.pages.chi2_views import bin_maps

    n_t = obs.shape[0]
    bin_maps(fig, axes, obs, exp, theta_edges, (f"{label}: observed", f"{label}: expected"))
    with np.errstate(divide="ignore", invalid="ignore"):
        res = np.where(exp > 0, (obs - exp) / np.sqrt(np.where(exp > 0, exp, 1.0)), np.nan)
    finite = np.abs(res[np.isfinite(res)])
    lim = max(3.0, min(float(np.percentile(finite, 99.5)) if finite.size else 3.0, 50.0))
    cmap = matplotlib.colormaps["RdBu_r"].with_extremes(bad="0.85")
    im = axes[2].imshow(np.ma.masked_invalid(res), origin="lower", aspect="auto", extent=(0, 360, 0, n_t), cmap=cmap,
                        norm=TwoSlopeNorm(0.0, -lim, lim), interpolation="nearest")
    axes[2].set_xticks([])
    axes[2].set_yticks([])
    axes[2].set_title(f"{label}: residual (O − E)/√E", fontsize=9)
    fig.colorbar(im, ax=axes[2], fraction=0.05, pad=0.02).ax.tick_params(labelsize=7)


def group_figure(res, g, title: str):
    """Both tests of one ω_i group in their own bins (module docstring)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = [(g.sc.observed, g.sc.expected, g.sc.theta_edges, "self-consistency (Σ r/p vs N∫r)")] \
        if g.sc is not None and g.sc.observed is not None else []
    if g.chi2 is not None and g.chi2.observed is not None:
        rows.append((g.chi2.observed, g.chi2.expected, g.chi2.theta_edges, f"vs brdflab's {res.against} sampler"))
    fig, axes = plt.subplots(max(len(rows), 1), 3, figsize=(14, 3.7 * max(len(rows), 1)), squeeze=False)
    fig.subplots_adjust(left=0.06, right=0.97, top=0.86, bottom=0.08, wspace=0.32, hspace=0.45)
    for ax_row, (obs, exp, te, label) in zip(axes, rows, strict=False):
        _panel(fig, ax_row, obs, exp, te, label)
    fig.suptitle(title, fontsize=10, color="#1a7f37" if g.passed else "#cf222e", fontweight="bold")
    return fig


def _thumb(g) -> str:
    from brdflab.pages import chi2_views as cv
    from brdflab.pages.validation import _png_uri

    src = g.sc if g.sc is not None and g.sc.observed is not None else g.chi2
    if src is None or src.observed is None:
        return ""
    fake = c2.Chi2Result("", {}, 0.0, 0, 0.0, observed=src.observed, expected=src.expected)
    return _png_uri(cv.thumbnail_png(fake))


def write_samples_report(res, out: Path) -> Path:
    """Write the report of an :class:`~brdflab.judges.samples.bsdf_checks.ExternalResult` into ``out``; return the HTML.

    Examples
    --------
    >>> import numpy as np, tempfile, pathlib
    >>> from brdflab.math import warps
    >>> from brdflab.judges.samples.bsdf_checks import check_samples
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> wo = warps.square_to_cosine_hemisphere(np.random.default_rng(5).random((5_000, 2)))
    >>> np.save(d / "cos.npy", np.column_stack([wo, wo[:, 2] / np.pi]))
    >>> write_samples_report(check_samples(d / "cos.npy", "cosine_hemisphere"), d / "r").name
    'index.html'
    """
    from brdflab.pages.jinja import render
    from brdflab.viz.figures import save

    out.mkdir(parents=True, exist_ok=True)
    lines = res.messages()
    notes = list(res.notes)
    failures = ["; ".join(x.strip() for x in res.nonfinite_lines())] if res.nonfinite else []
    failures += ["; ".join(x.strip() for x in res._group_lines(g)) for g in res.groups if not g.passed]
    failures += [x.strip() for x in lines if x.strip().startswith("WARNING")]
    summary = (f"{res.path}: {sum(g.n for g in res.groups)} samples in {len(res.groups)} ω_i group(s) against "
               f"{res.against} (per-group threshold {res.threshold:.3g}, Šidák over the groups). "
               + " ".join(notes) + " The verdict: the directions follow the pdf written beside them "
               "(self-consistency, whatever the sampling method) and the weights equal f·cos θo / pdf; the "
               "comparison with brdflab's own sampler only says whether the method is the same.")
    details, rows = [], []
    for k, g in enumerate(res.groups):
        glines = res._group_lines(g)
        verdict_line = glines[0]
        hint = next((x.strip() for x in glines[1:]), "")
        title = verdict_line if len(verdict_line) < 150 else verdict_line[:147] + "..."
        cls, text = ("pass", "pass") if g.passed else ("fail", "FAIL")
        anchor = f"group-{k}"
        try:
            save(group_figure(res, g, title + ("\n" + hint[:160] if hint else "")), out / f"samples_group_{k}",
                 dpi=80, formats=("png",))
            details.append({"png": out / f"samples_group_{k}.png", "anchor": anchor, "cls": cls, "text": text,
                            "title": "; ".join(x.strip() for x in glines)})
        except Exception:  # noqa: BLE001 - a group without bins (too few samples) gets no figure
            anchor = None
        sc = g.sc
        rows.append({"name": f"wi = ({', '.join(f'{x:.4g}' for x in g.wi)})",
                     "params": f"{g.n} samples from line {g.first_line}",
                     "stat": f"{sc.statistic:.1f}" if sc is not None else
                     (f"{g.chi2.statistic:.1f}" if g.chi2 is not None else ""),
                     "dof": sc.dof if sc is not None else (g.chi2.dof if g.chi2 is not None else ""),
                     "p": f"{sc.p_value:.4g}" if sc is not None else
                     (f"{g.chi2.p_value:.4g}" if g.chi2 is not None else ""),
                     "integral": f"{g.chi2.integral:.4f}" if g.chi2 is not None else "",
                     "cls": cls, "text": text, "detail": anchor, "thumb": _thumb(g)})
    page = render("validation.html.j2", title=f"brdflab chi-square: {Path(res.path).name} against {res.against}",
                  summary=summary, negative=[], negative_what="", failures=failures, causes=failures, details=details,
                  views_note=__doc__.split("\n\n", 1)[1].replace("\n", " "), rows=rows, consistency=[], albedo=None,
                  white=None, stability=None, light=None)
    path = out / "index.html"
    path.write_text(page)
    return path
