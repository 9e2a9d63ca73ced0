"""``brdflab chi2 --bsdf NAME`` / ``--warp NAME``: chi-square tests of one sampling routine."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from brdflab.cli.argtypes import count
from brdflab.outputs import DEFAULT_REPORTS, index_root, output_folder

from .cluster_options import add_cluster_options, cluster_from_args
from .options import add_bsdf_options, bsdf_spec_from_args, load_plugins


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``chi2`` sub-command."""
    from brdflab.validate.battery import POINT_WARPS, WARPS

    p = sub.add_parser("chi2", help="chi-square goodness of fit of a BSDF or warp sampler, with an HTML report",
                       description="Samples directions, histograms them on the sphere about the lobe axis, integrates "
                       "the pdf over every bin and applies Pearson's test (Šidák-corrected for the number of tests). "
                       "Without --alpha/--theta it sweeps α ∈ {1e-3, 0.005, 0.05, 0.1, 0.3, 0.5, 1} (BSDFs with an "
                       "alpha parameter) and θ ∈ {0, 30, 60, 80, 89}°. Exit status 1 if a test fails.")
    add_bsdf_options(p)
    p.add_argument("--warp", choices=list(WARPS) + list(POINT_WARPS), help="test a warp instead of a BSDF")
    p.add_argument("--samples", type=count(1000), default=100_000,
                   help="samples per test, at least 1000 (default 100000)")
    p.add_argument("--full", action="store_true", help="also consistency, furnace and stability checks")
    p.add_argument("-o", "--output", type=Path, help="report folder (default: reports/chi2_<name>)")
    add_cluster_options(p)
    p.set_defaults(func=run, parser=p)


def run(args: argparse.Namespace) -> int:
    """Run the tests and write the report."""
    from brdflab.errors import BrdflabError
    from brdflab.report.index import write_index
    from brdflab.report.validation import write_validation_report
    from brdflab.validate.battery import ALPHAS, THETAS, run_battery

    if (args.bsdf is None) == (args.warp is None):
        raise BrdflabError("chi2 needs exactly one of --bsdf NAME or --warp NAME")
    load_plugins(args)
    params: dict = {}
    if args.bsdf:
        name, params, alphas, thetas = bsdf_spec_from_args(args, args.bsdf)
    else:
        name, alphas, thetas = args.warp, args.alpha, args.theta
        if args.param:
            raise BrdflabError("--param applies to --bsdf, not to --warp")
    with cluster_from_args(args) as cluster:
        bat = run_battery(n=args.samples, bsdfs=[name] if args.bsdf else [],
                          warp_names=[name] if args.warp else [], alphas=tuple(alphas or ALPHAS),
                          thetas=tuple(thetas or THETAS), params=params, full=args.full, progress=print,
                          cluster=cluster)
    out = args.output or DEFAULT_REPORTS / f"chi2_{name.replace('/', '_')}"
    parent_created = output_folder(out.parent) if args.output else False
    output_folder(out)
    path = write_validation_report(bat, out, title=f"brdflab chi-square: {name}")
    root = index_root(out, args.output is not None, parent_created)
    if root is not None:
        write_index(root)
    print(("ALL PASSED" if bat.passed else f"{len(bat.failures())} FAILURES") + f"; report: {path}")
    for f in bat.failures():
        print("  " + f, file=sys.stderr)
    return 0 if bat.passed else 1
