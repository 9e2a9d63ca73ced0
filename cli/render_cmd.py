"""``brdflab render SCENE.xml``: render a Nori scene to EXR + PNG."""

from __future__ import annotations

import argparse
import signal
import sys
import time
import warnings
from pathlib import Path

from brdflab.cli.argtypes import count, seconds, seed
from brdflab.cli.cluster_options import add_cluster_options, cluster_from_args
from brdflab.cli.progress import Progress
from brdflab.cli.signals import GracefulStop, exit_status
from brdflab.errors import MESSAGE_CHARS, BrdflabError, Interrupted, clean

from .options import add_force_option, add_plugin_option, load_plugins


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``render`` sub-command."""
    from brdflab.renderer import MAX_WORKERS

    p = sub.add_parser("render", help="render a Nori scene to EXR + PNG",
                       description="Render a Nori scene file. Output: <stem>.exr and <stem>.png beside the "
                       "scene (or -o), or <stem>_<spp>spp.exr/.png in --figures DIR. Interrupted (Ctrl-C, "
                       "SIGTERM, SIGHUP): the completed passes are written as <stem>_partial_<N>spp.exr/.png "
                       "and the exit status is 130/143/129; a second signal aborts at once.")
    p.add_argument("scene", type=Path, help="Nori scene XML file")
    p.add_argument("--spp", type=count(1), help="samples per pixel (default: the scene's sampleCount)")
    p.add_argument("--seed", type=seed, help="random seed in [0, 2^64) (default: the scene's seed, else 0)")
    p.add_argument("--workers", type=count(1, MAX_WORKERS), help="worker processes (default: all cores)")
    p.add_argument("--integrator", help="override the scene's integrator (normals, direct_ems, direct_mats, "
                   "direct_mis, direct_whitted, path, path_nee, path_mis)")
    p.add_argument("--emitter-selection", choices=("uniform", "power"), default="uniform",
                   help="how to pick the emitter to sample (default: uniform, as Nori)")
    p.add_argument("-o", "--output", type=Path, help="output EXR path (the PNG is written beside it)")
    p.add_argument("--figures", type=Path, metavar="DIR",
                   help="write <stem>_<spp>spp.exr/.png into DIR instead")
    p.add_argument("--time-limit", type=seconds, metavar="SECONDS",
                   help="render as many full passes as fit in this time (a number > 0)")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    add_force_option(p, "an existing EXR/PNG")
    add_plugin_option(p)
    add_cluster_options(p, scene_transfer=True)
    p.set_defaults(func=run)


def output_paths(scene_path: Path, output: Path | None, figures: Path | None, spp: int,
                 partial: bool = False) -> tuple[Path, Path]:
    """The EXR and PNG paths for a render of ``scene_path`` at ``spp`` (``partial``: an interrupted render,
    named ``<stem>_partial_<spp>spp``)."""
    if figures is not None:
        exr = figures / f"{scene_path.stem}_{'partial_' if partial else ''}{spp}spp.exr"
    else:
        if output is not None:
            exr = output if output.suffix.lower() == ".exr" else output.with_suffix(".exr")
        else:
            exr = scene_path.with_suffix(".exr")
        if partial:
            exr = exr.with_name(f"{exr.stem}_partial_{spp}spp.exr")
    return exr, exr.with_suffix(".png")


def run(args: argparse.Namespace) -> int:
    """Load, render and write the images."""
    from brdflab.cluster import ClusterError
    from brdflab.imageio import write_images
    from brdflab.kernels import preload
    from brdflab.outputs import check_outputs, output_folder, prepare_files
    from brdflab.renderer import render
    from brdflab.scene.loader import load_scene
    from brdflab.timing import fixed_costs_line, process_seconds

    startup_s = process_seconds()
    t_run = time.perf_counter()

    load_plugins(args)
    if args.figures is not None:
        output_folder(args.figures, "--figures")
    elif args.output is not None and args.output.is_dir():
        raise BrdflabError(f"-o '{clean(args.output, 100)}' is a folder; expected an EXR file name "
                           "(use --figures DIR to write into a folder)")
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = load_scene(args.scene, args.integrator)
    for w in caught:
        print(f"brdflab: warning: {clean(w.message, MESSAGE_CHARS)}", file=sys.stderr)
    scene.set_emitter_selection(args.emitter_selection)
    load_s = time.perf_counter() - t0
    spp = args.spp or scene.spp
    cam = scene.camera
    # Refuse before rendering: every name this run could write (complete or partial) against every input.
    check_outputs([*output_paths(args.scene, args.output, args.figures, spp),
                      *output_paths(args.scene, args.output, args.figures, 1, partial=True)], scene.inputs)
    prepare_files(output_paths(args.scene, args.output, args.figures, spp), scene.inputs,
                  getattr(args, "force", False), "--figures" if args.figures is not None else "-o")
    if not args.quiet:
        print(f"{clean(args.scene, 120)}: {cam.width}×{cam.height}, {spp} spp, {scene.integrator_type}, "
              f"{scene.geometry.triangle_count:,} triangles, {len(scene.emitters)} emitters "
              f"(loaded in {load_s:.2f} s)", file=sys.stderr)

    failure = per_worker = None
    if args.cluster is None:
        # The engine is decided (and a first build waited for, when --engine numba asks for it) before the
        # render's graceful handling of signals: a Ctrl-C during that wait stops the build at once.
        preload()
    with GracefulStop() as graceful:
        progress = Progress("rendering", spp * cam.width * cam.height, spp, args.time_limit, quiet=args.quiet)
        try:
            with cluster_from_args(args, quiet=args.quiet) as cluster:
                try:
                    image, stats = render(scene, spp=spp, seed=args.seed, workers=args.workers, progress=progress,
                                          stop=graceful.stop, time_limit=args.time_limit, cluster=cluster)
                except ClusterError as exc:
                    if exc.image is None:
                        raise ClusterError(f"{exc}; no pass had completed, no image written") from None
                    image, stats, failure = exc.image, exc.stats, exc
                if cluster is not None and not args.quiet:
                    per_worker = cluster.summary()
        finally:
            progress.close(complete=not graceful.stop.is_set())
        if stats.spp == 0:
            raise Interrupted(graceful.signum or signal.SIGINT,
                              "interrupted before the first pass finished; no image written")
        partial = (graceful.stop.is_set() or failure is not None) and stats.spp < spp
        exr, png = output_paths(args.scene, args.output, args.figures, stats.spp, partial)
        check_outputs([exr, png], scene.inputs)
        write_s = write_images(exr, png, image, extra={"brdflab_spp": str(stats.spp),
                                                       "brdflab_integrator": scene.integrator_type,
                                                       "brdflab_seconds": f"{stats.seconds:.3f}"})
    if failure is not None:
        print(f"brdflab: error: {failure}; wrote the {stats.spp} completed spp to {clean(exr, 120)}", file=sys.stderr)
        return 1
    if not args.quiet:
        print(stats.summary(), file=sys.stderr)
        if per_worker:
            print("\n".join(per_worker), file=sys.stderr)
        # The whole run by the wall clock: the process's own age (process_seconds) can fall back to its CPU
        # time, which leaves out the render when workers did it.
        whole_s = startup_s + time.perf_counter() - t_run
        print("  " + fixed_costs_line(startup_s, scene.timings, write_s, whole_s), file=sys.stderr)
        print(f"wrote {clean(exr, 120)} and {clean(png.name, 120)}", file=sys.stderr)
    return exit_status(graceful.signum) if graceful.signum else 0
