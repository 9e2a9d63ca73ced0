"""Views of chi-square tests a person can read: (φ, cos θ) histograms, residual maps, warped points.

The test itself bins directions in θ′ at quantiles of a pilot sample (:mod:`brdflab.judges.material.chi2`), so
its *observed* histogram is nearly flat by construction and a fault shows only in the *expected* one.
For display, :func:`direction_view` draws a fresh sample from the same sampler (its own random stream)
and bins it **uniformly in (φ′, cos θ′)** about the test's axis — equal solid angle per bin, as Nori's
warptest does — with the expected counts N ∫_bin p dω from the same adaptive quadrature as the test
(dω = d cos θ′ dφ′). The cos θ′ range is zoomed to [μ_lo, 1] where μ_lo holds all but 0.2 % of the
samples (so α = 10⁻³ lobes are still resolved); the residual map (O − E)/√E on a diverging colour scale
shows *where* a sampler and its pdf disagree.

The sampler is rebuilt from the result's name and parameters (:func:`sampler_of`) through the same
tables the battery uses; results it cannot rebuild simply get no detailed view.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from brdflab.judges.core.guard import checked
from brdflab.judges.material import chi2 as c2

#: Fraction of the samples allowed outside the zoomed cos θ′ range.
ZOOM_TAIL = 0.002


@dataclass
class Sampler:
    """A rebuilt sampler: ``sample(u (N, 3)) → (w (N, 3), pdf (N,))``, its claimed ``pdf`` and binning ``axis``."""

    sample: Callable
    pdf: Callable
    axis: np.ndarray | None
    """None for warps to 2-D points (binned on the test's own (x, y) grid)."""


@dataclass
class View:
    """Observed and expected counts on a regular grid, and a subset of the sample points."""

    x_edges: np.ndarray
    y_edges: np.ndarray
    observed: np.ndarray
    """(ny, nx) counts."""
    expected: np.ndarray
    """(ny, nx) N ∫_bin p."""
    points: np.ndarray
    """(M, 2) sample points in the same coordinates."""
    x_label: str
    y_label: str
    shown: float
    """Fraction of the valid samples inside the grid."""

    @property
    def residual(self) -> np.ndarray:
        """(O − E)/√E per bin (NaN where E is essentially 0 and nothing was observed)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            r = (self.observed - self.expected) / np.sqrt(self.expected)
        r = np.where((self.expected < 1e-9) & (self.observed == 0), np.nan, r)
        return np.where(np.isfinite(r) | np.isnan(r), r, np.sign(self.observed) * 1e3)


def sampler_of(result: c2.Chi2Result) -> Sampler | None:
    """Rebuild the sampler of a battery result from its name and parameters, or None."""
    from brdflab.judges.material import battery as bt

    name, params = result.name, dict(result.params or {})
    try:
        if name in bt.POINT_WARPS:
            w, p, _ = bt.POINT_WARPS[name]
            return Sampler(lambda u, w=w: (w(u[:, :2]), np.ones(len(u))), p, None)
        if name in bt.WARPS:
            w, p, takes_alpha = bt.WARPS[name]
            a = params.get("alpha")
            if takes_alpha:
                w, p = (lambda u, a=a, w=w: w(u, a)), (lambda d, a=a, p=p: p(d, a))
            return Sampler(lambda u, w=w, p=p: (lambda d: (d, p(d)))(w(u[:, :2])), p, np.array([0.0, 0.0, 1.0]))
        theta = params.pop("theta", None)
        phi = float(params.pop("phi", 0.0) or 0.0)
        alpha = params.pop("alpha", None)
        if theta is None:
            return None
        if name == "roughconductor without Jacobian":
            bsdf = bt.NoJacobianConductor(0.5, alpha if alpha is not None else 0.3)
        else:
            bsdf = bt.make_named_bsdf(name, alpha, params)
        # Through the contract checks: a plugin that broke its contract in the test breaks it here again,
        # as a PluginFault that view_of turns into "no detailed view", never a crash of the report.
        bsdf = checked(bsdf)
    except (Exception, SystemExit):  # noqa: BLE001 - a result we cannot rebuild just gets no detailed view
        return None
    wi1 = c2.incident(theta, phi)
    axis = np.array([0.0, 0.0, 1.0]) if name in ("diffuse", "roughsubstrate/diffuse") else \
        np.array([-wi1[0], -wi1[1], wi1[2]])

    def sample(u):
        r = bsdf.sample(np.ascontiguousarray(np.broadcast_to(wi1, (len(u), 3))), u)
        return r.wo, r.pdf

    def pdf(w):
        return bsdf.pdf(np.ascontiguousarray(np.broadcast_to(wi1, (len(w), 3))), w)

    return Sampler(sample, pdf, axis)


def direction_view(s: Sampler, n: int, seed: int, n_mu: int = 20, n_phi: int = 40, n_points: int = 3000) -> View:
    """Histogram ``n`` fresh samples uniformly in (φ′, cos θ′) about ``s.axis`` (module docstring)."""
    rng = np.random.default_rng(seed)
    w, p = s.sample(rng.random((n, 3)))
    ok = p > 0
    theta, phi = c2.to_angles(w[ok], s.axis)
    mu = np.cos(theta)
    q = float(np.quantile(mu, ZOOM_TAIL)) if mu.size else -1.0
    mu_lo = max(-1.0, 1.0 - 1.15 * (1.0 - q))
    mu_lo = min(mu_lo, 1.0 - 1e-9)
    mu_edges = np.linspace(mu_lo, 1.0, n_mu + 1)
    phi_edges = np.linspace(0.0, 2 * np.pi, n_phi + 1)
    obs, _, _ = np.histogram2d(mu, phi, bins=[mu_edges, phi_edges])

    def density(m, f):
        return s.pdf(c2.from_angles(np.arccos(np.clip(m, -1.0, 1.0)), f, s.axis))

    exp = c2.adaptive_integrate(density, mu_edges, phi_edges, n) * n
    inside = (mu >= mu_lo)
    pts = np.stack([np.degrees(phi[:n_points]), mu[:n_points]], axis=1)
    label = "cos θ′" + (f" (zoomed: ≥ {mu_lo:.7g})" if mu_lo > -1 else "")
    return View(np.degrees(phi_edges), mu_edges, obs, exp, pts, "φ′ [°] about the test axis", label,
                float(inside.mean()) if mu.size else 0.0)


def plane_view(result: c2.Chi2Result, s: Sampler, seed: int, n_points: int = 3000) -> View:
    """A 2-D point warp on the test's own regular (x, y) grid, with a fresh subset of points."""
    rng = np.random.default_rng(seed)
    pts, _ = s.sample(rng.random((n_points, 3)))
    edges = result.theta_edges  # the x edges of the test grid (square grid)
    return View(edges, edges, result.observed.T, result.expected.T, pts[:, :2], "x", "y", 1.0)


def view_of(result: c2.Chi2Result, n: int = 100_000, seed: int = 0) -> View | None:
    """The detailed view of a battery result (None when its sampler cannot be rebuilt, or the test has no bins:
    a delta BSDF's judge, a test that faulted)."""
    if result.observed is None:
        return None
    s = sampler_of(result)
    if s is None:
        return None
    try:
        if s.axis is None:
            obs = result.observed
            if obs is None or result.theta_edges is None or obs.shape[0] != obs.shape[1]:
                return None
            return plane_view(result, s, seed)
        with np.errstate(all="ignore"):
            return direction_view(s, n, seed)
    except Exception:  # noqa: BLE001 - a PluginFault or any plugin error: the test already has its verdict;
        return None  # the page just has no view


def verdict(result: c2.Chi2Result, negative: bool) -> tuple[str, str]:
    """(CSS class, text) of a test's verdict; a rejected negative control is what must happen."""
    if negative:
        return ("rejected", "rejected, as it must be") if not result.passed else \
            ("fail", "NOT rejected: the test is blind to this bug")
    return ("pass", "pass") if result.passed else ("fail", "FAIL")


VERDICT_COLOURS = {"pass": "#1a7f37", "fail": "#cf222e", "rejected": "#0b5cad"}


def _mu_axis(ax, view: View) -> None:
    """Readable cos θ′ ticks when the range is zoomed to within 10⁻³ of 1 (as 1 − x)."""
    from matplotlib.ticker import FuncFormatter

    if view.x_label != "x" and 1.0 - view.y_edges[0] < 1e-3:
        ax.yaxis.set_major_formatter(FuncFormatter(lambda y, _: "1" if y >= 1 else f"1−{1 - y:.1e}"))


def _distinct_labels(values: np.ndarray) -> list[str]:
    """Tick labels with the fewest significant digits (3 to 8) that tell distinct values apart (a thin streak's
    strips span hundredths of a degree)."""
    for digits in range(3, 9):
        labels = [f"{v:.{digits}g}" for v in values]
        if len(set(labels)) == len(set(values.tolist())):
            break
    return labels


def bin_maps(fig, axes, obs: np.ndarray, exp: np.ndarray, theta_edges: np.ndarray, titles: tuple[str, str]) -> None:
    """Observed and expected values of a chi-square test on its own bins (θ strips × φ bins, both pilot
    quantiles) on ``axes[0]`` and ``axes[1]`` with one colour scale and one colour bar."""
    vmax = max(float(np.max(obs)), float(np.max(exp)), 1.0)
    n_t = obs.shape[0]
    edges = np.degrees(theta_edges)
    ticks = np.arange(0, n_t + 1, max(1, n_t // 5))
    for ax, data, title in zip(axes[:2], (obs, exp), titles, strict=True):
        im = ax.imshow(data, origin="lower", aspect="auto", extent=(0, 360, 0, n_t), cmap="viridis", vmin=0,
                       vmax=vmax, interpolation="nearest")
        ax.set_yticks(ticks)
        ax.set_yticklabels(_distinct_labels(edges[ticks]), fontsize=7)
        ax.set_xticks([])  # the test's φ bins are quantiles of the pilot inside each θ strip, not degrees
        ax.tick_params(labelsize=7)
        ax.set_xlabel("φ bins (pilot quantiles within each θ strip)", fontsize=8)
        ax.set_ylabel("θ bin edges [°] (pilot quantiles)", fontsize=8)
        ax.set_title(title, fontsize=9)
    fig.colorbar(im, ax=list(axes[:2]), fraction=0.04, pad=0.01).ax.tick_params(labelsize=7)


def figure(result: c2.Chi2Result, view: View, negative: bool = False):
    """The detailed figure: test histograms, (φ′, cos θ′) observed | expected, residual map, points."""
    import matplotlib

    matplotlib.use("Agg")
    from brdflab.viz.mpl import safe_figures

    safe_figures()  # user text is never mathtext; log axes still read 10⁻²
    import matplotlib.pyplot as plt
    from matplotlib.colors import TwoSlopeNorm

    cls, text = verdict(result, negative)
    plane = view.x_label == "x"
    if plane:
        fig, axes = plt.subplots(1, 4, figsize=(15, 3.8))
        fig.subplots_adjust(left=0.04, right=0.98, top=0.86, bottom=0.14, wspace=0.3)
        top, bottom = [], list(axes)
    else:
        fig, axes = plt.subplots(2, 3, figsize=(14, 7.4))
        fig.subplots_adjust(left=0.06, right=0.97, top=0.92, bottom=0.07, wspace=0.32, hspace=0.3)
        top, bottom = list(axes[0]), list(axes[1])
    if top:
        ax_ = result.axis
        about = "" if ax_ is None or (ax_[0] == 0 and ax_[1] == 0) else \
            f" (θ about ({ax_[0]:.2g}, {ax_[1]:.2g}, {ax_[2]:.2g}))"
        bin_maps(fig, top, result.observed, result.expected, result.theta_edges,
                 ("test bins: observed counts" + about, "test bins: expected counts" + about))
        ax = top[2]
        ax.scatter(view.points[:, 0], view.points[:, 1], s=1.2, alpha=0.5, color="#333", linewidths=0)
        ax.set_xlim(view.x_edges[0], view.x_edges[-1])
        ax.set_ylim(view.y_edges[0], view.y_edges[-1])
        ax.set_xlabel(view.x_label, fontsize=8)
        ax.set_ylabel(view.y_label, fontsize=8)
        ax.tick_params(labelsize=7)
        _mu_axis(ax, view)
        ax.set_title(f"{len(view.points)} sampled directions", fontsize=9)
    ext = (view.x_edges[0], view.x_edges[-1], view.y_edges[0], view.y_edges[-1])
    vmax = max(float(view.observed.max()), float(view.expected.max()), 1.0)
    for ax, data, title in ((bottom[0], view.observed, "observed"), (bottom[1], view.expected, "expected")):
        im = ax.imshow(data, origin="lower", aspect="auto", extent=ext, cmap="viridis", vmin=0, vmax=vmax,
                       interpolation="nearest")
        ax.set_title(f"{title} counts, uniform bins", fontsize=9)
        ax.set_xlabel(view.x_label, fontsize=8)
        ax.set_ylabel(view.y_label, fontsize=8)
        ax.tick_params(labelsize=7)
        _mu_axis(ax, view)
    fig.colorbar(im, ax=bottom[:2], fraction=0.04, pad=0.01).ax.tick_params(labelsize=7)
    res = view.residual
    finite = np.abs(res[np.isfinite(res)])
    lim = max(3.0, min(float(np.percentile(finite, 99.5)) if finite.size else 3.0, 50.0))
    cmap = matplotlib.colormaps["RdBu_r"].with_extremes(bad="0.85")
    ax = bottom[2]
    im = ax.imshow(np.ma.masked_invalid(res), origin="lower", aspect="auto", extent=ext, cmap=cmap,
                   norm=TwoSlopeNorm(0.0, -lim, lim), interpolation="nearest")
    ax.set_title("residual (O − E)/√E: red = sampled too often", fontsize=9)
    ax.set_xlabel(view.x_label, fontsize=8)
    ax.set_ylabel(view.y_label, fontsize=8)
    ax.tick_params(labelsize=7)
    _mu_axis(ax, view)
    fig.colorbar(im, ax=ax, fraction=0.05, pad=0.02).ax.tick_params(labelsize=7)
    if plane:
        ax = bottom[3]
        ax.scatter(view.points[:, 0], view.points[:, 1], s=1.2, alpha=0.5, color="#333", linewidths=0)
        ax.set_aspect("equal")
        ax.set_title(f"{len(view.points)} warped points", fontsize=9)
        ax.tick_params(labelsize=7)
    params = " ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}"
                      for k, v in (result.params or {}).items() if v is not None)
    fig.suptitle(f"{result.name} {params}: p = {result.p_value:.3g} (threshold {result.threshold:.2g}) — {text}",
                 fontsize=11, color=VERDICT_COLOURS[cls], fontweight="bold")
    return fig


def thumbnail_png(result: c2.Chi2Result, scale: int = 4) -> bytes:
    """A small image of the test bins: observed | expected (shared viridis scale) | residual (RdBu, ±4)."""
    import io

    import matplotlib

    matplotlib.use("Agg")
    from brdflab.viz.mpl import safe_figures

    safe_figures()  # user text is never mathtext; log axes still read 10⁻²
    import matplotlib.image

    obs, exp = result.observed, result.expected
    vmax = max(float(obs.max()), float(exp.max()), 1.0)
    vir = matplotlib.colormaps["viridis"]
    with np.errstate(divide="ignore", invalid="ignore"):
        res = np.where(exp > 0, (obs - exp) / np.sqrt(exp), 0.0)
    div = matplotlib.colormaps["RdBu_r"]
    gap = np.ones((obs.shape[0], 2, 4))
    img = np.concatenate([vir(obs / vmax), gap, vir(exp / vmax), gap, div(np.clip(res / 8 + 0.5, 0, 1))], axis=1)
    img = np.kron(img, np.ones((scale, scale, 1)))
    buf = io.BytesIO()
    matplotlib.image.imsave(buf, img[::-1], format="png")
    return buf.getvalue()
