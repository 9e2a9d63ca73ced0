"""``brdflab check RENDER.exr … --scene SCENE.xml``: is this render an unbiased estimate of the scene?"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from brdflab.cli.argtypes import count, number, resolution, seed

from .cluster_options import add_cluster_options, cluster_from_args
from .options import add_force_option, add_plugin_option


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``check`` sub-command."""
    p = sub.add_parser(
        "check", help="test whether renders are unbiased (p-value, block map, HTML)",
        description="Compare one or more renders of SCENE (different seeds) with brdflab's own independent "
        "estimate, block by block and for the image mean, with a family-wise false-alarm level. Exit status: "
        "0 consistent, 1 biased, 2 usage error.")
    p.add_argument("renders", type=Path, nargs="+", metavar="RENDER.exr", help="your render(s) of the scene (EXR)")
    p.add_argument("--scene", type=Path, required=True, help="the Nori scene the renders show")
    p.add_argument("--integrator", help="brdflab integrator of the estimate (default: the scene's; NAME or "
                   "NAME:VARIANT, e.g. direct_mis:power)")
    p.add_argument("--ref", type=Path, help="use this reference EXR instead of rendering brdflab's estimate")
    p.add_argument("--ref-var", type=Path, help="per-pixel variance EXR of the reference mean (with --ref)")
    p.add_argument("--spp", type=count(1), default=32, help="samples per pixel of each brdflab run (default 32)")
    p.add_argument("--runs", type=count(1, 10_000), default=4,
                   help="independent brdflab runs (default 4); more spp or runs "
                   "cost proportionally more time and detect smaller biases")
    p.add_argument("--user-spp", type=count(1), help="samples per pixel of your render(s) (default: the EXR's "
                   "brdflab_spp attribute, else the scene's sampleCount); with one render, brdflab's variance "
                   "at this spp is a lower bound of the variance used")
    p.add_argument("--block", type=count(2), default=16, help="block side in pixels (default 16)")
    p.add_argument("--levels", type=count(1, 8), default=4, help="block sizes BLOCK·2^i for i < LEVELS, one "
                   "family (default 4: 16, 32, 64, 128 px; with one render every window at every BLOCK offset); "
                   "1 = BLOCK only")
    p.add_argument("--alpha", type=number(0.0, 1.0, open_lo=True, open_hi=True), default=0.01,
                   help="family-wise false-alarm level (default 0.01)")
    p.add_argument("--seed", type=seed, default=0, help="base seed of brdflab's runs, in [0, 2^64)")
    p.add_argument("--workers", type=count(1, 256), help="worker processes (default: all cores)")
    p.add_argument("-o", "--output", type=Path, help="output folder for check.html/check.json (default: "
                   "check-<stem>/ beside the first render)")
    p.add_argument("--where-spp", type=count(0, 4096), default=8, metavar="N",
                   help="samples per pixel of the auxiliary renders that say, for a biased render, which materials, "
                   "emitters and sampling strategy the flagged regions follow (default 8; 0: off)")
    p.add_argument("--resolution", metavar="WxH", type=resolution,
                   help="replace the scene camera's size, for brdflab's runs and your renders alike (quick checks)")
    p.add_argument("--quiet", action="store_true", help="only the verdict line")
    add_force_option(p, "files in the output folder")
    add_plugin_option(p)
    add_cluster_options(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the check (:func:`brdflab.workflows.check`); exit status 0 consistent, 1 biased."""
    from brdflab.stats.attribution import attribution_lines
    from brdflab.workflows import check

    out = args.output or args.renders[0].parent / f"check-{args.renders[0].stem}"
    say = (lambda m: None) if args.quiet else (lambda m: print(m, file=sys.stderr))
    with cluster_from_args(args, quiet=args.quiet) as cluster:
        res = check(args.renders, args.scene, integrator=args.integrator, spp=args.spp, runs=args.runs,
                    seed=args.seed, ref=args.ref, ref_var=args.ref_var, user_spp=args.user_spp, block=args.block,
                    levels=args.levels, alpha=args.alpha, workers=args.workers, output=out, force=args.force,
                    plugins=args.plugin, progress=say, where_spp=args.where_spp, cluster=cluster,
                    resolution=args.resolution)
    print(res.verdict())
    if res.estimate_note:
        print(res.estimate_note)
    for line in [] if res.attribution is None or args.quiet else attribution_lines(res.attribution):
        print(line)
    say(f"cost: {res.seconds:.1f} s; wrote {out / 'check.html'} and {out / 'check.json'}")
    return 0 if res.consistent else 1
