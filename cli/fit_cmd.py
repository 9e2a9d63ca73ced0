"""``brdflab fit MEASURED.binary --model NAME``: fit an analytic model's parameters to a measured BRDF."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from .options import add_effort_option, add_force_option, add_plugin_option


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``fit`` sub-command."""
    p = sub.add_parser("fit", help="least-squares fit of a model's parameters to a measured BRDF (MERL .binary)",
                       description="Cosine-weighted least squares (log-compressed by default) of the model's float "
                       "and colour parameters against the table's nodes; prints the parameters and the residual and "
                       "writes fit.html with the θh×θd slices of the measurement, the model and their ratio.")
    p.add_argument("measured", type=Path, help="a MERL .binary file")
    p.add_argument("--model", default="roughconductor", help="the model: roughconductor (default), roughsubstrate, "
                   "or a plugin's type")
    p.add_argument("--loss", choices=("log", "linear"), default="log", help="residual: log(1+f·cos·cos) (default) "
                   "or f·cos·cos")
    p.add_argument("--fix", action="append", default=[], metavar="K=V", help="hold a parameter at a value "
                   "(repeatable), e.g. --fix intIOR=1.5")
    p.add_argument("--free", action="append", default=None, metavar="K,K", help="the parameters to fit "
                   "(comma-separated, repeatable; default: the model's own, roughconductor: R0,alpha), e.g. "
                   "--free alpha_u,alpha_v,eta,k --fix distribution=ggx")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.add_argument("-o", "--output", type=Path, help="folder for fit.html, fit.json and the slices "
                   "(default: fit-<stem>/ beside the measurement)")
    add_force_option(p, "files in the output folder")
    add_effort_option(p)
    add_plugin_option(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Fit and write the page (:func:`brdflab.fitting.fit`)."""
    from brdflab.fitting import fit

    out = args.output or args.measured.parent / f"fit-{args.measured.stem}"
    res = fit(args.measured, args.model, args.loss, fix=args.fix, free=args.free, effort=args.effort or "normal",
              output=out, force=args.force, plugins=args.plugin)
    if args.json:
        print(json.dumps(res.to_dict(), indent=2))
    else:
        print(res.summary())
    print(f"wrote {out / 'fit.html'}", file=sys.stderr)
    return 0
