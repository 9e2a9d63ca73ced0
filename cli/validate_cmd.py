"""``brdflab validate``: the whole validation battery with an HTML report."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from brdflab.cli.argtypes import count
from brdflab.outputs import DEFAULT_REPORTS, index_root, output_folder

from .cluster_options import add_cluster_options, cluster_from_args
from .options import add_bsdf_options, add_effort_option, add_force_option, bsdf_spec_from_args, load_plugins


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``validate`` sub-command."""
    p = sub.add_parser("validate", help="run every chi-square, consistency, furnace and stability check",
                       description="All warps and BSDFs over α ∈ {1e-3 … 1} and θ_i ∈ {0 … 89°}; console verdicts "
                       "and an HTML report. Exit status 1 if anything fails.")
    add_bsdf_options(p, repeat=True)
    p.add_argument("--samples", type=count(1000), default=200_000,
                   help="samples per chi-square test, at least 1000 (default 200000)")
    p.add_argument("-o", "--output", type=Path, help="report folder (default: reports/validation)")
    add_force_option(p, "files in the report folder")
    p.add_argument("--furnace-render", choices=("off", "quick", "normal", "full"), default=None,
                   help="the white furnace under path tracing on the page: a sphere of each BSDF judged in a "
                        "uniform white environment (quick 32² × 32 spp, normal 64² × 64, full 128² × 256 per "
                        "sphere; default: quick with --effort quick, else normal; off: none)")
    add_effort_option(p)
    add_cluster_options(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the battery (:func:`brdflab.workflows.validate`) and write the report."""
    from brdflab.errors import BrdflabError
    from brdflab.judges.core.failures import grouped_failures
    from brdflab.pages.index import write_index
    from brdflab.workflows import validate

    out = args.output or DEFAULT_REPORTS / "validation"
    parent_created = output_folder(out.parent) if args.output else False
    load_plugins(args)
    bsdfs, params = None, None
    if args.bsdf:  # the whole battery on these BSDFs only (no warps)
        specs = [bsdf_spec_from_args(args, name) for name in args.bsdf]
        if len(specs) > 1 and args.param:
            raise BrdflabError("--param applies to a single --bsdf")
        bsdfs, params = [s[0] for s in specs], specs[0][1]
    elif args.param or args.alpha or args.theta:
        raise BrdflabError("--param, --alpha and --theta need --bsdf NAME")
    with cluster_from_args(args) as cluster:
        bat = validate(bsdfs, samples=args.samples, alphas=args.alpha, thetas=args.theta, params=params, output=out,
                       force=args.force, plugins=args.plugin, progress=print, cluster=cluster,
                       furnace_render=args.furnace_render or ("quick" if args.effort == "quick" else "normal"))
    root = index_root(out, args.output is not None, parent_created)
    if root is not None:
        write_index(root)
    path = out / "index.html"
    grouped = [] if bat.passed else grouped_failures(bat)
    print(("ALL PASSED" if bat.passed else f"{len(bat.failures())} FAILURES, {len(grouped)} distinct (one line per "
           "cause below)") + f"; report: {path}")
    for f in grouped:
        print("  " + f, file=sys.stderr)
    return 0 if bat.passed else 1
