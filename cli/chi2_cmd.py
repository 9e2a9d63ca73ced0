"""``brdflab chi2 --bsdf NAME`` / ``--warp NAME``: chi-square tests of one sampling routine."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from brdflab.errors import BrdflabError


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``chi2`` sub-command."""
    from brdflab.validate.battery import BSDFS, POINT_WARPS, WARPS

    p = sub.add_parser("chi2", help="chi-square goodness of fit of a BSDF or warp sampler, with an HTML report",
                       description="Samples directions, histograms them on the sphere about the lobe axis, integrates "
                       "the pdf over every bin and applies Pearson's test (Šidák-corrected for the number of tests). "
                       "Without --alpha/--theta it sweeps α ∈ {1e-3, 0.005, 0.05, 0.1, 0.3, 0.5, 1} and "
                       "θ ∈ {0, 30, 60, 80, 89}°. Exit status 1 if a test fails.")
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--bsdf", choices=list(BSDFS))
    g.add_argument("--warp", choices=list(WARPS) + list(POINT_WARPS))
    p.add_argument("--alpha", type=float, action="append", help="roughness (repeatable)")
    p.add_argument("--theta", type=float, action="append", help="incident angle in degrees (repeatable)")
    p.add_argument("--param", action="append", default=[], metavar="K=V",
                   help="material parameter, e.g. R0=0.9 or kd=0.3 or intIOR=1.33")
    p.add_argument("--samples", type=int, default=100_000)
    p.add_argument("--full", action="store_true", help="also consistency, furnace and stability checks")
    p.add_argument("-o", "--output", type=Path, help="report folder (default: reports/chi2_<name>)")
    p.set_defaults(func=run)


def _params(items: list[str]) -> dict:
    out = {}
    for item in items:
        k, sep, v = item.partition("=")
        if not sep:
            raise BrdflabError(f"--param expects K=V, got '{item}'")
        try:
            out[k] = float(v)
        except ValueError:
            raise BrdflabError(f"--param {k}: expected a number, got '{v}'") from None
    return out


def run(args: argparse.Namespace) -> int:
    """Run the tests and write the report."""
    from brdflab.report.index import write_index
    from brdflab.report.validation import write_validation_report
    from brdflab.validate.battery import ALPHAS, THETAS, run_battery

    for a in args.alpha or []:
        if not a > 0:
            raise BrdflabError(f"--alpha must be > 0, got {a}")
    for t in args.theta or []:
        if not 0 <= t < 90:
            raise BrdflabError(f"--theta must be in [0, 90) degrees, got {t}")
    name = args.bsdf or args.warp
    bat = run_battery(n=args.samples, bsdfs=[args.bsdf] if args.bsdf else [],
                      warp_names=[args.warp] if args.warp else [], alphas=tuple(args.alpha or ALPHAS),
                      thetas=tuple(args.theta or THETAS), params=_params(args.param), full=args.full, progress=print)
    out = args.output or Path("reports") / f"chi2_{name.replace('/', '_')}"
    path = write_validation_report(bat, out, title=f"brdflab chi-square: {name}")
    write_index(out.parent)
    print(("ALL PASSED" if bat.passed else f"{len(bat.failures())} FAILURES") + f"; report: {path}")
    for f in bat.failures():
        print("  " + f, file=sys.stderr)
    return 0 if bat.passed else 1
