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
                 times_cos: bool = False, decades: int = 4, deltas: list | None = None):
    """Plane of incidence: linear and log polar plots of f (or f·cos θ_o), ω_i and the mirror direction marked.

    The normal points up; θ_o > 0 (right) is the side opposite ω_i (see :mod:`brdflab.viz.coords`). When
    ``theta_o`` runs beyond ±90° (a transmitting BSDF) the whole circle is drawn, the transmitted half below the
    horizon line. ``deltas`` (per BSDF, a list of :class:`brdflab.viz.reflectance.DeltaLobe` or None): delta lobes
    drawn as spikes of length ∝ their energy (R or T), labelled with it.
    """
    plt = _plt()
    v = values * np.abs(np.cos(np.radians(theta_o))) if times_cos else values
    quantity = "f·|cos θ_o|" if times_cos else "f"
    full = float(np.max(np.abs(theta_o))) > 90.0
    deltas = deltas or [None] * len(labels)
    several = len(labels) > 1
    rows_legend = (len(labels) + 2) // 2
    height = (5.4 if full else 3.3) + 0.2 * rows_legend
    fig, axes = plt.subplots(1, 2, figsize=(10.5, height), subplot_kw={"projection": "polar"})
    t = np.radians(theta_o)
    fin = np.where(np.isfinite(v), v, 0.0)
    vmax = float(fin.max()) if fin.size and fin.max() > 0 else 1.0
    floor = vmax / 10.0**decades
    peaks = fin.max(axis=1) if fin.size else np.zeros(len(labels))
    cols = colours(len(labels))
    for ax, log in zip(axes, (False, True), strict=True):
        ax.set_theta_zero_location("N")
        ax.set_theta_direction(-1)
        ax.set_thetamin(-180 if full else -90)
        ax.set_thetamax(180 if full else 90)
        rmax = float(decades) if log else (1.08 if several or not peaks.any() else vmax * 1.08)
        for k, lab in enumerate(labels):
            name = f"{lab} (max {peaks[k]:.3g})" if several and peaks[k] > 0 else lab
            if deltas[k] is not None:  # f = 0: spikes at the delta directions instead of a curve
                _delta_spikes(ax, deltas[k], rmax, cols[k], line_style(k), name)
                continue
            if log:
                r = _log_radius(v[k], floor)
            else:  # several: each curve over its own maximum, so a sharp lobe does not hide the others
                r = v[k] / (peaks[k] if several and peaks[k] > 0 else 1.0)
            ax.plot(t, r, color=cols[k], lw=1.6, label=name, **line_style(k))
        ax.set_rlim(0, rmax)
        ax.plot([np.radians(theta_i)] * 2, [0, rmax], "k--", lw=0.9, label=f"mirror direction (+{theta_i:g}°)")
        if full:
            ax.plot([np.pi / 2, -np.pi / 2], [rmax, rmax], color="0.2", lw=0.6)
            ax.plot(np.radians([90.0, 90.0]), [0, rmax], color="0.2", lw=1.0)
            ax.plot(np.radians([-90.0, -90.0]), [0, rmax], color="0.2", lw=1.0)
            ax.text(np.radians(112), rmax * 0.9, "transmitted\n(below the surface)", ha="center", va="center",
                    fontsize=7, color="0.3")
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
        ax.text(0.0, rmax * (1.3 if full else 1.24), title, ha="center", va="bottom", fontsize=10)
        ax.set_thetagrids(range(-180 if full else -90, 180 if full else 91, 30), fontsize=8)
    handles, names = axes[0].get_legend_handles_labels()
    ncol = 2 if len(names) > 2 else len(names)
    fig.legend(handles, names, loc="lower center", fontsize=8, ncol=ncol, frameon=False, handlelength=3.0,
               bbox_to_anchor=(0.5, 0.0))
    legend_rows = (len(names) + ncol - 1) // ncol
    if full:
        fig.subplots_adjust(left=0.05, right=0.95, top=0.9, bottom=0.07 + 0.05 * legend_rows, wspace=0.25)
    else:
        fig.subplots_adjust(left=0.06, right=0.94, top=1.0, bottom=-0.12 + 0.065 * legend_rows, wspace=0.25)
    return fig


def _delta_spikes(ax, lobes: list, rmax: float, colour, style: dict, name: str) -> None:
    """Delta lobes as spikes (length ∝ energy, full length = 1) with an arrow head and their R/T value."""
    first = True
    for d in lobes:
        a = float(np.arctan2(-d.direction[0], d.direction[2]))  # the signed θ_o of the plane (φ_i = 0)
        r = rmax * min(max(d.energy, 0.0), 1.0)
        ax.plot([a, a], [0, r], color=colour, lw=2.2, ls=style["ls"], label=f"{name}: delta lobes" if first else None)
        ax.plot([a], [r], marker="o", color=colour, ms=4)
        side = 1.0 if (a % (2 * np.pi)) < np.pi else -1.0  # beside the spike, away from the axis labels
        ax.text(a + side * np.radians(9), max(r, 0.3 * rmax) * 0.8, f"{'T' if d.transmitted else 'R'} = "
                f"{d.energy:.3f}", fontsize=7.5, ha="center", va="center", color=colour,
                bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.8})
        first = False


def lobe_figure(lobe: Lobe, labels: list[str], theta_i: float, phi_i: float = 0.0, deltas: list | None = None):
    """3D lobe: the surface r(ω_o) = f·|cos θ_o| ω_o (the scattered-radiance lobe), ω_i and the normal drawn; on
    a grid of the whole sphere (a transmitting BSDF) the transmitted lobe hangs below the surface's rim.
    ``deltas`` (per BSDF, delta lobes or None): drawn as arrows of length ∝ their energy, labelled R/T.

    Several BSDFs are drawn side by side (small multiples, one shaded surface each, the same view), each scaled to
    its own maximum (given in its title): overlaid wireframes tangled into one another.
    """
    import matplotlib

    plt = _plt()
    k = len(labels)
    cols = min(k, 3)
    rows = (k + cols - 1) // cols
    fig = plt.figure(figsize=(6.4 if k == 1 else 3.7 * cols, (5.6 if k == 1 else 3.6 * rows) + 0.3))
    r_all = lobe.values * np.abs(np.cos(np.radians(lobe.theta_o_deg)))[None, :, None]
    peaks = np.nanmax(r_all.reshape(k, -1), axis=1)
    full = float(lobe.theta_o_deg[-1]) > 90.0
    deltas = deltas or [None] * k
    ti, pi = np.radians(theta_i), np.radians(phi_i)
    wi_dir = np.array([np.sin(ti) * np.cos(pi), np.sin(ti) * np.sin(pi), np.cos(ti)])
    for i, lab in enumerate(labels):
        ax = fig.add_subplot(rows, cols, i + 1, projection="3d")
        r = r_all[i] / (peaks[i] if peaks[i] > 0 else 1.0)
        xyz = lobe.directions * r[..., None]
        shade = matplotlib.colormaps["viridis"](np.clip(r, 0.0, 1.0))
        if deltas[i] is None:
            ax.plot_surface(xyz[..., 0], xyz[..., 1], xyz[..., 2], facecolors=shade, rstride=1, cstride=2,
                            linewidth=0.2, edgecolor=(0, 0, 0, 0.15), shade=False)
        else:
            for d in deltas[i]:
                tip = d.direction * min(max(d.energy, 0.0), 1.0)
                ax.plot([0, tip[0]], [0, tip[1]], [0, tip[2]], color="C3" if d.transmitted else "C0", lw=2.5)
                ax.text(*(tip * 1.1), f"{'T' if d.transmitted else 'R'} = {d.energy:.3f}", fontsize=7)
        if full:
            ring = np.linspace(0, 2 * np.pi, 73)
            ax.plot(np.cos(ring), np.sin(ring), np.zeros_like(ring), color="0.4", lw=0.8)  # the surface's rim
        ax.plot([0, wi_dir[0]], [0, wi_dir[1]], [0, wi_dir[2]], color="0.3", lw=1.5, ls="--")
        ax.text(*(wi_dir * 1.05), "ω_i", color="0.3")
        ax.plot([0, 0], [0, 0], [0, 1.0], color="k", lw=0.8)
        ax.text(0, 0, 1.05, "n", color="k")
        ax.set_xlim(-1, 1)
        ax.set_ylim(-1, 1)
        ax.set_zlim(-1 if full else 0, 1)
        ax.set_box_aspect((2, 2, 2 if full else 1))
        ax.view_init(elev=20, azim=-70)
        ax.tick_params(labelsize=6)
        if k == 1:
            ax.set_xlabel("x")
            ax.set_ylabel("y")
            ax.set_zlabel("z (normal)")
        what = "delta lobes" if deltas[i] is not None else f"max {peaks[i]:.3g}"
        ax.set_title(wrapped(f"{lab} ({what})", 34), fontsize=8 if k > 1 else 9)
    fig.suptitle(("3D lobes: radius f·|cos θ_o| / its maximum" if k > 1 else "3D lobe: radius f·|cos θ_o| / max")
                 + f", θ_i = {theta_i:g}°" + (f", φ_i = {phi_i:g}°" if phi_i else ""), fontsize=10)
    fig.tight_layout()
    return fig


def slice_figure(theta_h: np.ndarray, theta_d: np.ndarray, values: np.ndarray, labels: list[str],
                 phi_d: float = 90.0, decades: int = 7, notes: list | None = None):
    """θ_h × θ_d image slices at φ_d, log colour scale shared by all panels, with a colour bar; ``notes`` (per BSDF,
    a text or None) is written across its panel (e.g. why a delta BSDF's panel is black)."""
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
        if notes and notes[i]:
            ax.text(45, 45, wrapped(notes[i], 22), ha="center", va="center", fontsize=9, color="white")
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
    """Directional albedo ρ(θ_i): quadrature (lines) and Monte Carlo (dots, ±2σ); when some BSDF transmits,
    three panels: reflection R, transmission T (energy) and R + T."""
    plt = _plt()
    split = alb.any_transmission
    panels = [("R: reflected", alb.reflected, alb.mc_parts[:, :, 0]), ("T: transmitted", alb.transmitted,
              alb.mc_parts[:, :, 1])] if split else []
    panels.append(("R + T" if split else "", alb.quadrature, np.stack([alb.monte_carlo, alb.mc_stderr], axis=-1)))
    fig, axes = plt.subplots(1, len(panels), figsize=(6.4 if not split else 13.0, 4.2 if not split else 4.0),
                             squeeze=False, sharey=True)
    cols = colours(len(labels))
    top = max(1.05, float(np.nanmax(alb.quadrature)) * 1.05)
    for ax, (name, quad, mc) in zip(axes[0], panels, strict=True):
        for k, lab in enumerate(labels):
            st = line_style(k)
            ax.plot(alb.theta_deg, quad[k], color=cols[k], lw=1.5, label=f"{lab}", ls=st["ls"])
            ax.errorbar(alb.theta_deg, mc[k, :, 0], yerr=2 * mc[k, :, 1], fmt=MARKERS[1 + k % 5], ms=3,
                        color=cols[k], capsize=2, lw=0.8)
        ax.axhline(1.0, color="k", lw=0.6, ls="--")
        ax.set_ylim(0, top)
        ax.set_xlim(0, 90)
        ax.set_xlabel("θ_i [°]")
        ax.grid(alpha=0.3)
        if split:
            ax.set_title(name, fontsize=9)
    axes[0, 0].set_ylabel("ρ(θ_i) = ∫ f |cos θ_o| dω_o  (Y)" if split else "ρ(θ_i) = ∫ f cos θ_o dω_o  (Y)")
    head = (f"directional albedo: quadrature (lines), Monte Carlo ± 2σ (dots, {alb.samples} samples)"
            + ("; T counts energy: × (η_o/η_i)²" if split else ""))
    if split:
        fig.suptitle(head, fontsize=9)
        axes[0, -1].legend(fontsize=8)
    else:
        axes[0, 0].set_title(head, fontsize=9)
        axes[0, 0].legend(fontsize=8)
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
