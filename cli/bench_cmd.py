"""``brdflab bench``: speed benchmarks (samples/s, rays/s, Embree share, load time, peak memory)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from brdflab.cli.argtypes import count

from .options import add_force_option, add_plugin_option


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``bench`` sub-command."""
    from brdflab.benchmarking import CASES
    from brdflab.renderer import MAX_WORKERS

    p = sub.add_parser("bench", help="speed benchmarks of the fixed bench scenes",
                       description="Each case runs in a fresh process; reports medians and spread over --runs.")
    p.add_argument("cases", nargs="*", default=list(CASES), help=f"cases (default: all of {', '.join(CASES)}); "
                   "or your own scene files (SCENE.xml, rendered with their own integrator)")
    p.add_argument("--spp", type=count(1), default=16, help="samples per pixel of each run (default 16)")
    p.add_argument("--runs", type=count(1), default=3, help="runs per case; medians are reported (default 3)")
    p.add_argument("--workers", type=count(1, MAX_WORKERS), help="worker processes (default: all cores)")
    p.add_argument("--json", type=Path, default=Path("benchmarks/results/latest.json"),
                   help="where to write the JSON records (default: benchmarks/results/latest.json)")
    add_force_option(p, "a --json file")
    add_plugin_option(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the benchmarks (:func:`brdflab.workflows_extra.bench`)."""
    from brdflab.workflows_extra import bench, bench_expected

    records = bench(args.cases, spp=args.spp, runs=args.runs, workers=args.workers, json=args.json, force=args.force,
                    plugins=args.plugin)
    if len(records) < bench_expected(args.cases):
        print(f"brdflab: error: {bench_expected(args.cases) - len(records)} bench run(s) failed", file=sys.stderr)
        return 1
    print(f"wrote {args.json}")
    return 0
