"""``brdflab plot --bsdf NAME[:K=V,…] …``: the BRDF views of one or several materials, as files."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from brdflab.errors import BrdflabError


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``plot`` sub-command."""
    from brdflab.cli.argtypes import count, number
    from brdflab.cli.options import add_bsdf_options, add_effort_option, add_force_option
    from brdflab.viz.static import DEFAULT_VIEWS, VIEWS

    p = sub.add_parser(
        "plot", help="polar plot, 3D lobe, θh×θd slice, albedo and lit sphere of BSDFs (PNG, SVG, CSV, HTML)",
        description="Draws one BSDF or several overlaid in their own colours. Each --bsdf is NAME or "
        "NAME:KEY=VALUE,KEY=VALUE (a colour keeps its commas: R0=0.95,0.64,0.54); --alpha and --param apply to "
        "every --bsdf that does not set the key itself. Example: brdflab plot --bsdf roughconductor:alpha=0.05 "
        "--bsdf roughconductor:alpha=0.3 --param R0=0.9 --theta 45 -o plots/sweep")
    add_bsdf_options(p, repeat=True)
    p._option_string_actions["--bsdf"].metavar = "NAME[:K=V,...]"
    p._option_string_actions["--bsdf"].help = (
        "material to plot (repeatable; default roughconductor): a built-in, a plugin's type_name or "
        "package.module:Class, optionally with its own parameters after ':'")
    p._option_string_actions["--alpha"].help = "roughness for every --bsdf with an alpha that does not set it " \
        "(repeatable: one material per value, an α sweep)"
    p._option_string_actions["--theta"].help = "incident angle θ_i in degrees (default 45)"
    p._option_string_actions["--param"].help = ("parameter for every --bsdf that has it and does not set it itself, "
                                                "e.g. R0=0.9 or R0=0.9,0.8,0.7 (repeatable)")
    p.add_argument("--phi-d", type=number(-360.0, 360.0), default=90.0,
                   help="φ_d of the θh×θd slice in degrees (default 90)")
    p.add_argument("--cos", action="store_true", help="polar plot of f·cos θ_o instead of f")
    p.add_argument("--views", default=",".join(DEFAULT_VIEWS),
                   help=f"comma-separated subset of {','.join(VIEWS)} (default {','.join(DEFAULT_VIEWS)}; furnace: "
                   "a path-traced sphere of each BSDF in a white environment, the energy it loses against α)")
    p.add_argument("--samples", type=count(2, 10**8), default=20_000, help="Monte Carlo samples per albedo point")
    p.add_argument("--size", type=count(8, 4096), default=128, help="lit-sphere resolution (default 128)")
    p.add_argument("--spp", type=count(1, 1 << 20), default=16, help="lit-sphere samples per pixel (default 16)")
    p.add_argument("--workers", type=count(1, 256), help="render workers (default: all cores)")
    p.add_argument("-o", "--output", type=Path, help="output folder (default plots/<first bsdf>)")
    add_force_option(p, "files in the output folder")
    add_effort_option(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Build the BSDFs and write the views."""
    from brdflab.cli.options import load_plugins
    from brdflab.viz import spec as bspec
    from brdflab.viz.static import VIEWS
    from brdflab.workflows import plot

    load_plugins(args)
    thetas = args.theta or [45.0]
    if len(thetas) > 1:
        raise BrdflabError("plot takes one --theta")
    theta = thetas[0]
    if not (math.isfinite(theta) and 0 <= theta < 90):
        raise BrdflabError(f"--theta must be in [0, 90) degrees, got {theta:g}")
    for a in args.alpha or []:
        if not (math.isfinite(a) and a > 0):
            raise BrdflabError(f"--alpha must be > 0, got {a:g}")
    chosen = tuple(v.strip() for v in args.views.split(",") if v.strip())
    bad = [v for v in chosen if v not in VIEWS]
    if bad or not chosen:
        raise BrdflabError(f"--views: unknown view '{(bad or [''])[0][:40]}'; valid: {', '.join(VIEWS)}")
    specs = bspec.resolve(args.bsdf or ["roughconductor"], args.alpha, args.param)
    bsdfs = [bspec.build(s) for s in specs]
    out = args.output or Path("plots") / specs[0].name
    res = plot(bsdfs, out, theta=theta, phi_d=args.phi_d, cos=args.cos, views=chosen, samples=args.samples,
               size=args.size, spp=args.spp, workers=args.workers, labels=[s.label for s in specs],
               plugins=args.plugin, progress=lambda m: print("  " + m), force=args.force)
    print(f"wrote {', '.join(chosen)} for {len(bsdfs)} BSDF(s): {res.page}")
    return 0
