"""``brdflab chi2 --bsdf NAME`` / ``--warp NAME``: chi-square tests of one sampling routine;
``brdflab chi2 --samples FILE --against NAME``: a file of samples from another renderer (see
:mod:`brdflab.judges.samples.bsdf_checks` and docs/external-samples.md).

``-n/--count N`` is the number of samples brdflab draws per test. ``--samples`` names a file of samples;
``--samples N`` with an integer N that is not an existing file still means the count (deprecated, with a
warning), so older command lines keep working.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from brdflab.cli.argtypes import count
from brdflab.outputs import DEFAULT_REPORTS, index_root, output_folder, prepare_folder, record_outputs

from .cluster_options import add_cluster_options, cluster_from_args
from .options import add_bsdf_options, add_effort_option, add_force_option, bsdf_spec_from_args, load_plugins


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``chi2`` sub-command."""
    from brdflab.judges.material.battery import POINT_WARPS, WARPS

    p = sub.add_parser("chi2", help="chi-square goodness of fit of a BSDF or warp sampler, with an HTML report",
                       description="Samples directions, histograms them on the sphere about the lobe axis, integrates "
                       "the pdf over every bin and applies Pearson's test (Šidák-corrected for the number of tests). "
                       "Without --alpha/--theta it sweeps α ∈ {1e-3, 0.005, 0.05, 0.1, 0.3, 0.5, 1} (BSDFs with an "
                       "alpha parameter) and θ ∈ {0, 30, 60, 80, 89}°. Exit status 1 if a test fails.")
    add_bsdf_options(p)
    p.add_argument("--warp", choices=list(WARPS) + list(POINT_WARPS), help="test a warp instead of a BSDF")
    p.add_argument("--samples", type=_samples_arg, metavar="FILE",
                   help="a file of samples from your renderer: one line 'wi_x wi_y wi_z wo_x wo_y wo_z [pdf [w_r w_g "
                   "w_b]]' per sample (local frame, z = normal; '#' comments), or .npy/.npz; use with --against "
                   "(an integer N that is not a file: the sample count, deprecated for -n)")
    p.add_argument("--against", metavar="NAME",
                   help="with --samples FILE: the BSDF (built-in or plugin type) or warp (beckmann, cosine_hemisphere, "
                   "uniform_hemisphere, uniform_sphere) the file's samples should follow")
    p.add_argument("--against-emitter", metavar="SCENE.xml[:INDEX]",
                   help="with --samples FILE: light samples (one line 'x y n pdf measure [L]' per sample, world "
                   "space; measure 0 = per area, 1 = per sr) checked against emitter INDEX of the scene (0-based), "
                   "or its whole light with the scene's emitter selection (docs/external-samples.md)")
    p.add_argument("-n", "--count", type=count(1000), default=None, metavar="N",
                   help="samples per test when brdflab samples, at least 1000 (default 100000)")
    p.add_argument("--full", action="store_true", help="also consistency, furnace and stability checks")
    p.add_argument("-o", "--output", type=Path, help="report folder (default: reports/chi2_<name>)")
    add_force_option(p, "files in the report folder")
    add_effort_option(p)
    add_cluster_options(p)
    p.set_defaults(func=run, parser=p)


def _samples_arg(text: str) -> int | str:
    """``--samples``: a file name, or (deprecated) an integer sample count ≥ 1000 when no such file exists."""
    if Path(text).exists():
        return text
    try:
        int(text)
    except ValueError:
        return text
    return count(1000)(text)


def _count(args: argparse.Namespace) -> int:
    """The sample count: ``-n/--count``, or the deprecated ``--samples N``."""
    from brdflab.errors import BrdflabError

    if isinstance(args.samples, int):
        if args.count is not None:
            raise BrdflabError("give the sample count once: -n/--count N ('--samples N' is its deprecated form)")
        print("brdflab: warning: '--samples N' for the sample count is deprecated; use '-n/--count N' "
              "('--samples FILE' checks a file of samples)", file=sys.stderr)
        return args.samples
    return 100_000 if args.count is None else args.count


def run(args: argparse.Namespace) -> int:
    """Run the tests and write the report (``--samples FILE``: :func:`run_samples_file`)."""
    from brdflab.errors import BrdflabError
    from brdflab.judges.material.battery import ALPHAS, THETAS, run_battery
    from brdflab.pages.index import write_index
    from brdflab.pages.validation import VALIDATION_FILES, write_validation_report

    if isinstance(args.samples, str):
        return run_samples_file(args)
    if args.against or args.against_emitter:
        raise BrdflabError("--against/--against-emitter need --samples FILE (the samples to check)")
    if (args.bsdf is None) == (args.warp is None):
        raise BrdflabError("chi2 needs exactly one of --bsdf NAME or --warp NAME (or --samples FILE --against NAME)")
    n = _count(args)
    load_plugins(args)
    params: dict = {}
    if args.bsdf:
        name, params, alphas, thetas = bsdf_spec_from_args(args, args.bsdf)
    else:
        name, alphas, thetas = args.warp, args.alpha, args.theta
        if args.param:
            raise BrdflabError("--param applies to --bsdf, not to --warp")
    out = args.output or DEFAULT_REPORTS / f"chi2_{name.replace('/', '_')}"
    parent_created = output_folder(out.parent) if args.output else False  # checked before the tests run
    prepare_folder(out, list(VALIDATION_FILES), getattr(args, "plugin", None) or [], args.force)
    with cluster_from_args(args) as cluster:
        bat = run_battery(n=n, bsdfs=[name] if args.bsdf else [],
                          warp_names=[name] if args.warp else [], alphas=tuple(alphas or ALPHAS),
                          thetas=tuple(thetas or THETAS), params=params, full=args.full, progress=print,
                          cluster=cluster)
    path = write_validation_report(bat, out, title=f"brdflab chi-square: {name}")
    record_outputs(out, list(VALIDATION_FILES))
    root = index_root(out, args.output is not None, parent_created)
    if root is not None:
        write_index(root)
    from brdflab.judges.core.failures import grouped_failures

    grouped = [] if bat.passed else grouped_failures(bat)
    print(("ALL PASSED" if bat.passed else f"{len(bat.failures())} FAILURES, {len(grouped)} distinct (one line per "
           "cause below)") + f"; report: {path}")
    for f in grouped:
        print("  " + f, file=sys.stderr)
    return 0 if bat.passed else 1


def run_samples_file(args: argparse.Namespace) -> int:
    """``chi2 --samples FILE --against NAME``: exit 0 if the file's samples pass, 1 if not (saying which check)."""
    from brdflab.errors import BrdflabError
    from brdflab.judges.material.battery import WARPS
    from brdflab.workflows_extra import check_samples

    if args.against_emitter:
        return run_emitter_samples(args)
    if not args.against:
        raise BrdflabError("--samples FILE needs --against NAME (a BSDF or warp, e.g. --against beckmann --alpha 0.1)")
    if args.bsdf or args.warp or args.theta or args.full or args.count is not None:
        raise BrdflabError("--samples FILE takes only --against, --alpha, --param and --plugin (the file fixes wi "
                           "and the count)")
    alphas = args.alpha or []
    if len(alphas) > 1:
        raise BrdflabError("--samples FILE takes one --alpha (the roughness the samples were drawn with)")
    load_plugins(args)
    if args.against in WARPS:
        if args.param:
            raise BrdflabError(f"--param does not apply to the {args.against} warp")
        name, params = args.against, {}
        if alphas and not alphas[0] > 0:
            raise BrdflabError(f"--alpha must be > 0, got {alphas[0]}")
    else:
        name, params, _, _ = bsdf_spec_from_args(args, args.against)
    out = args.output or DEFAULT_REPORTS / f"chi2_samples_{Path(args.samples).stem}"
    parent_created = output_folder(out.parent) if args.output else False  # checked before the tests run
    res = check_samples(args.samples, name, alpha=alphas[0] if alphas else None, params=params, output=out,
                        force=args.force, plugins=getattr(args, "plugin", None))
    print(f"{res.path}: {sum(g.n for g in res.groups)} samples in {len(res.groups)} wi group(s) against "
          f"{res.against} (chi-square threshold {res.threshold:.3g} per group)")
    for line in res.messages():
        print(line)
    path = out / "index.html"
    root = index_root(out, args.output is not None, parent_created)
    if root is not None:
        from brdflab.pages.index import write_index

        write_index(root)
    bad = [g for g in res.groups if not g.passed]
    verdict = [f"{len(bad)} of {len(res.groups)} wi group(s) FAILED"] if bad else []
    verdict += [f"{res.nonfinite['count']:,} non-finite sample(s): FAILED"] if res.nonfinite else []
    print(("ALL PASSED" if res.passed else "; ".join(verdict)) + f"; report: {path}")
    return 0 if res.passed else 1


def run_emitter_samples(args: argparse.Namespace) -> int:
    """``chi2 --samples FILE --against-emitter SCENE[:INDEX]``: exit 0 if the light samples pass, 1 if not."""
    from brdflab.errors import BrdflabError
    from brdflab.judges.samples.light_samples import parse_target
    from brdflab.workflows_extra import check_emitter_samples

    if args.against or args.bsdf or args.warp or args.theta or args.full or args.count is not None or args.alpha \
            or args.param:
        raise BrdflabError("--samples FILE --against-emitter SCENE takes no BSDF, warp or count options")
    scene_path, index = parse_target(args.against_emitter)
    out = args.output or DEFAULT_REPORTS / f"chi2_emitter_samples_{Path(args.samples).stem}"
    parent_created = output_folder(out.parent) if args.output else False  # checked before the tests run
    res = check_emitter_samples(args.samples, scene_path, index=index, output=out, force=args.force,
                                plugins=getattr(args, "plugin", None))
    print(f"{res.path}: {res.samples} light samples against {res.target}")
    for line in res.messages():
        print(line)
    path = out / "emitter_samples.html"
    root = index_root(out, args.output is not None, parent_created)
    if root is not None:
        from brdflab.pages.index import write_index

        write_index(root)
    bad = [c for c in res.checks if not c.passed]
    print(("ALL PASSED" if res.passed else f"{len(bad)} of {len(res.checks)} check(s) FAILED") + f"; report: {path}")
    return 0 if res.passed else 1
