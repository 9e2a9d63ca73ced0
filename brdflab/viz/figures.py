"""matplotlib figures of the BRDF views (:mod:`brdflab.viz.views`), one colour per BSDF.

Every function returns a :class:`matplotlib.figure.Figure`; :func:`save` writes it as PNG and SVG.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from brdflab.viz.views import Albedo, Lobe


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    from brdflab.viz.mpl import safe_figures

    safe_figures()  # user text is never mathtext; log axes still read 10⁻²
    import matplotlib.pyplot as plt

    return plt


def colours(k: int) -> list:
    """The colour of each of ``k`` BSDFs (matplotlib's tab10 cycle)."""
    import matplotlib

    cmap = matplotlib.colormaps["tab10"]
    return [cmap(i % 10) for i in range(k)]


#: Line styles and markers per BSDF, so that overlays stay legible in grey print.
STYLES = ["-", "--", ":", "-."]
MARKERS = ["", "o", "s", "^", "v", "D"]


def line_style(k: int) -> dict:
    """matplotlib keywords of the ``k``-th curve: its colour, a dash pattern and (after four) a sparse marker."""
    return {"ls": STYLES[k % len(STYLES)], "marker": MARKERS[(k // len(STYLES)) % len(MARKERS)] or None,
            "markevery": 24, "ms": 4}


def wrapped(text: str, width: int = 24) -> str:
    """``text`` broken into lines of at most ``width`` characters (titles that must not overprint)."""
    import textwrap

    return "\n".join(textwrap.wrap(str(text), width)) or str(text)


def save(fig, base: Path, dpi: int = 100, formats: tuple[str, ...] = ("png", "svg")) -> list[Path]:
    """Write ``base``.png and ``base``.svg (or the given ``formats``) and close the figure; return the paths."""
    paths = []
    for ext in formats:
        p = base.with_suffix("." + ext)
        fig.savefig(p, dpi=dpi, metadata={"Date": None} if ext == "svg" else None)
        paths.append(p)
    _plt().close(fig)
    return paths


def _log_radius(v: np.ndarray, floor: float) -> np.ndarray:
    with np.errstate(divide="ignore"):
        return np.clip(np.log10(np.maximum(v, 1e-300)) - np.log10(floor), 0.0, None)


def polar_figure(theta_o: np.ndarray, values: np.ndarray, labels: list[str], theta_i: float,
                 times_cos: bool = False, decades: int = 4):
    """Plane of incidence: linear and log polar plots of f (or f·cos θ_o), ω_i and the mirror direction marked.

    The normal points up; θ_o > 0 (right) is the side opposite ω_i (see :mod:`brdflab.viz.coords`).
    """
    plt = _plt()
    v = values * np.cos(np.radians(theta_o)) if times_cos else values
    quantity = "f·cos θ_o" if times_cos else "f"
    several = len(labels) > 1
    rows_legend = (len(labels) + 2) // 2
    fig, axes = plt.subplots(1, 2, figsize=(10.5, 3.3 + 0.2 * rows_legend), subplot_kw={"projection": "polar"})
    t = np.radians(theta_o)
    vmax = float(np.nanmax(v)) if np.isfinite(np.nanmax(v)) and np.nanmax(v) > 0 else 1.0
    floor = vmax / 10.0**decades
    peaks = np.nanmax(v, axis=1)
    cols = colours(len(labels))
    for ax, log in zip(axes, (False, True), strict=True):
        ax.set_theta_zero_location("N")
        ax.set_theta_direction(-1)
        ax.set_thetamin(-90)
        ax.set_thetamax(90)
        for k, lab in enumerate(labels):
            if log:
                r = _log_radius(v[k], floor)
            else:  # several: each curve over its own maximum, so a sharp lobe does not hide the others
                r = v[k] / (peaks[k] if several and peaks[k] > 0 else 1.0)
            name = f"{lab} (max {peaks[k]:.3g})" if several else lab
            ax.plot(t, r, color=cols[k], lw=1.6, label=name, **line_style(k))
        rmax = float(decades) if log else (1.08 if several else vmax * 1.08)
        ax.set_rlim(0, rmax)
        ax.plot([np.radians(theta_i)] * 2, [0, rmax], "k--", lw=0.9, label=f"mirror direction (+{theta_i:g}°)")
        ax.annotate("", xy=(0, 0), xytext=(np.radians(-theta_i), rmax * 0.95),
                    arrowprops={"arrowstyle": "->", "color": "0.35", "lw": 1.2})
        ax.text(np.radians(-theta_i - 4), rmax * 0.8, "ω_i", ha="center", va="center", fontsize=9, color="0.35")
        if log:
            ticks = np.arange(0, decades + 1)
            ax.set_rticks(ticks[1:])
            ax.set_yticklabels([f"{floor * 10.0**d:.0e}" for d in ticks[1:]])
            ax.tick_params(axis="y", labelsize=6.5)
            title = f"{quantity}, log scale ({decades} decades), θ_i = {theta_i:g}°"
        else:
            title = f"{quantity} / its maximum" if several else quantity
            title += f", linear, θ_i = {theta_i:g}°"
            ax.tick_params(axis="y", labelsize=7)
        ax.text(0.0, rmax * 1.24, title, ha="center", va="bottom", fontsize=10)
        ax.set_thetagrids(range(-90, 91, 30), fontsize=8)
    handles, names = axes[0].get_legend_handles_labels()
    ncol = 2 if len(names) > 2 else len(names)
    fig.legend(handles, names, loc="lower center", fontsize=8, ncol=ncol, frameon=False, handlelength=3.0,
               bbox_to_anchor=(0.5, 0.0))
    legend_rows = (len(names) + ncol - 1) // ncol
    fig.subplots_adjust(left=0.06, right=0.94, top=1.0, bottom=-0.12 + 0.065 * legend_rows, wspace=0.25)
    return fig


def lobe_figure(lobe: Lobe, labels: list[str], theta_i: float, phi_i: float = 0.0):
    """3D lobe: the surface r(ω_o) = f·cos θ_o ω_o (the reflected-radiance lobe), ω_i and the normal drawn.

    Several BSDFs are drawn side by side (small multiples, one shaded surface each, the same view), each scaled to
    its own maximum (given in its title): overlaid wireframes tangled into one another.
    """
    import matplotlib

    plt = _plt()
    k = len(labels)
    cols = min(k, 3)
    rows = (k + cols - 1) // cols
    fig = plt.figure(figsize=(6.4 if k == 1 else 3.7 * cols, (5.6 if k == 1 else 3.6 * rows) + 0.3))
    r_all = lobe.values * np.cos(np.radians(lobe.theta_o_deg))[None, :, None]
    peaks = np.nanmax(r_all.reshape(k, -1), axis=1)
    ti, pi = np.radians(theta_i), np.radians(phi_i)
    wi_dir = np.array([np.sin(ti) * np.cos(pi), np.sin(ti) * np.sin(pi), np.cos(ti)])
    for i, lab in enumerate(labels):
        ax = fig.add_subplot(rows, cols, i + 1, projection="3d")
        r = r_all[i] / (peaks[i] if peaks[i] > 0 else 1.0)
        xyz = lobe.directions * r[..., None]
        shade = matplotlib.colormaps["viridis"](np.clip(r, 0.0, 1.0))
        ax.plot_surface(xyz[..., 0], xyz[..., 1], xyz[..., 2], facecolors=shade, rstride=1, cstride=2,
                        linewidth=0.2, edgecolor=(0, 0, 0, 0.15), shade=False)
        ax.plot([0, wi_dir[0]], [0, wi_dir[1]], [0, wi_dir[2]], color="0.3", lw=1.5, ls="--")
        ax.text(*(wi_dir * 1.05), "ω_i", color="0.3")
        ax.plot([0, 0], [0, 0], [0, 1.0], color="k", lw=0.8)
        ax.text(0, 0, 1.05, "n", color="k")
        ax.set_xlim(-1, 1)
        ax.set_ylim(-1, 1)
        ax.set_zlim(0, 1)
        ax.set_box_aspect((2, 2, 1))
        ax.view_init(elev=20, azim=-70)
        ax.tick_params(labelsize=6)
        if k == 1:
            ax.set_xlabel("x")
            ax.set_ylabel("y")
            ax.set_zlabel("z (normal)")
        ax.set_title(wrapped(f"{lab} (max {peaks[i]:.3g})", 34), fontsize=8 if k > 1 else 9)
    fig.suptitle(("3D lobes: radius f·cos θ_o / its maximum" if k > 1 else "3D lobe: radius f·cos θ_o / max")
                 + f", θ_i = {theta_i:g}°" + (f", φ_i = {phi_i:g}°" if phi_i else ""), fontsize=10)
    fig.tight_layout()
    return fig


def slice_figure(theta_h: np.ndarray, theta_d: np.ndarray, values: np.ndarray, labels: list[str],
                 phi_d: float = 90.0, decades: int = 7):
    """θ_h × θ_d image slices at φ_d, log colour scale shared by all panels, with a colour bar."""
    import matplotlib
    from matplotlib.colors import LogNorm

    plt = _plt()
    k = len(labels)
    cols = min(k, 3)
    rows = (k + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(3.6 * cols + 1.0, 3.5 * rows + 0.5), squeeze=False)
    pos = values[np.isfinite(values) & (values > 0)]
    vmax = float(pos.max()) if pos.size else 1.0
    vmin = max(float(pos.min()) if pos.size else vmax * 1e-5, vmax / 10.0**decades)
    cmap = matplotlib.colormaps["magma"].with_extremes(bad="0.8", under="black")
    im = None
    for i, ax in enumerate(axes.ravel()):
        if i >= k:
            ax.set_axis_off()
            continue
        v = np.ma.masked_invalid(np.where(values[i] > 0, values[i], vmin * 0.5))
        im = ax.imshow(v, origin="lower", extent=(theta_h[0], theta_h[-1], theta_d[0], theta_d[-1]), cmap=cmap,
                       norm=LogNorm(vmin, vmax), aspect="equal", interpolation="nearest")
        ax.set_title(labels[i], fontsize=9)
        ax.set_xlabel("θ_h [°]")
        ax.set_ylabel("θ_d [°]")
        ax.set_xticks(range(0, 91, 15))
        ax.set_yticks(range(0, 91, 15))
        ax.tick_params(labelsize=7)
    cbar = fig.colorbar(im, ax=axes.ravel().tolist(), fraction=0.046, pad=0.03)
    cbar.set_label("f (Y), log scale; grey: outside the hemisphere", fontsize=8)
    fig.suptitle(f"half/difference slice at φ_d = {phi_d:g}° (φ_h = 0)", fontsize=10)
    return fig


def albedo_figure(alb: Albedo, labels: list[str]):
    """Directional albedo ρ(θ_i): quadrature (lines) and Monte Carlo (dots, ±2σ)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    cols = colours(len(labels))
    for k, lab in enumerate(labels):
        st = line_style(k)
        ax.plot(alb.theta_deg, alb.quadrature[k], color=cols[k], lw=1.5, label=f"{lab}", ls=st["ls"])
        ax.errorbar(alb.theta_deg, alb.monte_carlo[k], yerr=2 * alb.mc_stderr[k], fmt=MARKERS[1 + k % 5], ms=3,
                    color=cols[k], capsize=2, lw=0.8)
    ax.axhline(1.0, color="k", lw=0.6, ls="--")
    top = max(1.05, float(np.nanmax(alb.quadrature)) * 1.05)
    ax.set_ylim(0, top)
    ax.set_xlim(0, 90)
    ax.set_xlabel("θ_i [°]")
    ax.set_ylabel("ρ(θ_i) = ∫ f cos θ_o dω_o  (Y)")
    ax.set_title(f"directional albedo: quadrature (lines), Monte Carlo ± 2σ (dots, {alb.samples} samples)",
                 fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def sphere_figure(images: dict[str, list[np.ndarray]], labels: list[str], outline: float | None = None):
    """A grid of lit-sphere renders: one row per light (key of ``images``), one column per BSDF.

    ``outline``: the sphere's radius in pixels, drawn as a faint circle (the silhouette on black).
    """
    from matplotlib.patches import Circle

    from brdflab.imageio import srgb_bytes

    plt = _plt()
    rows, cols = len(images), len(labels)
    fig, axes = plt.subplots(rows, cols, figsize=(2.3 * cols + 0.9, 2.35 * rows + 0.2), squeeze=False)
    for r, (light, imgs) in enumerate(images.items()):
        for c, img in enumerate(imgs):
            ax = axes[r, c]
            ax.imshow(srgb_bytes(img), interpolation="nearest")
            if outline:
                h, w = img.shape[:2]
                ax.add_patch(Circle(((w - 1) / 2, (h - 1) / 2), outline, fill=False, ec=(1, 1, 1, 0.25), lw=0.6,
                                    ls="--"))
            ax.set_xticks([])
            ax.set_yticks([])
            if r == 0:
                ax.set_title(wrapped(labels[c], 26), fontsize=8)
            if c == 0:
                ax.set_ylabel(light, fontsize=9)
    fig.tight_layout()
    return fig
