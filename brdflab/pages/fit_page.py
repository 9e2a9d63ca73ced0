"""The page of ``brdflab fit`` (``bl.fit(..., output=DIR)``): the measurement and the fitted model compared in four
views — the θh × θd slice with the residual, the plane of incidence, the directional albedo and lit spheres — and
the parameters with their standard errors.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

#: Lit spheres of the fit page: small and quick (the page compares two materials, it is no beauty shot).
SPHERE_SIZE, SPHERE_SPP = 64, 4
#: Incident angles of the albedo comparison (a measured table's quadrature is slow: a few angles suffice).
ALBEDO_THETAS = (0.0, 20.0, 40.0, 60.0, 75.0, 85.0)

DEFINITIONS = ("relative error = Σ |f_model − f_measured| · cos θ_i cos θ_o / Σ f_measured · cos θ_i cos θ_o over the "
               "fitted nodes (both directions above the surface, unmeasured nodes left out, the three channels "
               "summed); rms = the root mean square of the loss's residuals. Standard errors come from the Jacobian J "
               "and residuals r at the optimum: (JᵀJ)⁻¹ (Σ_c g_c g_cᵀ) (JᵀJ)⁻¹ with g_c = Σ J r over the rows of "
               "measured node c (its channels and azimuths), a linear approximation robust to residuals of "
               "varying size; none is given for a parameter at a bound of its range, where that approximation "
               "does not hold. An anisotropic fit compares the data at four azimuths of the half vector (φ_h = "
               "0°, 30°, 60°, 90°); an isotropic table's value is then used at each.")


def _fmt(v) -> str:
    if v is None:
        return "—"
    if isinstance(v, np.ndarray | list | tuple):
        return ", ".join(f"{x:.4g}" for x in np.ravel(v))
    return f"{v:.4g}" if isinstance(v, float) else str(v)


def _slices(meas, model, result, out: Path, phi_d: float) -> Path:
    import matplotlib.pyplot as plt

    from brdflab.viz import views

    _, _, sv = views.half_diff_slice([meas, model], phi_d, n=90)
    with np.errstate(divide="ignore", invalid="ignore"):
        lg = np.log10(np.where(sv > 0, sv, np.nan))
    top = float(np.nanmax(lg)) if np.isfinite(lg).any() else 0.0
    ratio = np.where((lg[0] > top - 5) | (lg[1] > top - 5), lg[1] - lg[0], np.nan)  # where either carries light
    fig, axes = plt.subplots(1, 3, figsize=(16, 5.4), constrained_layout=True)
    for ax, img, name in ((axes[0], lg[0], "measured: log₁₀ f"), (axes[1], lg[1], f"{result.model} (fit): log₁₀ f")):
        im = ax.imshow(img, origin="lower", extent=(0, 90, 0, 90), vmin=top - 5, vmax=top, cmap="magma")
        ax.set_title(name, fontsize=12)
        ax.set_xlabel("θh [°]", fontsize=11)
        ax.set_ylabel("θd [°]", fontsize=11)
        ax.tick_params(labelsize=10)
        fig.colorbar(im, ax=ax, shrink=0.85)
    # colour range: the residual's 95th percentile, between 0.05 and 2 decades (beyond: saturated)
    lim = float(np.clip(np.nanpercentile(np.abs(ratio), 95), 0.05, 2.0)) if np.isfinite(ratio).any() else 1.0
    im = axes[2].imshow(ratio, origin="lower", extent=(0, 90, 0, 90), vmin=-lim, vmax=lim, cmap="RdBu_r")
    axes[2].set_title("residual: log₁₀(model / measured)\nwhere f > 10⁻⁵ max", fontsize=12)
    axes[2].set_xlabel("θh [°]", fontsize=11)
    axes[2].tick_params(labelsize=10)
    fig.colorbar(im, ax=axes[2], shrink=0.85)
    fig.suptitle(f"θh × θd at φd = {phi_d:g}° (white: ω_i or ω_o below the surface there, where f is not defined)",
                 fontsize=11)
    png = out / "fit_slices.png"
    fig.savefig(png, dpi=100)
    plt.close(fig)
    return png


def _albedo(meas, model, labels: list[str], png: Path, n: int = 20_000) -> None:
    """ρ(θ_i) of both by Monte Carlo of their own samplers (± 2σ). Not by quadrature: adaptive quadrature of a
    noisy measured table chases its noise (100 s for six angles of a table with 5 % noise)."""
    import matplotlib.pyplot as plt

    from brdflab.judges.material.furnace import albedo_monte_carlo
    from brdflab.viz.figures import colours, line_style

    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for k, (b, lab) in enumerate(zip((meas, model), labels, strict=True)):
        est = np.array([albedo_monte_carlo(b, t, n, seed=100 + i) for i, t in enumerate(ALBEDO_THETAS)])
        st = line_style(k)
        ax.errorbar(ALBEDO_THETAS, est[:, 0], yerr=2 * est[:, 1], color=colours(2)[k], ls=st["ls"], marker="os"[k],
                    ms=4, capsize=2, label=lab)
    ax.axhline(1.0, color="k", lw=0.6, ls="--")
    ax.set_xlim(0, 90)
    ax.set_ylim(0, 1.05)
    ax.set_xlabel("θ_i [°]")
    ax.set_ylabel("ρ(θ_i) (Y)")
    ax.set_title(f"directional albedo, Monte Carlo ± 2σ ({n} samples per angle)", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(png, dpi=100)
    plt.close(fig)


def _correlations(result) -> str:
    """The table of the fitted values' strongest correlations (|ρ| > 0.5), or nothing."""
    from brdflab.fitting_data import strong_pairs
    from brdflab.pages import page as html

    corr = result.correlation or {}
    if not corr.get("labels"):
        return ""
    pairs = strong_pairs(corr["labels"], np.asarray(corr["matrix"]), 0.5)
    if not pairs:
        return html.esc_p("No two fitted values are correlated beyond |ρ| = 0.5.")
    return (html.esc_p("Correlations of the fitted values (|ρ| > 0.5; same covariance as the standard errors; a "
                       "strong one means the data fix a combination of the two better than either, as η and k "
                       "of a conductor):")
            + html.table(["value", "value", "ρ"], [[a, b, f"{r:+.3f}"] for a, b, r in pairs]))


def write_fit_page(out: Path, measured_table, result, title: str = "brdflab fit",
                   phi_d: float = 90.0, theta: float = 45.0, workers: int | None = 1) -> Path:
    """``fit.html``, ``fit.json`` and the four comparisons of the measurement (a table, or data given as a
    BSDF) and the fit into ``out``."""
    from brdflab.bsdf.measured import Measured
    from brdflab.outputs import json_text, write_text
    from brdflab.pages import page as html
    from brdflab.plugins import make_bsdf
    from brdflab.viz import figures, sphere, views
    from brdflab.viz.mpl import safe_figures

    safe_figures()
    out.mkdir(parents=True, exist_ok=True)
    meas = Measured(table=measured_table) if isinstance(measured_table, np.ndarray) else measured_table
    model = make_bsdf(result.model, result.params)
    labels = ["measured" if meas is not measured_table else "data", f"{result.model} (fit)"]
    slices = _slices(meas, model, result, out, phi_d)
    t, v = views.polar([meas, model], theta, 0.0, n=361)
    figures.save(figures.polar_figure(t, v, labels, theta), out / "fit_polar", formats=("png",))
    _albedo(meas, model, labels, out / "fit_albedo.png")
    imgs = sphere.render_spheres([meas, model], SPHERE_SIZE, SPHERE_SPP, 0, workers)
    figures.save(figures.sphere_figure(imgs, labels, sphere.silhouette_radius(SPHERE_SIZE)), out / "fit_sphere",
                 formats=("png",))
    write_text(out / "fit.json", json_text(result.to_dict(), indent=2))
    unc = result.uncertainty or {}
    rows = [[k, _fmt(v), _fmt(unc.get(k)) if k in unc else "held fixed"] for k, v in result.params.items()]
    notes = "".join(html.esc_p(f"Note: {n}") for n in result.notes)
    body = (html.section("Fitted parameters", html.table(["parameter", "value", "standard error"], rows)
                         + html.esc_p(result.summary(notes=False)) + notes + _correlations(result)
                         + html.esc_p(DEFINITIONS))
            + html.section("Measured and fit: four views",
                           f'<figure class="wide"><img class="fig" src="{html.data_uri(slices)}" alt="slices">'
                           f"<figcaption>{html.esc('θh × θd slices and the residual (log₁₀ model / measured)')}"
                           "</figcaption></figure>"
                + html.image_row([(out / "fit_polar.png", f"plane of incidence at θ_i = {theta:g}°"),
                                  (out / "fit_albedo.png", "directional albedo")], cls="plot")
                + html.image_row([(out / "fit_sphere.png", "lit spheres: a point light and a sky")], cls="plot")))
    path = out / "fit.html"
    write_text(path, html.page(title, body))
    return path
