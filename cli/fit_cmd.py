"""``brdflab fit MEASURED.binary --model NAME``: fit an analytic model's parameters to a measured BRDF."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from brdflab.errors import BrdflabError

from .options import add_effort_option, add_force_option, add_plugin_option, load_plugins, parse_params


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
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.add_argument("-o", "--output", type=Path, help="folder for fit.html, fit.json and the slices "
                   "(default: fit-<stem>/ beside the measurement)")
    add_force_option(p, "files in the output folder")
    add_effort_option(p)
    add_plugin_option(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Fit and write the page."""
    from brdflab.bsdf.measured import measured_values, read_merl
    from brdflab.fitting import fit, write_fit_page
    from brdflab.outputs import prepare_folder, record_outputs
    from brdflab.plugins import bsdf_class

    load_plugins(args)
    bsdf_class(args.model)  # an unknown model fails before the work
    out = args.output or args.measured.parent / f"fit-{args.measured.stem}"
    files = ["fit.html", "fit.json", "fit_slices.png"]
    prepare_folder(out, files, [args.measured, *args.plugin], args.force)  # before the work
    raw = read_merl(args.measured, raw=True)  # unmeasured nodes are left out of the fit, not fitted as 0
    stride = {"quick": (4, 6, 12), "full": (1, 2, 3)}.get(args.effort or "normal", (2, 3, 6))
    res = fit(raw, args.model, args.loss, fixed=parse_params(args.fix), stride=stride)
    table = measured_values(raw)
    page = write_fit_page(out, table, res, title=f"brdflab fit — {args.measured.name} as {args.model}")
    record_outputs(out, files)
    if args.json:
        print(json.dumps(res.to_dict(), indent=2))
    else:
        print(res.summary())
    print(f"wrote {page}", file=sys.stderr)
    if not (res.rms == res.rms):
        raise BrdflabError("the fit did not converge (NaN residual)")
    return 0
