"""``brdflab plot``: every BRDF view as PNG and SVG, the data of each as CSV, and a self-contained page.

Outputs in the folder (all written to a temporary folder beside it first, then moved in, so a failed
run leaves no half-written set):

=====================  ==========================================================================
``polar.{png,svg}``     plane of incidence, linear and log (optionally × cos θ_o); ``polar.csv``
``lobe.{png,svg}``      3D lobe f·cos θ_o; ``lobe.csv`` (θ_o, φ_o, ω_o and f per BSDF)
``slice.{png,svg}``     θ_h × θ_d image at φ_d, log colour scale; ``slice.csv``
``albedo.{png,svg}``    directional albedo, quadrature and Monte Carlo ± 2σ; ``albedo.csv``
``sphere.{png,svg}``    lit spheres (point light, environment); ``sphere_<k>_<light>.exr``
``furnace.{png,svg}``   the white furnace under path tracing (only when asked: ``--views furnace``):
                        energy lost by a sphere of each BSDF against α; ``furnace.csv``
``index.html``          all views and a summary table, images embedded (opens without a server)
=====================  ==========================================================================

Every CSV starts with ``#`` comment lines stating what the values are and the angle conventions
(:mod:`brdflab.viz.coords`), then a header row; one value column per BSDF, named by its label.
"""

from __future__ import annotations

import csv
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from brdflab.errors import BrdflabError, clean
from brdflab.viz import coords, figures, reflectance, views

VIEWS = ("polar", "lobe", "slice", "albedo", "sphere", "furnace")
#: The views drawn unless others are asked for (the furnace renders a path-traced sphere per BSDF: on request).
DEFAULT_VIEWS = ("polar", "lobe", "slice", "albedo", "sphere")

POLAR_NOTE = ("theta_o_deg is signed, in the plane of incidence: omega_o = (-sin t cos phi_i, -sin t sin phi_i, "
              "cos t) for t = theta_o_deg, so positive angles lie on the side opposite omega_i's azimuth (the mirror "
              "direction is at +theta_i) and negative ones on omega_i's side (omega_o = omega_i at -theta_i)")
VALUE_NOTE = ("values: luminance Y = 0.2127 R + 0.7152 G + 0.0722 B of the BSDF value f(omega_i, omega_o) [1/sr], "
              "without the cosine")


@dataclass
class PlotOptions:
    """What ``brdflab plot`` draws (defaults as on the command line)."""

    theta: float = 45.0
    phi_d: float = 90.0
    times_cos: bool = False
    views: tuple[str, ...] = DEFAULT_VIEWS
    samples: int = 20_000
    sphere_size: int = 128
    sphere_spp: int = 16
    seed: int = 0
    workers: int | None = None


def _write_csv(path: Path, comments: list[str], header: list[str], columns: list[np.ndarray]) -> None:
    with open(path, "w", newline="") as f:
        for c in comments:
            f.write(f"# {c}\n")
        w = csv.writer(f)
        w.writerow(header)
        rows = np.column_stack([np.asarray(c, float).ravel() for c in columns])
        w.writerows([[f"{x:.9g}" for x in row] for row in rows])


def plot_files(views: tuple[str, ...], n_bsdfs: int) -> list[str]:
    """The names :func:`write_plots` writes into its folder for ``views`` of ``n_bsdfs`` BSDFs (checked by
    :func:`brdflab.outputs.prepare_folder` before anything is computed)."""
    from brdflab.viz.sphere import LIGHTS

    names = ["index.html"]
    for v in views:
        names += [f"{v}.png", f"{v}.svg"] + ([f"{v}.csv"] if v != "sphere" else [])
        if v == "sphere":
            names += [f"sphere_{k}_{li}.exr" for k in range(n_bsdfs) for li in range(len(LIGHTS))]
    return names


def check_plot_work(opts: PlotOptions, n_bsdfs: int) -> None:
    """Refuse (before the work) a plot whose Monte Carlo albedo or lit spheres would take longer than
    ``BRDFLAB_MAX_HOURS`` at brdflab's optimistic rate (:func:`brdflab.limits.check_work`), and check the
    memory of the albedo's sample batch."""
    import os

    from brdflab.limits import check_memory, check_work
    from brdflab.viz.sphere import SPP_FACTOR

    if "albedo" in opts.views:
        check_memory(opts.samples * 8 * 3 * 8, f"{opts.samples:,} albedo samples per angle")
        check_work(opts.samples * len(views.ALBEDO_THETAS) * n_bsdfs, 1,
                   f"the Monte Carlo albedo ({opts.samples:,} samples × {len(views.ALBEDO_THETAS)} angles × "
                   f"{n_bsdfs} BSDF(s))", limit_option=None)
    if "sphere" in opts.views:
        spp = opts.sphere_spp * sum(SPP_FACTOR.values())
        check_work(spp * opts.sphere_size**2 * n_bsdfs, opts.workers or os.cpu_count() or 1,
                   f"the lit spheres ({opts.sphere_size}² pixels × {spp:,} spp × {n_bsdfs} BSDF(s))",
                   limit_option=None)
    if "furnace" in opts.views:
        from brdflab.viz.white_furnace import SPP_FACTOR as FURNACE_SPP

        check_work(opts.sphere_spp * FURNACE_SPP * opts.sphere_size**2 * n_bsdfs, opts.workers or os.cpu_count() or 1,
                   f"the white furnace ({opts.sphere_size}² pixels × {opts.sphere_spp * FURNACE_SPP:,} spp × "
                   f"{n_bsdfs} BSDF(s), path traced)", limit_option=None)


def write_plots(bsdfs: list, labels: list[str], out: Path, opts: PlotOptions | None = None,
                progress=None) -> Path:
    """Write the views of ``bsdfs`` (legend ``labels``) into ``out``; return the path of ``index.html``."""
    from brdflab.pages.jinja import render

    opts = opts or PlotOptions()
    say = progress or (lambda msg: None)
    out = Path(out)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
        try:
            cards = _write_all(bsdfs, labels, tmp, opts, say)
            (tmp / "index.html").write_text(render(
                "plot.html.j2", title="brdflab plot: " + ", ".join(labels), cards=cards, labels=labels, opts=opts,
                polar_note=POLAR_NOTE, folder=tmp))
            out.mkdir(exist_ok=True)
            for p in sorted(tmp.iterdir()):
                os.replace(p, out / p.name)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    except OSError as exc:  # the folder was removed or made read-only during the run, a full disk …
        reason = clean(exc.strerror or exc, 80)
        raise BrdflabError(f"cannot write the plots into '{clean(out, 100)}': {reason}") from None
    return out / "index.html"


def _write_all(bsdfs: list, labels: list[str], out: Path, o: PlotOptions, say) -> list[dict]:
    cards = []
    wi = coords.incident(o.theta)
    head = [f"brdflab plot; BSDFs: {'; '.join(labels)}",
            f"theta_i_deg = {o.theta:g}, phi_i_deg = 0, omega_i = ({wi[0]:.6f}, {wi[1]:.6f}, {wi[2]:.6f}) in the "
            "local shading frame (z = normal)"]
    if "polar" in o.views:
        say("polar plot of the plane of incidence")
        t, v = views.polar(bsdfs, o.theta)
        deltas = [reflectance.delta_lobes(b, o.theta) if reflectance.all_delta(b) else None for b in bsdfs]
        _write_csv(out / "polar.csv", [*head, VALUE_NOTE, POLAR_NOTE], ["theta_o_deg", "cos_theta_o", *labels],
                   [t, np.cos(np.radians(t)), *v])
        figures.save(figures.polar_figure(t, v, labels, o.theta, o.times_cos, deltas=deltas), out / "polar")
        peak = [float(t[np.argmax(x)]) for x, d in zip(v, deltas, strict=True) if d is None]
        cards.append({"key": "polar", "title": "Plane of incidence",
                      "caption": ("f·cos θ_o" if o.times_cos else "f") + " against the signed θ_o, linear and log; "
                      "dashed: the mirror direction, arrow: ω_i"
                      + (", the whole circle: the transmitted half below the horizon" if abs(t[0]) > 90 else "")
                      + (". Peak at θ_o = " + ", ".join(f"{p:+.2f}°" for p in peak) if peak else "")
                      + (". Delta lobes (f is a Dirac delta, 0 in the CSV): spikes of length ∝ their energy "
                         "R or T" if any(d is not None for d in deltas) else "") + ".", "csv": "polar.csv"})
    if "lobe" in o.views:
        say("3D lobe")
        lb = views.lobe(bsdfs, o.theta)
        T, P = np.meshgrid(lb.theta_o_deg, lb.phi_o_deg, indexing="ij")
        d = lb.directions.reshape(-1, 3)
        _write_csv(out / "lobe.csv", [*head, VALUE_NOTE, "grid of the upper hemisphere: theta_o from the normal, "
                                      "phi_o from +x; x, y, z = omega_o; the plotted radius is value * |z|"],
                   ["theta_o_deg", "phi_o_deg", "x", "y", "z", *labels], [T, P, d[:, 0], d[:, 1], d[:, 2],
                                                                       *(x.ravel() for x in lb.values)])
        figures.save(figures.lobe_figure(lb, labels, o.theta, deltas=[
            reflectance.delta_lobes(b, o.theta) if reflectance.all_delta(b) else None for b in bsdfs]), out / "lobe")
        cards.append({"key": "lobe", "title": "3D lobe", "csv": "lobe.csv",
                      "caption": "the surface f·|cos θ_o| · ω_o over the hemisphere (the whole sphere when a BSDF "
                                 "transmits): the shape of the scattered radiance for light from ω_i."})
    if "slice" in o.views:
        say(f"half/difference slice at phi_d = {o.phi_d:g}")
        th, td, v = views.half_diff_slice(bsdfs, o.phi_d)
        TD, TH = np.meshgrid(td, th, indexing="ij")
        _write_csv(out / "slice.csv", [f"brdflab plot; BSDFs: {'; '.join(labels)}", VALUE_NOTE,
                                       f"Rusinkiewicz half/difference angles with phi_h = 0 and phi_d = {o.phi_d:g} "
                                       "deg (brdflab.viz.coords); nan: omega_i or omega_o below the horizon"],
                   ["theta_h_deg", "theta_d_deg", *labels], [TH, TD, *(x.ravel() for x in v)])
        notes = ["delta lobes only: f = 0 here (see the polar view)" if reflectance.all_delta(b) else None
                 for b in bsdfs]
        figures.save(figures.slice_figure(th, td, v, labels, o.phi_d, notes=notes), out / "slice")
        cards.append({"key": "slice", "title": f"θ_h × θ_d slice (φ_d = {o.phi_d:g}°)", "csv": "slice.csv",
                      "caption": "Rusinkiewicz's half/difference angles: specular peaks run along small θ_h, "
                                 "Fresnel shows as θ_d → 90°; log colour scale shared by all panels"
                                 + ("; reflection only (the half vector of a transmitted pair is another one)"
                                    if any(reflectance.transmits(b) for b in bsdfs) else "") + "."})
    if "albedo" in o.views:
        say(f"directional albedo (quadrature and {o.samples} Monte Carlo samples per angle)")
        alb = views.albedo(bsdfs, n=o.samples, seed=o.seed)
        cols, names = [alb.theta_deg], ["theta_i_deg"]
        for k, lab in enumerate(labels):
            cols += [alb.quadrature[k], alb.monte_carlo[k], alb.mc_stderr[k]]
            names += [f"{lab} quadrature", f"{lab} monte_carlo", f"{lab} mc_stderr"]
            if alb.any_transmission:
                cols += [alb.reflected[k], alb.transmitted[k], alb.mc_parts[k, :, 0, 0], alb.mc_parts[k, :, 1, 0]]
                names += [f"{lab} R quadrature", f"{lab} T quadrature", f"{lab} R monte_carlo",
                          f"{lab} T monte_carlo"]
        _write_csv(out / "albedo.csv", [f"brdflab plot; BSDFs: {'; '.join(labels)}",
                                        "directional albedo rho(theta_i) = integral of f cos theta_o over the "
                                        "hemisphere (luminance Y), phi_i = 0; quadrature, and Monte Carlo mean of "
                                        f"the BSDF's sample weights with its standard error ({alb.samples} samples); "
                                        "a transmitting BSDF: R + T, T = integral of f |cos theta_o| (eta_o/eta_i)^2 "
                                        "below the surface (energy)"],
                   names, cols)
        figures.save(figures.albedo_figure(alb, labels), out / "albedo")
        worst = float(np.max(np.abs(alb.quadrature - alb.monte_carlo) / np.maximum(alb.mc_stderr, 1e-12)))
        cards.append({"key": "albedo", "title": "Directional albedo", "csv": "albedo.csv",
                      "caption": "quadrature (lines) and Monte Carlo of the BSDF's own sampler (dots, ± 2σ); "
                                 f"largest |quadrature − MC| = {worst:.1f} σ."})
    if "sphere" in o.views:
        from brdflab.imageio import write_exr
        from brdflab.viz import sphere

        say(f"lit spheres ({o.sphere_size}x{o.sphere_size}, {o.sphere_spp} spp, direct_mis)")
        imgs = sphere.render_spheres(bsdfs, o.sphere_size, o.sphere_spp, o.seed, o.workers)
        for li, (light, row) in enumerate(imgs.items()):
            for k, img in enumerate(row):
                write_exr(out / f"sphere_{k}_{li}.exr", img, comments=f"brdflab plot: {labels[k]} under {light}")
        figures.save(figures.sphere_figure(imgs, labels, sphere.silhouette_radius(o.sphere_size)), out / "sphere")
        cards.append({"key": "sphere", "title": "Lit sphere", "csv": None,
                      "caption": "rendered by brdflab (direct_mis; path_mis for a material that transmits): a "
                                 "point light above left of the camera "
                                 f"({o.sphere_spp} spp; dashed: the silhouette), and a procedural sky with a sun "
                                 f"({o.sphere_spp * sphere.SPP_FACTOR['environment']} spp); linear images in "
                                 "sphere_<bsdf>_<light>.exr (light 0: point, 1: environment)."})
    if "furnace" in o.views:
        cards.append(_furnace(bsdfs, labels, out, o, say))
    for c in cards:
        c["png"] = out / f"{c['key']}.png"
        c["svg"] = f"{c['key']}.svg"
        if c["csv"]:
            with open(out / c["csv"]) as f:
                c["preview"] = "".join(next(f) for _ in range(6))
    return cards


def _furnace(bsdfs: list, labels: list[str], out: Path, o: PlotOptions, say) -> dict:
    from brdflab.viz import white_furnace as wf

    say(f"white furnace (path_mis, {o.sphere_size}x{o.sphere_size}, {o.sphere_spp * wf.SPP_FACTOR} spp)")
    res, mask, mu = wf.render_furnace(bsdfs, labels, o.sphere_size, o.sphere_spp * wf.SPP_FACTOR, o.seed, o.workers)
    pred = wf.predicted_losses(bsdfs, res, mask, mu)
    with open(out / "furnace.csv", "w", newline="") as f:
        f.write(wf.csv_text(res, pred, "plot"))
    figures.save(wf.furnace_figure(res, pred), out / "furnace")
    return {"key": "furnace", "title": "White furnace (path traced)", "csv": "furnace.csv",
            "caption": "a sphere of each BSDF in a uniform white environment, rendered by path_mis with Russian "
                       "roulette only: the energy it loses (1 − its mean radiance; a lossless material reads 0). "
                       "Dashed: the single-bounce loss by quadrature of the directional albedo (non-transmissive "
                       "BSDFs: on a convex sphere light bounces once), which the renders must match."}
