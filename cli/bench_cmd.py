"""``brdflab bench``: speed benchmarks (samples/s, rays/s, Embree share, load time, peak memory)."""

from __future__ import annotations

import argparse
from pathlib import Path

from brdflab.errors import BrdflabError


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``bench`` sub-command."""
    from brdflab.bench import CASES

    p = sub.add_parser("bench", help="speed benchmarks of the fixed bench scenes",
                       description="Each case runs in a fresh process; reports medians and spread over --runs.")
    p.add_argument("cases", nargs="*", default=list(CASES), help=f"cases (default: all of {', '.join(CASES)})")
    p.add_argument("--spp", type=int, default=16)
    p.add_argument("--runs", type=int, default=3)
    p.add_argument("--workers", type=int)
    p.add_argument("--json", type=Path, default=Path("benchmarks/results/latest.json"),
                   help="where to write the JSON records (default: benchmarks/results/latest.json)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the benchmarks."""
    from brdflab.bench import CASES, run_suite

    for c in args.cases:
        if c not in CASES:
            raise BrdflabError(f"unknown bench case '{c}'; valid: {', '.join(CASES)}")
    run_suite(args.cases, args.spp, args.runs, args.workers, args.json)
    print(f"wrote {args.json}")
    return 0
