"""``brdflab render SCENE.xml``: render a Nori scene to EXR + PNG."""

from __future__ import annotations

import argparse
import signal
import sys
import threading
import time
import warnings
from pathlib import Path

from brdflab.cli.cluster_options import add_cluster_options, cluster_from_args
from brdflab.errors import BrdflabError

from .options import add_plugin_option, load_plugins


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``render`` sub-command."""
    p = sub.add_parser("render", help="render a Nori scene to EXR + PNG",
                       description="Render a Nori scene file. Output: <stem>.exr and <stem>.png beside the "
                       "scene (or -o), or <stem>_<spp>spp.exr/.png in --figures DIR.")
    p.add_argument("scene", type=Path, help="Nori scene XML file")
    p.add_argument("--spp", type=int, help="samples per pixel (default: the scene's sampleCount)")
    p.add_argument("--seed", type=int, help="random seed (default: the scene's seed, else 0)")
    p.add_argument("--workers", type=int, help="worker processes (default: all cores)")
    p.add_argument("--integrator", help="override the scene's integrator (normals, direct_ems, direct_mats, "
                   "direct_mis, direct_whitted)")
    p.add_argument("--emitter-selection", choices=("uniform", "power"), default="uniform",
                   help="how to pick the emitter to sample (default: uniform, as Nori)")
    p.add_argument("-o", "--output", type=Path, help="output EXR path (the PNG is written beside it)")
    p.add_argument("--figures", type=Path, metavar="DIR",
                   help="write <stem>_<spp>spp.exr/.png into DIR instead")
    p.add_argument("--time-limit", type=float, metavar="SECONDS",
                   help="render as many full passes as fit in this time")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    add_plugin_option(p)
    add_cluster_options(p, scene_transfer=True)
    p.set_defaults(func=run)


class Progress:
    """A progress bar with ETA on a terminal; plain periodic lines otherwise."""

    def __init__(self, label: str, stream=None, quiet: bool = False) -> None:
        self.label = label
        self.stream = stream if stream is not None else sys.stderr
        self.quiet = quiet
        self.tty = self.stream.isatty()
        self.t0 = time.perf_counter()
        self.last = -1.0

    def __call__(self, frac: float, stats) -> None:
        if self.quiet:
            return
        now = time.perf_counter() - self.t0
        eta = now * (1 - frac) / frac if frac > 0 else 0.0
        if self.tty:
            if now - self.last < 0.1 and frac < 1:
                return
            width = 30
            fill = int(width * frac)
            bar = "█" * fill + "·" * (width - fill)
            self.stream.write(f"\r{self.label} [{bar}] {100 * frac:5.1f}%  {now:6.1f}s elapsed, ETA {eta:6.1f}s ")
            if frac >= 1:
                self.stream.write("\n")
        else:
            if now - self.last < 5.0 and frac < 1:
                return
            self.stream.write(f"{self.label}: {100 * frac:.0f}% after {now:.1f}s, ETA {eta:.1f}s\n")
        self.stream.flush()
        self.last = now


def output_paths(scene_path: Path, output: Path | None, figures: Path | None, spp: int) -> tuple[Path, Path]:
    """The EXR and PNG paths for a render of ``scene_path`` at ``spp``."""
    if figures is not None:
        exr = figures / f"{scene_path.stem}_{spp}spp.exr"
    elif output is not None:
        exr = output if output.suffix.lower() == ".exr" else output.with_suffix(".exr")
    else:
        exr = scene_path.with_suffix(".exr")
    return exr, exr.with_suffix(".png")


def run(args: argparse.Namespace) -> int:
    """Load, render and write the images."""
    from brdflab.cluster import ClusterError
    from brdflab.imageio import write_images
    from brdflab.render import render
    from brdflab.scene.loader import load_scene
    from brdflab.timing import fixed_costs_line, process_seconds

    startup_s = process_seconds()

    if args.spp is not None and args.spp < 1:
        raise BrdflabError(f"--spp must be at least 1, got {args.spp}")
    if args.workers is not None and args.workers < 1:
        raise BrdflabError(f"--workers must be at least 1, got {args.workers}")
    load_plugins(args)
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = load_scene(args.scene, args.integrator)
    for w in caught:
        print(f"brdflab: warning: {w.message}", file=sys.stderr)
    scene.set_emitter_selection(args.emitter_selection)
    load_s = time.perf_counter() - t0
    spp = args.spp or scene.spp
    if not args.quiet:
        cam = scene.camera
        print(f"{args.scene}: {cam.width}×{cam.height}, {spp} spp, {scene.integrator_type}, "
              f"{scene.geometry.triangle_count:,} triangles, {len(scene.emitters)} emitters "
              f"(loaded in {load_s:.2f} s)", file=sys.stderr)

    stop = threading.Event()
    previous = signal.getsignal(signal.SIGINT)

    def on_sigint(signum, frame):
        if stop.is_set():
            raise KeyboardInterrupt
        stop.set()
        print("\nbrdflab: interrupted — saving the completed passes (Ctrl-C again to abort)", file=sys.stderr)

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, on_sigint)
    failure = None
    try:
        with cluster_from_args(args, quiet=args.quiet) as cluster:
            try:
                image, stats = render(scene, spp=spp, seed=args.seed, workers=args.workers,
                                      progress=Progress("rendering", quiet=args.quiet), stop=stop,
                                      time_limit=args.time_limit, cluster=cluster)
            except ClusterError as exc:
                if exc.image is None:
                    raise ClusterError(f"{exc}; no pass had completed, no image written") from None
                image, stats, failure = exc.image, exc.stats, exc
            if cluster is not None and not args.quiet:
                per_worker = cluster.summary()
    finally:
        if threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGINT, previous)
    if stats.spp == 0:
        raise BrdflabError("stopped before the first pass finished; no image written")
    interrupted = (stop.is_set() or failure is not None) and stats.spp < spp
    exr, png = output_paths(args.scene, args.output, args.figures, stats.spp)
    if interrupted and args.figures is None:
        exr = exr.with_name(f"{exr.stem}_partial_{stats.spp}spp.exr")
        png = exr.with_suffix(".png")
    write_s = write_images(exr, png, image, extra={"brdflab_spp": str(stats.spp),
                                                   "brdflab_integrator": scene.integrator_type,
                                                   "brdflab_seconds": f"{stats.seconds:.3f}"})
    if failure is not None:
        print(f"brdflab: error: {failure}; wrote the {stats.spp} completed spp to {exr}", file=sys.stderr)
        return 1
    if not args.quiet:
        print(stats.summary(), file=sys.stderr)
        if cluster is not None:
            print("\n".join(per_worker), file=sys.stderr)
        print("  " + fixed_costs_line(startup_s, scene.timings, write_s, process_seconds()), file=sys.stderr)
        print(f"wrote {exr} and {png}", file=sys.stderr)
    return 130 if interrupted else 0
