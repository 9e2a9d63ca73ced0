"""``brdflab bench``: speed benchmarks (samples/s, rays/s, Embree share, load time, peak memory)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from brdflab.cli.argtypes import count
from brdflab.errors import BrdflabError, clean

from .options import add_force_option, add_plugin_option, load_plugins


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``bench`` sub-command."""
    from brdflab.benchmarking import CASES
    from brdflab.renderer import MAX_WORKERS

    p = sub.add_parser("bench", help="speed benchmarks of the fixed bench scenes",
                       description="Each case runs in a fresh process; reports medians and spread over --runs.")
    p.add_argument("cases", nargs="*", default=list(CASES), help=f"cases (default: all of {', '.join(CASES)}); "
                   "or your own scene files (SCENE.xml, rendered with their own integrator)")
    p.add_argument("--spp", type=count(1), default=16, help="samples per pixel of each run (default 16)")
    p.add_argument("--runs", type=count(1), default=3, help="runs per case; medians are reported (default 3)")
    p.add_argument("--workers", type=count(1, MAX_WORKERS), help="worker processes (default: all cores)")
    p.add_argument("--json", type=Path, default=Path("benchmarks/results/latest.json"),
                   help="where to write the JSON records (default: benchmarks/results/latest.json)")
    add_force_option(p, "a --json file")
    add_plugin_option(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the benchmarks."""
    from brdflab.benchmarking import CASES, ROOT, is_scene_case, run_suite
    from brdflab.scene.loader import load_scene

    load_plugins(args)
    inputs = [*args.plugin]  # what the --json file must never be
    for c in args.cases:
        if is_scene_case(c):
            inputs += load_scene(Path(c)).inputs  # a user's scene: every error (and a missing --plugin) before any run
        elif c not in CASES:
            raise BrdflabError(f"unknown bench case '{clean(c)}'; valid: {', '.join(CASES)}, or a scene file (.xml)")
    missing = [c for c in args.cases if not is_scene_case(c) and CASES[c][0] != "<generated>"
               and not (ROOT / CASES[c][0]).is_file()]
    if missing:
        where = clean(ROOT / CASES[missing[0]][0], 100)
        raise BrdflabError(f"bench scene of {', '.join(missing)} not found ({where}); "
                           "nothing was run")
    from brdflab.outputs import prepare_files, record_outputs

    # before the runs: not an input, not a folder, not a file brdflab did not write (without --force), writable
    prepare_files([args.json], inputs, args.force, "--json")
    records = run_suite(args.cases, args.spp, args.runs, args.workers, args.json, plugins=args.plugin)
    if args.json.exists():
        record_outputs(args.json.parent, [args.json.name])
    expected = sum(1 if is_scene_case(c) else len(CASES[c][1]) for c in args.cases)
    if len(records) < expected:
        print(f"brdflab: error: {expected - len(records)} bench run(s) failed", file=sys.stderr)
        return 1
    print(f"wrote {args.json}")
    return 0
