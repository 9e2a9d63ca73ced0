"""``brdflab plot --bsdf NAME[:K=V,…] …``: the BRDF views of one or several materials, as files."""

from __future__ import annotations

import argparse
from pathlib import Path

from brdflab.errors import BrdflabError


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``plot`` sub-command."""
    from brdflab.viz.static import VIEWS

    p = sub.add_parser(
        "plot", help="polar plot, 3D lobe, θh×θd slice, albedo and lit sphere of BSDFs (PNG, SVG, CSV, HTML)",
        description="Draws one BSDF or several overlaid in their own colours. Each --bsdf is NAME or "
        "NAME:KEY=VALUE,KEY=VALUE (a colour keeps its commas: R0=0.95,0.64,0.54); --alpha and --param apply to "
        "every --bsdf that does not set the key itself. Example: brdflab plot --bsdf roughconductor:alpha=0.05 "
        "--bsdf roughconductor:alpha=0.3 --param R0=0.9 --theta 45 -o plots/sweep")
    p.add_argument("--bsdf", action="append", metavar="NAME[:K=V,...]",
                   help="material to plot (repeatable; default roughconductor)")
    p.add_argument("--plugin", action="append", default=[], metavar="FILE",
                   help="register the BSDF classes of a .py file or package.module:Class (repeatable)")
    p.add_argument("--alpha", type=float, help="roughness for every --bsdf that does not set alpha")
    p.add_argument("--param", action="append", default=[], metavar="K=V",
                   help="parameter for every --bsdf that does not set it (repeatable), e.g. R0=0.9")
    p.add_argument("--theta", type=float, default=45.0, help="incident angle θ_i in degrees (default 45)")
    p.add_argument("--phi-d", type=float, default=90.0, help="φ_d of the θh×θd slice in degrees (default 90)")
    p.add_argument("--cos", action="store_true", help="polar plot of f·cos θ_o instead of f")
    p.add_argument("--views", default=",".join(VIEWS), help=f"comma-separated subset of {','.join(VIEWS)}")
    p.add_argument("--samples", type=int, default=20_000, help="Monte Carlo samples per albedo point")
    p.add_argument("--size", type=int, default=128, help="lit-sphere resolution (default 128)")
    p.add_argument("--spp", type=int, default=16, help="lit-sphere samples per pixel (default 16)")
    p.add_argument("--workers", type=int, help="render workers (default: all cores)")
    p.add_argument("-o", "--output", type=Path, help="output folder (default plots/<first bsdf>)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Build the BSDFs and write the views."""
    from brdflab.viz import spec as bspec
    from brdflab.viz.registry import load_plugin
    from brdflab.viz.static import VIEWS, PlotOptions, write_plots

    for plugin in args.plugin:
        load_plugin(plugin)
    if not 0 <= args.theta < 90:
        raise BrdflabError(f"--theta must be in [0, 90) degrees, got {args.theta:g}")
    if args.alpha is not None and not args.alpha > 0:
        raise BrdflabError(f"--alpha must be > 0, got {args.alpha:g}")
    chosen = tuple(v.strip() for v in args.views.split(",") if v.strip())
    bad = [v for v in chosen if v not in VIEWS]
    if bad or not chosen:
        raise BrdflabError(f"--views: unknown view '{(bad or [''])[0][:40]}'; valid: {', '.join(VIEWS)}")
    for name, v, lo in (("--samples", args.samples, 2), ("--size", args.size, 8), ("--spp", args.spp, 1)):
        if v < lo:
            raise BrdflabError(f"{name} must be at least {lo}, got {v}")
    specs = bspec.resolve(args.bsdf or ["roughconductor"], args.alpha, args.param)
    bsdfs = [bspec.build(s) for s in specs]
    labels = [s.label for s in specs]
    out = args.output or Path("plots") / specs[0].name
    opts = PlotOptions(theta=args.theta, phi_d=args.phi_d, times_cos=args.cos, views=chosen, samples=args.samples,
                       sphere_size=args.size, sphere_spp=args.spp, workers=args.workers)
    path = write_plots(bsdfs, labels, out, opts, progress=lambda m: print("  " + m))
    print(f"wrote {', '.join(chosen)} for {len(bsdfs)} BSDF(s): {path}")
    return 0
