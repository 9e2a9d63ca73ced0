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
from dataclasses import dataclass, field, replace
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
    error: str = ""
    """What the BSDF raised (``render_furnace(catch=True)``); the numbers are then NaN."""

    @property
    def loss(self) -> float:
        """Energy lost: 1 − :attr:`mean`."""
        return 1.0 - self.mean


def render_furnace(bsdfs: list, labels: list[str] | None = None, size: int = 48, spp: int = 64, seed: int = 0,
                   workers: int | None = None, catch: bool = False, alphas: list | None = None
                   ) -> tuple[list[FurnaceResult], np.ndarray, np.ndarray]:
    """Render a sphere of each BSDF in the white furnace (module docstring); returns the results and the
    sphere's (mask, μ) from :func:`sphere_cosines`. ``spp`` is split over :data:`RUNS` independent renders; the
    k-th BSDF's runs have their own seeds (from ``seed``, k and the run), so the same list gives the same numbers
    wherever it is rendered (``plot --views furnace``, ``validate``'s page). ``catch``: a BSDF that raises
    gets a result with NaN numbers and :attr:`FurnaceResult.error` set instead of stopping the others.
    ``alphas``: each BSDF's α for the figure (default its ``alpha_value``, None without one)."""
    from brdflab.renderer import render
    from brdflab.scene.loader import load_scene

    runs_spp = max(1, spp // RUNS)
    out = []
    with tempfile.TemporaryDirectory(prefix="brdflab-furnace-") as tmp:
        base = load_scene(write_scene(Path(tmp), size))  # loaded once: each render gets a copy with its BSDF
    mask, mu = sphere_cosines(base.camera)
    for k, bsdf in enumerate(bsdfs):
        label = labels[k] if labels else getattr(bsdf, "type_name", type(bsdf).__name__)
        alpha = alphas[k] if alphas is not None else getattr(bsdf, "alpha_value", None)
        alpha = None if alpha is None else float(alpha)
        means, imgs = [], []
        try:
            for r in range(RUNS):
                # a new Scene (dataclasses.replace): no per-scene tables cached from another material
                img, _ = render(replace(base, bsdfs=[bsdf]), spp=runs_spp, seed=seed * 7919 + 97 * k + r,
                                workers=workers)
                lum = np.asarray(img, np.float64).mean(axis=2)
                imgs.append(lum)
                means.append(float(lum[mask].mean()))
        except Exception as exc:  # noqa: BLE001 - a user's BSDF: reported in its row, the others still render
            if not catch:
                raise
            from brdflab.errors import clean

            why = f"{type(exc).__name__}: {clean(str(exc), 160)}"
            out.append(FurnaceResult(label, alpha, float("nan"), float("nan"), runs_spp * RUNS,
                                     np.full(mask.shape, np.nan), error=why))
            continue
        out.append(FurnaceResult(label, alpha, float(np.mean(means)), float(np.std(means, ddof=1) / np.sqrt(RUNS)),
                                 runs_spp * RUNS, np.mean(imgs, axis=0)))
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


#: Per material (not colour alone, so that the figure reads in grey print): a marker and a line style.
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")
LINES = ("-", "--", "-.", ":", (0, (5, 1, 1, 1, 1, 1)), (0, (1, 1)), (0, (8, 2)), (0, (3, 1, 3, 4)))


def material_key(label: str) -> str:
    """A result's material: its label without the ``alpha=…`` word."""
    return " ".join(w for w in label.split() if not w.startswith("alpha=")) or label


def furnace_figure(results: list[FurnaceResult], predicted: dict[str, float] | None = None):
    """Energy lost (%) against α, one marker and line style per material (``label`` up to its ``alpha=…``; legible
    in grey print); materials without a roughness are horizontal lines. ``predicted``: label → the
    single-scattering loss of a non-transmissive BSDF by quadrature (hollow markers of the material's shape),
    the figure's own check."""
    from brdflab.viz.figures import _plt, colours

    plt = _plt()
    groups: dict[str, list[FurnaceResult]] = {}
    for r in results:
        if np.isfinite(r.mean):
            groups.setdefault(material_key(r.label), []).append(r)
    fig, ax = plt.subplots(figsize=(7.2, 4.6), dpi=100)
    cols = colours(len(groups))
    alphas = sorted({r.alpha for r in results if r.alpha is not None}) or [0.0, 1.0]
    flat = [key for key, rs in groups.items() if all(r.alpha is None for r in rs)]
    handles: dict[str, object] = {}
    for k, (c, (key, rs)) in enumerate(zip(cols, groups.items(), strict=True)):
        style = {"color": c, "marker": MARKERS[k % len(MARKERS)], "ls": LINES[k % len(LINES)]}
        rs = sorted(rs, key=lambda r: -1.0 if r.alpha is None else r.alpha)
        if all(r.alpha is None for r in rs):
            r = rs[0]
            ax.fill_between([alphas[0], alphas[-1]], 100 * (r.loss - 2 * r.stderr), 100 * (r.loss + 2 * r.stderr),
                            color=c, alpha=0.15, lw=0)
            # lossless materials share the line 0: each puts its markers on every len(flat)-th α of its own
            handles[f"{key}: {100 * r.loss:+.2f} % (± {200 * r.stderr:.2f})"], = ax.plot(
                alphas, [100 * r.loss] * len(alphas), lw=1.2, ms=6, mfc="white",
                markevery=(flat.index(key) % len(alphas), max(len(flat), 1)), **style)
            continue
        a = [r.alpha for r in rs]
        handles[key] = ax.errorbar(a, [100 * r.loss for r in rs], yerr=[200 * r.stderr for r in rs], ms=4,
                                   capsize=2, lw=1.3, **style)
        pred = [predicted.get(r.label) for r in rs] if predicted else []
        if pred and all(p is not None for p in pred):
            ax.plot(a, [100 * p for p in pred], color=c, marker=style["marker"], ms=9, mfc="none", mew=0.9, ls="none")
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_xlabel("roughness α")
    ax.set_ylabel("energy lost: 1 − mean radiance of the sphere [%]")
    spp = results[0].spp if results else 0
    ax.set_title(f"White furnace under path tracing (path_mis, {spp} spp, roulette only)", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(list(handles.values()), list(handles), fontsize=7, loc="upper left", framealpha=0.9,
              title="filled: renders ± 2σ; hollow: one bounce by quadrature", title_fontsize=7)
    fig.tight_layout()
    return fig


def table_rows(results: list[FurnaceResult], predicted: dict[str, float]) -> list[dict]:
    """One row per sphere: material, α, energy lost by the render (± its standard error), the single-bounce loss
    by quadrature (non-transmissive BSDFs) and their difference in standard errors; plain strings and numbers
    (``plot``'s furnace.csv and ``validate``'s table)."""
    rows = []
    for r in results:
        p = predicted.get(r.label)
        z = (r.loss - p) / r.stderr if p is not None and r.stderr > 0 else None
        rows.append({"bsdf": r.label, "material": material_key(r.label), "alpha": r.alpha, "mean": r.mean,
                     "stderr": r.stderr, "loss": r.loss, "single_scattering_loss": p, "z": z, "error": r.error})
    return rows


def predicted_losses(bsdfs: list, results: list[FurnaceResult], mask: np.ndarray, mu: np.ndarray) -> dict:
    """label → 1 − mean over the sphere's pixels of ρ(μ) (:func:`single_scattering`), for the non-transmissive
    BSDFs that rendered; the renders must agree with these within their noise."""
    out = {}
    for bsdf, r in zip(bsdfs, results, strict=True):
        if r.error or getattr(bsdf, "has_transmission", False) or getattr(bsdf, "has_delta", False):
            continue
        out[r.label] = 1.0 - float(single_scattering(bsdf, mu[mask]).mean())
    return out


def csv_text(results: list[FurnaceResult], predicted: dict[str, float], command: str) -> str:
    """The furnace's table as CSV (``#`` comment lines first), as ``plot`` and ``validate`` write it."""
    import csv
    import io

    f = io.StringIO()
    f.write(f"# brdflab {command}; white furnace: a unit sphere of each BSDF under a uniform environment of radiance "
            f"1, path_mis ({results[0].spp if results else 0} spp, {RUNS} independent runs, roulette only, no depth "
            "cap)\n# mean: mean luminance of the sphere's pixels; loss = 1 - mean; stderr over the runs; "
            "single_scattering_loss: 1 - mean of the directional albedo by quadrature over the same pixels "
            "(non-transmissive BSDFs only: one bounce on a convex sphere)\n")
    w = csv.writer(f)
    w.writerow(["bsdf", "alpha", "mean", "stderr", "loss", "single_scattering_loss"])
    for r in table_rows(results, predicted):
        p = r["single_scattering_loss"]
        w.writerow([r["bsdf"], "" if r["alpha"] is None else f"{r['alpha']:g}", f"{r['mean']:.6f}",
                    f"{r['stderr']:.6f}", f"{r['loss']:.6f}", "" if p is None else f"{p:.6f}"])
    return f.getvalue()


#: ``validate --furnace-render``: (image side in pixels, samples per pixel) of each sphere; ``off``: none.
LEVELS = {"quick": (32, 32), "normal": (64, 64), "full": (128, 256)}


@dataclass
class FurnaceRun:
    """The white furnace of the BSDFs ``validate`` judged (:func:`battery_furnace`)."""

    results: list[FurnaceResult]
    predicted: dict[str, float]
    """label → single-bounce loss by quadrature (non-transmissive BSDFs)."""
    size: int
    spp: int
    seconds: float

    def rows(self) -> list[dict]:
        """:func:`table_rows` of the run."""
        return table_rows(self.results, self.predicted)


def battery_materials(bsdfs=None, params: dict | None = None, alphas=None, make=None):
    """(BSDFs, labels, α per BSDF, failures) of ``validate``'s white furnace: every entry the battery judges
    with the consistency and furnace checks (:func:`brdflab.judges.material.entries.resolve_bsdfs`; built-ins and
    plugins, delta and transmissive ones included, lobe variants left out) at its furnace parameters, over
    ``alphas`` (default the battery's furnace α) when it has a roughness. A user's BSDF is checked on every
    call (a NaN is an error, as in ``plot``); ``failures``: results of the BSDFs whose constructor raised."""
    from brdflab.builtin_types import is_builtin_class
    from brdflab.errors import clean
    from brdflab.judges.core.guard import CheckedBSDF, SceneCheckedBSDF
    from brdflab.judges.material.entries import FURNACE_ALPHAS, furnace_name, furnace_parameters, resolve_bsdfs

    params = dict(params or {})
    objs, labels, alpha_of, failed = [], [], [], []
    for e in resolve_bsdfs(bsdfs, make):
        if not e.checks:
            continue
        for point in e.grid(params):
            prm, name = furnace_parameters(e, params, point), furnace_name(e, point)
            for a in (tuple(alphas or FURNACE_ALPHAS) if e.takes_alpha else (None,)):
                label = name if a is None else f"{name} alpha={a:g}"
                try:
                    b = e.make(a, prm)
                except Exception as exc:  # noqa: BLE001 - reported in its row
                    failed.append(FurnaceResult(label, a, float("nan"), float("nan"), 0, np.zeros((0, 0)),
                                                error=f"{type(exc).__name__}: {clean(str(exc), 200)}"))
                    continue
                wrap = not isinstance(b, CheckedBSDF) and not is_builtin_class(type(b))
                objs.append(SceneCheckedBSDF(b) if wrap else b)
                labels.append(label)
                alpha_of.append(a)
    return objs, labels, alpha_of, failed


def battery_furnace(bsdfs=None, params: dict | None = None, level: str = "normal", seed: int = 0,
                    workers: int | None = None, make=None, progress=None) -> FurnaceRun:
    """Render the white furnace of the BSDFs ``validate`` judged (:func:`battery_materials`) at ``level``
    (:data:`LEVELS`): the same numbers as ``plot --views furnace`` gives for the same BSDFs in the same order,
    ``--size`` the level's side and ``--spp`` its spp / :data:`SPP_FACTOR`."""
    import time

    size, spp = LEVELS[level]
    t0 = time.perf_counter()
    objs, labels, alpha_of, failed = battery_materials(bsdfs, params, None, make)
    if progress:
        progress(f"white furnace: {len(objs)} spheres ({size}x{size}, {spp} spp, path_mis)")
    res, mask, mu = render_furnace(objs, labels, size, spp, seed, workers, catch=True, alphas=alpha_of)
    try:
        pred = predicted_losses(objs, res, mask, mu)
    except Exception as exc:  # noqa: BLE001 - a user's BSDF failing the quadrature: the renders still show
        pred = {}
        if progress:
            progress(f"white furnace: no single-bounce quadrature ({type(exc).__name__})")
    run = FurnaceRun(res + failed, pred, size, spp, time.perf_counter() - t0)
    if progress:
        ok = [r for r in res if not r.error]
        worst = max(ok, key=lambda r: r.loss, default=None)
        progress(f"white furnace: {len(ok)} spheres rendered in {run.seconds:.1f} s"
                 + (f"; most energy lost: {worst.label} {100 * worst.loss:.1f} %" if worst else "")
                 + (f"; {len(res) + len(failed) - len(ok)} raised" if len(ok) < len(res) + len(failed) else ""))
    return run
