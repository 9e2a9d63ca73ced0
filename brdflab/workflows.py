"""The command line's workflows as Python functions: ``check``, ``compare``, ``report``, ``plot``, ``validate``.

Each returns the result object whose ``to_dict()`` the corresponding command writes as JSON
(:class:`~brdflab.stats.render_check.CheckResult`, :class:`Comparison`, :class:`~brdflab.pages.variance.Study`,
:class:`PlotResult`, :class:`~brdflab.judges.material.battery.Battery`) and writes the same HTML page when given an
``output`` folder. Images may be arrays or EXR paths; ``plugins`` are loaded first, exactly like ``--plugin``.
``import brdflab as bl`` exports them as ``bl.check``, ``bl.compare``, ``bl.report``, ``bl.plot`` and
``bl.validate``; ``docs/api.md`` shows each in use (executed by the tests).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from brdflab.errors import BrdflabError


def _image(x, what: str) -> np.ndarray:
    """An (H, W, 3) float array from an array or an EXR path."""
    if isinstance(x, str | Path):
        from brdflab.imageio import read_exr

        return read_exr(Path(x))
    a = np.asarray(x, dtype=np.float64)
    if a.ndim != 3 or a.shape[2] < 1:
        raise BrdflabError(f"{what}: expected an (H, W, C) image or an EXR path, got an array of shape {a.shape}")
    return a


def _specs(plugins) -> list:
    """The ``plugins`` argument as a list (inputs of the run: never an output)."""
    return [] if plugins is None else [plugins] if isinstance(plugins, str | Path) else list(plugins)


def _load_plugins(plugins) -> None:
    from brdflab.plugins import load_plugins

    load_plugins([plugins] if isinstance(plugins, str | Path) else plugins)


#: Which methods of a scene's BSDFs each integrator calls for brdflab's own estimate (a bug in a method the
#: estimate calls is in the estimate too, so the check cannot see it).
USER_METHODS = {"direct_ems": ("eval",), "direct_mats": ("sample",), "direct_mis": ("eval", "pdf", "sample"),
                "direct_whitted": ("eval",), "normals": ()}


def estimate_integrator(scene, integrator: str | None) -> tuple[str, str]:
    """The integrator of brdflab's estimate for ``check``, and a sentence saying whose code it runs.

    Asked for one (``integrator``): that one. Otherwise the scene's, except when the scene has a user's BSDF
    (a plugin) and the scene's integrator calls its ``sample``/``pdf``: then ``direct_ems``, which calls only
    ``eval`` — a bug in the plugin's sampler or pdf would otherwise be in brdflab's estimate as well and cancel
    out (a render and an estimate that share a bug agree).
    """
    from brdflab.builtin_types import is_builtin_class

    mine = sorted({type(b).__name__ for b in scene.bsdfs if not is_builtin_class(type(b))})
    chosen = integrator or scene.integrator_type
    if integrator is None and mine and "direct_ems" in USER_METHODS and chosen in ("direct_mats", "direct_mis"):
        chosen = "direct_ems"
    if not mine:
        return chosen, ""
    uses = USER_METHODS.get(chosen, ("eval", "pdf", "sample"))
    unused = [m for m in ("eval", "pdf", "sample") if m not in uses]
    what = ", ".join(f"{m}()" for m in uses) or "none of its methods"
    note = (f"brdflab's estimate ({chosen}) runs your {', '.join(mine)}'s {what}: a bug there is in both images "
            "and cannot show")
    if unused:
        note += f"; {', '.join(f'{m}()' for m in unused)} are not used, so a bug in them shows as a difference"
    if integrator is None and chosen != scene.integrator_type:
        note += f" (the scene's {scene.integrator_type} would run your sampler too; --integrator to choose)"
    return chosen, note


def check(renders, scene: str | Path, *, integrator: str | None = None, spp: int = 32, runs: int = 4,
          seed: int = 0, ref=None, ref_var=None, user_spp: int | None = None, block: int = 16, levels: int = 4,
          alpha: float = 0.01, workers: int | None = None, output: str | Path | None = None, force: bool = False,
          plugins: Sequence[str] | str | None = None, progress: Callable[[str], None] | None = None,
          resolution: tuple[int, int] | None = None, where_spp: int = 8, cluster=None):
    """Is a render an unbiased estimate of ``scene``? (``brdflab check``; the command calls this function)

    Parameters
    ----------
    renders
        One render or a list of independent renders (arrays (H, W, 3) or EXR paths) of the scene.
    scene
        The Nori scene file they show.
    integrator
        brdflab's integrator for its own estimate (default: the scene's; with a user's BSDF whose ``sample`` or
        ``pdf`` the scene's integrator would call, ``direct_ems``: see :func:`estimate_integrator`).
    spp, runs, seed
        brdflab's independent runs (each ``spp`` samples per pixel) and their base seed.
    ref, ref_var
        A reference image (and its per-pixel variance of the mean) to use instead of rendering.
    user_spp
        Samples per pixel of the renders (default: their ``brdflab_spp`` attribute, else the scene's).
    block, levels, alpha
        Block side (px), number of block sizes block·2^i, family-wise false-alarm level.
    output, force
        A folder for ``check.html``, ``check.json`` and the maps (nothing is written without it), checked
        before the work (:func:`brdflab.outputs.prepare_folder`); ``force`` replaces files brdflab did not write.
    plugins
        ``--plugin`` specs the scene needs.
    resolution
        (width, height) replacing the scene camera's, for brdflab's runs and the renders alike (quick checks).
    where_spp
        Samples per pixel of the auxiliary renders that say where and what for a biased render (0: off;
        :mod:`brdflab.stats.attribution`); the result's ``attribution`` holds it.
    cluster
        A :class:`brdflab.cluster.Cluster`, or its address (``"local:2"``, ``"tcp://host:8786"``), to run
        brdflab's runs on (one job each).

    Returns
    -------
    CheckResult
        ``consistent``, ``p_value``, ``bias`` with its interval, the block maps; ``to_dict()`` is ``check.json``.

    Examples
    --------
    >>> import brdflab as bl
    >>> scene = "scenes/cbox/cbox_diffuse.xml"
    >>> mine = bl.render(bl.load_scene(scene, width=32, height=24), spp=8, seed=11, workers=1)
    >>> res = bl.check(mine, scene, spp=8, runs=2, user_spp=8, block=8, levels=1, resolution=(32, 24), workers=1)
    >>> res.consistent, res.to_dict()["verdict"].split(":")[0]
    (True, 'consistent')
    """
    from brdflab.cluster import open_cluster
    from brdflab.errors import clean
    from brdflab.outputs import prepare_folder, record_outputs
    from brdflab.pages.check_page import CHECK_FILES, write_check
    from brdflab.scene.loader import load_scene
    from brdflab.stats.attribution import attribute_check
    from brdflab.stats.jobs import make_integrator
    from brdflab.stats.render_check import check_inputs, run_check

    if spp < 1 or runs < 1:
        raise BrdflabError("spp and runs must be at least 1")
    if isinstance(where_spp, bool) or not isinstance(where_spp, int | np.integer) or where_spp < 0:
        raise BrdflabError(f"where_spp must be a whole number ≥ 0 (0: no attribution), got {clean(where_spp, 30)}")
    if block < 2:
        raise BrdflabError("block must be at least 2 pixels")
    if not 0 < alpha < 1:
        raise BrdflabError(f"alpha must be in (0, 1), got {alpha}")
    if ref_var is not None and ref is None:
        raise BrdflabError("--ref-var needs --ref")
    _load_plugins(plugins)
    scene = Path(scene)
    sc = load_scene(scene)
    integrator, estimate_note = estimate_integrator(sc, integrator)
    make_integrator(integrator)
    items = list(renders) if isinstance(renders, list | tuple) else [renders]
    images = [_image(r, f"render {i + 1}") for i, r in enumerate(items)]
    ref_img = None if ref is None else _image(ref, "ref")
    var_img = None if ref_var is None else _image(ref_var, "ref_var")
    names = [clean(p, 80) if isinstance(p, str | Path) else f"render {i + 1}" for i, p in enumerate(items)]
    check_inputs(images, var_img, user_spp, names, block, ref_img)
    paths = [Path(p) if isinstance(p, str | Path) else Path(f"render_{i + 1}") for i, p in enumerate(items)]
    if output is not None:
        inputs = [*(p for p in items if isinstance(p, str | Path)), scene, *sc.inputs,
                  *(p for p in (ref, ref_var) if isinstance(p, str | Path))]
        prepare_folder(Path(output), list(CHECK_FILES), inputs, force)  # before the work, not after it
    w, h = resolution or (sc.camera.width, sc.camera.height)
    for what, img in [*zip(names, images, strict=True), ("ref", ref_img), ("ref_var", var_img)]:
        if img is not None and img.shape[:2] != (h, w):
            raise BrdflabError(f"{what}: image is {img.shape[1]}×{img.shape[0]} pixels, the scene renders {w}×{h}")
    first = items[0] if isinstance(items[0], str | Path) else None
    user_spp = user_spp or (_spp_attribute(Path(first)) if first is not None else None) or sc.spp
    say = progress or (lambda m: None)
    if ref_img is None:
        say(f"brdflab estimate: {runs} runs × {spp} spp of {integrator} at {w}×{h}")
        if estimate_note:
            say(estimate_note)
    # On a cluster each independent run is one job, rendered by one single-threaded worker (the scene is loaded
    # there from its path: a shared file system); the runs' seeds make the result placement-free.
    cluster, owned = open_cluster(cluster)  # an address ("local:2", "tcp://…") or a Cluster
    try:
        res = run_check(images, scene, integrator, spp, runs, seed, ref_img, var_img, block, alpha,
                        1 if cluster else workers, progress=say, user_spp=user_spp, resolution=resolution,
                        map_fn=map if cluster is None else cluster.imap, levels=levels)
    finally:
        if owned:
            cluster.close()
    res.estimate_integrator = integrator if ref_img is None else ""
    res.estimate_note = estimate_note if ref_img is None else ""
    res.attribution = attribute_check(res, images, scene, integrator, seed, where_spp, workers, say)
    if output is not None:
        write_check(Path(output), paths, images, res, scene, attribution=res.attribution)
        record_outputs(Path(output), list(CHECK_FILES))
    return res


def _spp_attribute(path: Path) -> int | None:
    """The ``brdflab_spp`` header attribute of an EXR written by brdflab, if any."""
    from brdflab.imageio import read_exr_header

    try:
        return int(read_exr_header(path).get("brdflab_spp", 0)) or None
    except (ValueError, TypeError, BrdflabError):
        return None


@dataclass
class Comparison:
    """Error metrics of an image against a reference (what ``brdflab compare --json`` prints)."""

    mse: float
    rmse: float
    relmse: float
    mape: float
    bias: float
    flip: float | None
    per_channel: dict
    nonfinite: int
    pixels: int

    def to_dict(self) -> dict:
        """Plain-dict form, JSON-safe (a non-finite number becomes None)."""
        def clean(v):
            if isinstance(v, dict):
                return {k: clean(x) for k, x in v.items()}
            return None if isinstance(v, float) and not math.isfinite(v) else v

        return clean(asdict(self))


def compare(test, reference, *, flip: bool = True, crop: tuple[int, int, int, int] | None = None) -> Comparison:
    """MSE, RMSE, relative MSE, MAPE, relative bias of the mean and HDR-FLIP of ``test`` against ``reference``
    (``brdflab compare``; definitions in :mod:`brdflab.pages.metrics`).

    Parameters
    ----------
    test, reference
        Arrays (H, W, C) or EXR paths.
    flip
        Also compute HDR-FLIP (NVIDIA ``flip-evaluator``; exposure range from the reference).
    crop
        (x, y, width, height): measure only this region (pixels, origin top left).

    Examples
    --------
    >>> import numpy as np, brdflab as bl
    >>> ref = np.full((8, 8, 3), 0.5)
    >>> m = bl.compare(ref * 1.1, ref, flip=False)
    >>> round(m.bias, 6), round(m.relmse, 6)
    (0.1, 0.009615)
    """
    from brdflab.pages.metrics import compare as _compare
    from brdflab.pages.metrics import crop as _crop
    from brdflab.pages.metrics import flip_error

    t, r = _image(test, "test"), _image(reference, "reference")
    if crop is not None:
        t, r = _crop(t, crop), _crop(r, crop)
    m = _compare(t, r)
    f = flip_error(t, r) if flip else None
    return Comparison(m.mse, m.rmse, m.relmse, m.mape, m.bias, f, m.per_channel, m.nonfinite, m.pixels)


def report(scene: str | Path, integrators: Sequence[str] = ("direct_ems", "direct_mats", "direct_mis"), *,
           spp: Sequence[int] = (1, 4, 16, 64, 256), runs: int = 4, ref: str | Path | None = None,
           ref_spp: int | None = None, seed: int = 0, workers: int | None = None,
           resolution: tuple[int, int] | None = None, flip: bool = True, mis_weights: bool = True,
           output: str | Path | None = None,
           plugins: Sequence[str] | str | None = None, progress: Callable[[str], None] | None = None,
           force: bool = False, cluster=None):
    """Compare integrators on one scene: error against samples and time, with intervals (``brdflab report``).

    Without ``ref`` the reference is rendered by brdflab's ``direct_mis`` (``path_mis`` when a path tracer is
    compared) at ``ref_spp`` with its own seeds,
    independent of the compared runs; the report says so (the MIS row's bias is then measured against the
    same estimator and cannot show a bias of MIS itself — give ``ref`` for that).

    Returns
    -------
    Study
        Rows per integrator and spp (relMSE, time, confidence intervals); ``output`` also gets ``report.html``.

    Examples
    --------
    >>> import brdflab as bl
    >>> st = bl.report("scenes/cbox/cbox_diffuse.xml", ["direct_ems", "direct_mats"], spp=[2], runs=2,
    ...                ref_spp=8, resolution=(24, 18), workers=1, flip=False, mis_weights=False)
    >>> sorted({row.integrator for row in st.rows}), st.reference_integrator
    (['direct_ems', 'direct_mats'], 'direct_mis')
    """
    from brdflab.pages.variance import run_study
    from brdflab.pages.variance_page import write_report
    from brdflab.stats.jobs import validate_specs

    _load_plugins(plugins)
    names = validate_specs(list(integrators))
    if not names or len(set(names)) != len(names):
        raise BrdflabError("integrators: give each integrator once")
    if not spp or min(spp) < 1 or runs < 1:
        raise BrdflabError("spp values and runs must be at least 1")
    files: list[str] = []
    if output is not None:
        from brdflab.outputs import prepare_folder
        from brdflab.pages.variance import REPORT_PATTERNS

        stem = Path(scene).stem
        files = ["report.html", f"{stem}_reference.png", *REPORT_PATTERNS, f"{stem}_*.png", f"{stem}_*.exr"]
        prepare_folder(Path(output), files, [scene, *([ref] if ref else []), *_specs(plugins)], force)
    study = run_study(Path(scene), names, list(spp), Path(ref) if ref else None, ref_spp, workers, seed,
                      progress=progress, runs=runs, resolution=resolution, flip=flip, mis_weights=mis_weights,
                      cluster=cluster)
    if output is not None:
        from brdflab.outputs import record_outputs

        write_report(study, Path(output))
        record_outputs(Path(output), files)
    return study


@dataclass
class PlotResult:
    """What ``plot`` drew: the page, and per view its files and data (the CSV columns)."""

    page: Path | None
    views: list

    def to_dict(self) -> dict:
        """Plain-dict form."""
        return {"page": str(self.page) if self.page else None, "views": self.views}


def plot(bsdfs, output: str | Path, *, theta: float = 45.0, phi_d: float = 90.0, cos: bool | None = None,
         views: Sequence[str] = ("polar", "lobe", "slice", "albedo", "sphere"), samples: int = 20_000,
         size: int | None = None, spp: int | None = None, workers: int | None = None,
         labels: Sequence[str] | None = None, plugins: Sequence[str] | str | None = None,
         progress: Callable[[str], None] | None = None, force: bool = False, times_cos: bool = False,
         sphere_size: int = 128, sphere_spp: int = 16) -> PlotResult:
    """Draw one BSDF or several overlaid: polar slice, 3D lobe, θh×θd slice, albedo, lit spheres (``brdflab plot``).

    Parameters
    ----------
    bsdfs
        A BSDF object, a ``--bsdf`` text (``"roughconductor:alpha=0.1"``) or a list of either.
    output, force
        The folder for ``index.html`` and each view as PNG, SVG and CSV, checked before the work (never an input,
        never a file brdflab did not write unless ``force``).
    cos, size, spp
        The command line's ``--cos`` (polar plot of f·cos θ_o), ``--size`` and ``--spp`` (the lit spheres'
        resolution and samples per pixel); ``times_cos``, ``sphere_size`` and ``sphere_spp`` are their older names.

    Examples
    --------
    >>> import tempfile, brdflab as bl
    >>> out = tempfile.mkdtemp()
    >>> res = bl.plot(["roughconductor:alpha=0.2", bl.Diffuse()], out, views=["polar"])
    >>> res.page.name
    'index.html'
    """
    from brdflab.outputs import prepare_folder, record_outputs
    from brdflab.viz import spec as bspec
    from brdflab.viz.static import VIEWS, PlotOptions, check_plot_work, plot_files, write_plots

    _load_plugins(plugins)
    if not (math.isfinite(theta) and 0 <= theta < 90):
        raise BrdflabError(f"theta must be in [0, 90) degrees, got {theta:g}")
    bad = [v for v in views if v not in VIEWS]
    if bad or not views:
        raise BrdflabError(f"views: unknown view '{str((bad or [''])[0])[:40]}'; valid: {', '.join(VIEWS)}")
    items = bsdfs if isinstance(bsdfs, list | tuple) else [bsdfs]
    objs, names = [], []
    for item in items:
        if isinstance(item, str):
            s = bspec.resolve([item])[0]
            objs.append(bspec.build(s))
            names.append(s.label)
        else:
            from brdflab.builtin_types import is_builtin_class
            from brdflab.judges.core.guard import CheckedBSDF, SceneCheckedBSDF

            # a user's object is checked on every call, as the command checks plugins: NaN is an error, not f = 0
            wrap = not isinstance(item, CheckedBSDF) and not is_builtin_class(type(item))
            objs.append(SceneCheckedBSDF(item) if wrap else item)
            names.append(getattr(item, "type_name", "") or type(item).__name__)
    opts = PlotOptions(theta=theta, phi_d=phi_d, times_cos=times_cos if cos is None else cos, views=tuple(views),
                       samples=samples, sphere_size=sphere_size if size is None else size,
                       sphere_spp=sphere_spp if spp is None else spp, workers=workers)
    files = plot_files(tuple(views), len(objs))
    check_plot_work(opts, len(objs))
    prepare_folder(Path(output), files, [p for p in _specs(plugins)], force)  # before the work
    page = write_plots(objs, list(labels or names), Path(output), opts, progress=progress)
    record_outputs(Path(output), files)
    return PlotResult(Path(page), [str(v) for v in views])


def validate(bsdfs=None, *, samples: int = 200_000, alphas: Sequence[float] | None = None,
             thetas: Sequence[float] | None = None, params: dict | None = None, output: str | Path | None = None,
             plugins: Sequence[str] | str | None = None, progress: Callable[[str], None] | None = None,
             force: bool = False, cluster=None, furnace_render: str | None = None):
    """Run the validation battery (``brdflab validate``): chi-square, consistency, furnace, stability.

    Parameters
    ----------
    bsdfs
        None for everything built in (every warp and BSDF, the negative control, the light-transport checks),
        or BSDF names, instances or classes (a plugin's): the whole battery on those only.
    samples
        Samples per chi-square test.
    output, force
        A folder for the HTML report, checked before the work (``force`` replaces files brdflab did not write).
    cluster
        A :class:`brdflab.cluster.Cluster` to run the chi-square tests and consistency checks on.
    furnace_render
        The white furnace under path tracing for the page (``quick``, ``normal``, ``full``: sphere size and spp
        from :data:`brdflab.viz.white_furnace.LEVELS`; ``off``: none): a sphere of each BSDF judged, at its
        furnace parameters and α, in a uniform white environment (``Battery.white_furnace``; display only).
        Default: ``normal`` when ``output`` writes a page, else ``off`` (no page, no picture to render).

    Returns
    -------
    Battery
        ``passed``, ``failures()`` and every result; ``output`` also gets ``index.html`` (and ``furnace.png``,
        ``furnace.csv``).

    Examples
    --------
    >>> import brdflab as bl
    >>> bat = bl.validate(["diffuse"], samples=5_000, thetas=[30])
    >>> bat.passed
    True
    """
    from brdflab.judges.material.battery import ALPHAS, THETAS, run_battery

    _load_plugins(plugins)
    if samples < 1000:
        raise BrdflabError(f"samples must be at least 1000, got {samples}")
    from brdflab.errors import clean
    from brdflab.viz.white_furnace import LEVELS, battery_furnace

    if furnace_render is None:
        furnace_render = "normal" if output is not None else "off"
    if furnace_render != "off" and furnace_render not in LEVELS:
        raise BrdflabError(f"furnace_render: expected off, {', '.join(LEVELS)}; got {clean(furnace_render)}")
    kwargs: dict = {}
    if bsdfs is not None:
        kwargs = {"bsdfs": bsdfs if isinstance(bsdfs, list | tuple) else [bsdfs], "warp_names": [],
                  "alphas": tuple(alphas or ALPHAS), "thetas": tuple(thetas or THETAS), "params": params}
    elif params or alphas or thetas:
        raise BrdflabError("params, alphas and thetas need bsdfs")
    if output is not None:
        from brdflab.outputs import prepare_folder
        from brdflab.pages.validation import VALIDATION_FILES

        prepare_folder(Path(output), list(VALIDATION_FILES), _specs(plugins), force)  # before the work
    bat = run_battery(n=samples, progress=progress, cluster=cluster, **kwargs)
    if furnace_render != "off":
        bat.white_furnace = battery_furnace(kwargs.get("bsdfs"), params, furnace_render, progress=progress)
    if output is not None:
        from brdflab.outputs import record_outputs
        from brdflab.pages.validation import write_validation_report

        write_validation_report(bat, Path(output))
        record_outputs(Path(output), list(VALIDATION_FILES))
    return bat
