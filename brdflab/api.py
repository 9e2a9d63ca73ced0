"""Notebook-level entry points of the public API (:mod:`brdflab` re-exports them).

The command line and these functions share their code paths: ``brdflab render`` is
:func:`load_scene` + :func:`render` + :func:`brdflab.imageio.write_exr`.
"""

from __future__ import annotations

from pathlib import Path


def load_scene(path: str | Path, *, integrator: str | None = None, spp: int | None = None,
               seed: int | None = None, width: int | None = None, height: int | None = None,
               emitter_selection: str | None = None, plugins: list[str] | None = None):
    """Load a Nori scene file, optionally overriding some of its settings.

    Parameters
    ----------
    path
        The scene XML file.
    integrator
        Replace the integrator type (``"direct_ems"``, ``"direct_mats"``, ``"direct_mis"``, …).
    spp, seed
        Replace the sampler's ``sampleCount`` and ``seed`` (the defaults of :func:`render`).
    width, height
        Replace the image size (the horizontal field of view is kept).
    emitter_selection
        ``"uniform"`` (Nori's rule, default) or ``"power"``.
    plugins
        Plugin files or ``module:Class`` paths to load first (see :func:`brdflab.plugins.load_plugin`).

    Returns
    -------
    Scene
        The assembled scene (camera, materials, emitters, Embree geometry).

    Raises
    ------
    BrdflabError
        For invalid input, with file and line.

    Examples
    --------
    >>> import brdflab as bl
    >>> scene = bl.load_scene("scenes/cbox/cbox_diffuse.xml", width=64, height=48, spp=2)
    >>> (scene.camera.width, scene.camera.height, scene.spp, scene.integrator_type)
    (64, 48, 2, 'direct_ems')
    """
    from brdflab.plugins import load_plugins
    from brdflab.scene.loader import load_scene as _load

    load_plugins(plugins)
    return _load(path, integrator=integrator, spp=spp, seed=seed, width=width, height=height,
                 emitter_selection=emitter_selection)


def render(scene, spp: int | None = None, seed: int | None = None, workers: int | None = None, *,
           return_stats: bool = False, cluster=None, time_limit: float | None = None):
    """Render a loaded scene and return its image.

    Parameters
    ----------
    scene
        A scene from :func:`load_scene`.
    spp, seed
        Samples per pixel and seed (default: the scene's sampler). The same scene, ``spp`` and ``seed``
        give the same image for any number of workers.
    workers
        Worker processes (default: all cores; 1 renders in this process).
    return_stats
        Also return the :class:`brdflab.renderer.RenderStats` (time, samples/s, rays/s, Embree share).
    cluster
        Render on a Dask cluster instead: ``"tcp://host:8786"``, ``"local:4"`` or a
        :class:`brdflab.cluster.Cluster` (same image, see :mod:`brdflab.cluster`).
    time_limit
        Seconds: render as many full passes as fit (``--time-limit``); the stats say how many samples that was.

    Returns
    -------
    numpy.ndarray or (numpy.ndarray, RenderStats)
        The linear RGB image, shape (H, W, 3), float32; with ``return_stats`` a pair (image, stats).

    Examples
    --------
    >>> import brdflab as bl
    >>> scene = bl.load_scene("scenes/cbox/cbox_diffuse.xml", width=32, height=24)
    >>> img = bl.render(scene, spp=2, seed=1, workers=1)
    >>> img.shape, img.dtype
    ((24, 32, 3), dtype('float32'))
    >>> img, stats = bl.render(scene, spp=2, seed=1, workers=1, return_stats=True)
    >>> stats.spp
    2
    """
    from brdflab.renderer import render_image

    return render_image(scene, spp, seed, workers, return_stats=return_stats, cluster=cluster, time_limit=time_limit)
