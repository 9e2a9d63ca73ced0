"""``brdflab check RENDER.exr … --scene SCENE.xml``: is this render an unbiased estimate of the scene?"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from brdflab.cli.argtypes import count, number, seed
from brdflab.errors import BrdflabError

from .cluster_options import add_cluster_options, cluster_from_args
from .options import add_plugin_option, load_plugins


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
    p.add_argument("--quiet", action="store_true", help="only the verdict line")
    p.add_argument("--force", action="store_true", help="replace files in the output folder that brdflab did not "
                   "write (never an input of the run)")
    add_plugin_option(p)
    add_cluster_options(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the check; exit status 0 consistent, 1 biased."""
    from brdflab.errors import clean
    from brdflab.imageio import read_exr
    from brdflab.outputs import prepare_folder, record_outputs
    from brdflab.report.check_page import CHECK_FILES, write_check
    from brdflab.scene.loader import load_scene
    from brdflab.stats.check import check_inputs, run_check
    from brdflab.stats.jobs import make_integrator

    if args.spp < 1 or args.runs < 1:
        raise BrdflabError("--spp and --runs must be at least 1")
    if args.block < 2:
        raise BrdflabError("--block must be at least 2 pixels")
    if not 0 < args.alpha < 1:
        raise BrdflabError(f"--alpha must be in (0, 1), got {args.alpha}")
    if args.ref_var and not args.ref:
        raise BrdflabError("--ref-var needs --ref")
    load_plugins(args)
    scene = load_scene(args.scene)
    integrator = args.integrator or scene.integrator_type
    make_integrator(integrator)
    images = [read_exr(p) for p in args.renders]
    ref = read_exr(args.ref) if args.ref else None
    ref_var = read_exr(args.ref_var) if args.ref_var else None
    check_inputs(images, ref_var, args.user_spp, [clean(p, 80) for p in args.renders], args.block, ref)
    out = args.output or args.renders[0].parent / f"check-{args.renders[0].stem}"
    inputs = [*args.renders, args.scene, *(p for p in (args.ref, args.ref_var) if p), *scene.inputs]
    prepare_folder(out, list(CHECK_FILES), inputs, args.force)  # before the work, not after it
    cam = scene.camera
    for p, img in zip(args.renders, images, strict=True):
        if img.shape[:2] != (cam.height, cam.width):
            raise BrdflabError(f"{p}: image is {img.shape[1]}×{img.shape[0]} pixels, the scene renders "
                               f"{cam.width}×{cam.height}")
    for p, img in ((args.ref, ref), (args.ref_var, ref_var)):
        if img is not None and img.shape[:2] != (cam.height, cam.width):
            raise BrdflabError(f"{p}: image is {img.shape[1]}×{img.shape[0]} pixels, the scene renders "
                               f"{cam.width}×{cam.height}")
    user_spp = args.user_spp or _spp_attribute(args.renders[0]) or scene.spp
    say = (lambda m: None) if args.quiet else (lambda m: print(m, file=sys.stderr))
    if ref is None:
        say(f"brdflab estimate: {args.runs} runs × {args.spp} spp of {integrator} at {cam.width}×{cam.height}")
    with cluster_from_args(args, quiet=args.quiet) as cluster:
        # On a cluster each independent run is one job, rendered by one single-threaded worker (the scene is
        # loaded there from its path: a shared file system); the runs' seeds make the result placement-free.
        res = run_check(images, args.scene, integrator, args.spp, args.runs, args.seed, ref, ref_var, args.block,
                        args.alpha, 1 if cluster else args.workers, progress=say, user_spp=user_spp,
                        map_fn=map if cluster is None else cluster.imap, levels=args.levels)
    from brdflab.stats.attribution import attribute_check, attribution_lines

    att = attribute_check(res, images, args.scene, integrator, args.seed, args.where_spp, args.workers, say)
    page = write_check(out, args.renders, images, res, args.scene, attribution=att)
    record_outputs(out, list(CHECK_FILES))
    print(res.verdict())
    for line in [] if att is None or args.quiet else attribution_lines(att):
        print(line)
    say(f"cost: {res.seconds:.1f} s; wrote {page} and {out / 'check.json'}")
    return 0 if res.consistent else 1


def _spp_attribute(path: Path) -> int | None:
    """The ``brdflab_spp`` header attribute of an EXR written by brdflab, if any."""
    from brdflab.imageio import read_exr_header

    try:
        return int(read_exr_header(path).get("brdflab_spp", 0)) or None
    except (ValueError, TypeError):
        return None
