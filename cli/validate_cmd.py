"""``brdflab validate``: the whole validation battery with an HTML report."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``validate`` sub-command."""
    p = sub.add_parser("validate", help="run every chi-square, consistency, furnace and stability check",
                       description="All warps and BSDFs over α ∈ {1e-3 … 1} and θ_i ∈ {0 … 89°}; console verdicts "
                       "and an HTML report. Exit status 1 if anything fails.")
    p.add_argument("--samples", type=int, default=200_000, help="samples per chi-square test (default 200000)")
    p.add_argument("-o", "--output", type=Path, default=Path("reports/validation"))
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the battery and write the report."""
    from brdflab.report.index import write_index
    from brdflab.report.validation import write_validation_report
    from brdflab.validate.battery import run_battery

    bat = run_battery(n=args.samples, progress=print)
    path = write_validation_report(bat, args.output)
    write_index(args.output.parent)
    print(("ALL PASSED" if bat.passed else f"{len(bat.failures())} FAILURES") + f"; report: {path}")
    for f in bat.failures():
        print("  " + f, file=sys.stderr)
    return 0 if bat.passed else 1
