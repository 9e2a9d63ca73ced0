"""The white furnace under path tracing: a sphere of the material in a uniform white environment (radiance 1).

A lossless material is invisible there: every pixel reads 1. What a sphere of the material loses is
``1 − mean radiance of the sphere's pixels`` — the classic figure of single-scattering microfacet models losing
energy at high roughness (the light that would scatter again between microfacets is dropped; Heitz et al. 2016,
Kulla & Conty 2017), measured here on brdflab's own renders: ``path_mis`` with Russian roulette only (no depth cap),
of a unit sphere (:func:`brdflab.scene.shapes.uv_sphere`, 96 × 192 quads, interpolated normals) seen from
:data:`DISTANCE` = 40 radii through a box filter, under a constant ``environment`` emitter.

What it must read (the tests hold it to these, independently of the renderer):

* a **non-transmissive** BSDF on a convex sphere scatters once: the ray leaves to the environment, so the pixel
  whose camera ray meets the sphere at angle θ to the normal reads the **directional albedo** ρ(θ) =
  ∫ f cos θ_o dω_o, computed by quadrature (:func:`brdflab.viz.views.albedo_quadrature`). The sphere's mean is then
  the mean of ρ over its pixels; from far away that is the hemispherical average 2∫ρ(μ)μ dμ
  (:func:`single_scattering`). Diffuse with albedo 1 and the mirror read 1;
* a **smooth dielectric** conserves energy whatever the path inside (every split of R and T, total internal
  reflection, the (η_i/η_t)² radiance scale undone on the way out): 1 within noise. A rough dielectric has no
  closed form (light crosses the surface several times): its loss is the figure's own finding.

The standard error of each mean comes from :data:`RUNS` independent renders (different seeds) of spp/RUNS each.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from brdflab.scene.shapes import uv_sphere, write_obj

#: Camera distance in sphere radii (the view directions across the sphere differ by ≤ 1.5°).
DISTANCE = 40.0
#: Independent renders behind every mean (its standard error).
RUNS = 4
#: Materials of the classic figure (built-ins at their furnace parameters: R0 = 1, k_d = 1, albedo = 1).
CLASSIC = (("roughconductor", {"R0": "1"}), ("roughdielectric", {}), ("roughsubstrate", {"kd": "1"}),
           ("diffuse", {"albedo": "1"}), ("mirror", {}), ("dielectric", {}))
#: Samples per pixel of the furnace relative to the plot's lit-sphere ``--spp`` (16 → 64).
SPP_FACTOR = 4
#: The α axis of the classic figure.
ALPHAS = (0.05, 0.1, 0.2, 0.35, 0.5, 0.75, 1.0)


def fov_deg() -> float:
    """Field of view (degrees) that frames the sphere with a 4 % margin."""
    return float(2 * np.degrees(np.arctan(1.04 * np.tan(np.arcsin(1.0 / DISTANCE)))))


def write_scene(folder: Path, size: int) -> Path:
    """The furnace scene (sphere.obj and furnace.xml) in ``folder``; returns the XML's path."""
    v, f, n, uv = uv_sphere(n_theta=96, n_phi=192)
    write_obj(folder / "sphere.obj", v, f, n, uv)
    path = folder / "furnace.xml"
    path.write_text(
        '<scene>\n  <integrator type="path_mis"/>\n  <camera type="perspective">\n'
        f'    <transform name="toWorld"><lookat origin="0, 0, {DISTANCE}" target="0, 0, 0" up="0, 1, 0"/>'
        f'</transform>\n    <float name="fov" value="{fov_deg()!r}"/>\n'
        f'    <integer name="width" value="{size}"/><integer name="height" value="{size}"/>\n'
        '    <rfilter type="box"/>\n  </camera>\n'
        '  <mesh type="obj"><string name="filename" value="sphere.obj"/><bsdf type="diffuse"/></mesh>\n'
        '  <emitter type="environment"><color name="radiance" value="1, 1, 1"/></emitter>\n</scene>\n')
    return path


def sphere_cosines(camera, sub: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """(mask, μ) per pixel, by analytic ray–unit-sphere intersection (not the renderer's mesh): ``mask`` the
    pixels whose ``sub`` × ``sub`` sub-pixel rays all hit the sphere, μ (H, W, sub²) = cos θ between the
    reversed ray and the sphere's normal at each sub-pixel position (NaN where a ray misses)."""
    h, w = camera.height, camera.width
    off = (np.arange(sub) + 0.5) / sub
    yy, xx, oy, ox = np.meshgrid(np.arange(h), np.arange(w), off, off, indexing="ij")
    o, d, _ = camera.generate_rays((xx + ox).ravel(), (yy + oy).ravel())
    o = np.asarray(o, np.float64)
    b = np.einsum("ij,ij->i", o, d)
    disc = b * b - (np.einsum("ij,ij->i", o, o) - 1.0)
    hit = disc > 0
    t = -b - np.sqrt(np.where(hit, disc, 0.0))
    normal = o + t[:, None] * d
    mu = np.where(hit, -np.einsum("ij,ij->i", normal, d), np.nan).reshape(h, w, sub * sub)
    return np.isfinite(mu).all(axis=2), mu


@dataclass
class FurnaceResult:
    """The sphere of one BSDF in the white furnace."""

    label: str
    alpha: float | None
    mean: float
    """Mean luminance of the sphere's pixels (1: lossless)."""
    stderr: float
    """Its standard error over :data:`RUNS` independent renders."""
    spp: int
    image: np.ndarray = field(repr=False)
    """(H, W) luminance of the sphere (all runs)."""

    @property
    def loss(self) -> float:
        """Energy lost: 1 − :attr:`mean`."""
        return 1.0 - self.mean


def render_furnace(bsdfs: list, labels: list[str] | None = None, size: int = 48, spp: int = 64, seed: int = 0,
                   workers: int | None = None) -> tuple[list[FurnaceResult], np.ndarray, np.ndarray]:
    """Render a sphere of each BSDF in the white furnace (module docstring); returns the results and the
    sphere's (mask, μ) from :func:`sphere_cosines`. ``spp`` is split over :data:`RUNS` independent renders."""
    from brdflab.renderer import render
    from brdflab.scene.loader import load_scene

    runs_spp = max(1, spp // RUNS)
    out = []
    with tempfile.TemporaryDirectory(prefix="brdflab-furnace-") as tmp:
        path = write_scene(Path(tmp), size)
        mask, mu = sphere_cosines(load_scene(path).camera)
        for k, bsdf in enumerate(bsdfs):
            means, imgs = [], []
            for r in range(RUNS):
                scene = load_scene(path)
                scene.bsdfs[0] = bsdf
                img, _ = render(scene, spp=runs_spp, seed=seed * 7919 + 97 * k + r, workers=workers)
                lum = np.asarray(img, np.float64).mean(axis=2)
                imgs.append(lum)
                means.append(float(lum[mask].mean()))
            alpha = getattr(bsdf, "alpha_value", None)
            out.append(FurnaceResult(labels[k] if labels else getattr(bsdf, "type_name", type(bsdf).__name__),
                                     None if alpha is None else float(alpha), float(np.mean(means)),
                                     float(np.std(means, ddof=1) / np.sqrt(RUNS)), runs_spp * RUNS,
                                     np.mean(imgs, axis=0)))
    return out, mask, mu


def albedo_table(bsdf, n: int = 24) -> tuple[np.ndarray, np.ndarray]:
    """(μ nodes, ρ(μ)) of a non-transmissive BSDF by quadrature at ``n`` Gauss–Legendre nodes in μ ∈ (0, 1)."""
    from brdflab.viz.views import albedo_quadrature

    x, _ = np.polynomial.legendre.leggauss(n)
    mu = 0.5 * (x + 1.0)
    return mu, np.array([albedo_quadrature(bsdf, float(np.degrees(np.arccos(m)))) for m in mu])


def single_scattering(bsdf, mu: np.ndarray, n: int = 24) -> np.ndarray:
    """ρ at the cosines ``mu`` (any shape), interpolated in μ from :func:`albedo_table`: what a non-transmissive
    sphere's pixels read in the furnace (one bounce)."""
    nodes, rho = albedo_table(bsdf, n)
    full = np.concatenate([[0.0], nodes, [1.0]])
    vals = np.concatenate([[rho[0]], rho, [rho[-1]]])
    return np.interp(np.clip(mu, 0.0, 1.0), full, vals)


def furnace_figure(results: list[FurnaceResult], predicted: dict[str, float] | None = None):
    """Energy lost (%) against α, one colour per material (``label`` up to its ``alpha=…``); materials without
    a roughness are horizontal lines. ``predicted``: label → the single-scattering loss of a non-transmissive
    BSDF by quadrature (dashed), the figure's own check."""
    from brdflab.viz.figures import _plt, colours

    plt = _plt()
    groups: dict[str, list[FurnaceResult]] = {}
    for r in results:
        key = " ".join(w for w in r.label.split() if not w.startswith("alpha=")) or r.label
        groups.setdefault(key, []).append(r)
    fig, ax = plt.subplots(figsize=(7.2, 4.6), dpi=100)
    cols = colours(len(groups))
    alphas = sorted({r.alpha for r in results if r.alpha is not None}) or [0.0, 1.0]
    for c, (key, rs) in zip(cols, groups.items(), strict=True):
        rs = sorted(rs, key=lambda r: -1.0 if r.alpha is None else r.alpha)
        if all(r.alpha is None for r in rs):
            r = rs[0]
            ax.axhline(100 * r.loss, color=c, lw=1.2, ls=":")
            ax.fill_between([alphas[0], alphas[-1]], 100 * (r.loss - 2 * r.stderr), 100 * (r.loss + 2 * r.stderr),
                            color=c, alpha=0.2, label=f"{key}: {100 * r.loss:+.2f} % (± {200 * r.stderr:.2f})")
            continue
        a = [r.alpha for r in rs]
        ax.errorbar(a, [100 * r.loss for r in rs], yerr=[200 * r.stderr for r in rs], color=c, marker="o", ms=3.5,
                    capsize=2, label=key)
        pred = [predicted.get(r.label) for r in rs] if predicted else []
        if pred and all(p is not None for p in pred):
            ax.plot(a, [100 * p for p in pred], color=c, ls="--", lw=1)
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_xlabel("roughness α")
    ax.set_ylabel("energy lost: 1 − mean radiance of the sphere [%]")
    spp = results[0].spp if results else 0
    ax.set_title(f"White furnace under path tracing (path_mis, {spp} spp, roulette only)", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left", title="markers: renders ± 2σ; dashed: one bounce by quadrature",
              title_fontsize=7)
    fig.tight_layout()
    return fig


def predicted_losses(bsdfs: list, results: list[FurnaceResult], mask: np.ndarray, mu: np.ndarray) -> dict:
    """label → 1 − mean over the sphere's pixels of ρ(μ) (:func:`single_scattering`), for the non-transmissive
    BSDFs; the renders must agree with these within their noise."""
    out = {}
    for bsdf, r in zip(bsdfs, results, strict=True):
        if getattr(bsdf, "has_transmission", False) or getattr(bsdf, "has_delta", False):
            continue
        out[r.label] = 1.0 - float(single_scattering(bsdf, mu[mask]).mean())
    return out
