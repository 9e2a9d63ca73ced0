"""``brdflab report SCENE.xml``: variance comparison of the integrators, error against run time."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from brdflab.cli.argtypes import count, resolution, seed
from brdflab.errors import BrdflabError, clean
from brdflab.outputs import DEFAULT_REPORTS, index_root, output_folder

from .cluster_options import add_cluster_options, cluster_from_args
from .options import add_force_option, add_plugin_option, load_plugins


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``report`` sub-command."""
    from brdflab.renderer import MAX_WORKERS

    p = sub.add_parser("report", help="compare integrators: error against run time, HTML report",
                       description="Render SCENE with each integrator progressively up to the largest spp, measure "
                       "the error of every checkpoint against a reference, and write CSV/JSON, plots, figures "
                       "and a self-contained report.html.")
    p.add_argument("scene", type=Path, help="Nori scene XML file")
    p.add_argument("--integrators", default="direct_ems,direct_mats,direct_mis",
                   help="comma-separated integrators, NAME or NAME:VARIANT (default: direct_ems,direct_mats,"
                   "direct_mis; e.g. direct_mis,direct_mis:power compares the balance and power heuristics)")
    p.add_argument("--spp", default="1,4,16,64,256", help="comma-separated sample counts (default: 1,4,16,64,256)")
    p.add_argument("--ref", type=Path, help="reference EXR (default: a high-spp direct_mis render made first)")
    p.add_argument("--runs", type=count(1), default=4, help="independent runs (seeds) per integrator "
                   "(default 4); intervals, speed-ups and bias flags come from their spread")
    p.add_argument("--ref-spp", type=count(1), help="spp of each of the 4 runs of the self-made reference "
                   "(default: 4 × the largest spp, 16 × in total)")
    p.add_argument("--resolution", metavar="WxH", type=resolution,
                   help="render at this size instead of the camera's")
    p.add_argument("--no-flip", action="store_true", help="skip HDR-FLIP")
    p.add_argument("--no-mis-weights", action="store_true", help="skip the MIS weight images")
    p.add_argument("--workers", type=count(1, MAX_WORKERS), help="worker processes (default: all cores)")
    p.add_argument("--seed", type=seed, default=0, help="random seed in [0, 2^64) (default 0)")
    p.add_argument("-o", "--output", type=Path, help="output folder (default: reports/<stem>/)")
    add_force_option(p, "files in the output folder")
    add_plugin_option(p)
    add_cluster_options(p, scene_transfer=True)
    p.set_defaults(func=run)


def _ints(text: str, what: str) -> list[int]:
    try:
        values = [int(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise BrdflabError(f"{what}: expected comma-separated integers, got '{clean(text)}'") from None
    if not values or min(values) < 1:
        raise BrdflabError(f"{what}: sample counts must be positive, got '{clean(text)}'")
    return values


def run(args: argparse.Namespace) -> int:
    """Run the study and write the report."""
    from brdflab.pages.index import write_index
    from brdflab.pages.variance_summary import summary
    from brdflab.stats.jobs import validate_specs
    from brdflab.workflows import report

    load_plugins(args)
    integrators = validate_specs(args.integrators.split(","))
    if not integrators:
        raise BrdflabError("--integrators: no integrator given")
    if len(set(integrators)) != len(integrators):
        raise BrdflabError(f"--integrators: '{clean(args.integrators, 80)}' names an integrator twice")
    spp = _ints(args.spp, "--spp")
    resolution = args.resolution
    out = args.output or DEFAULT_REPORTS / args.scene.stem
    parent_created = output_folder(out.parent) if args.output else False
    with cluster_from_args(args) as cluster:
        study = report(args.scene, integrators, spp=spp, runs=args.runs, ref=args.ref, ref_spp=args.ref_spp,
                       seed=args.seed, workers=args.workers, resolution=resolution, flip=not args.no_flip,
                       mis_weights=not args.no_mis_weights, output=out, force=args.force, plugins=args.plugin,
                       progress=lambda msg: print(msg, file=sys.stderr), cluster=cluster)
    path = out / "report.html"
    root = index_root(out, args.output is not None, parent_created)
    if root is not None:
        write_index(root)
    for line in summary(study):
        print(line)
    print(f"wrote {path}", file=sys.stderr)
    return 0
