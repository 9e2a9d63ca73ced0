"""Entry point of the ``brdflab`` command.

Sub-commands live in ``cli/<name>_cmd.py`` modules (installed as ``brdflab.cli.<name>_cmd``); each exposes
``register(subparsers)`` which adds its parser and sets ``func`` (a callable taking the parsed arguments and
returning an exit status).
User errors (:class:`brdflab.errors.BrdflabError`) are printed as one line without a traceback and give
exit status 2; ``--debug`` shows the traceback.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from brdflab import __version__
from brdflab.errors import BrdflabError

#: Sub-command modules, in the order they appear in ``--help``. Missing modules are skipped.
COMMANDS = ("render", "chi2", "validate", "compare", "report", "check", "bench", "plot")


def build_parser() -> argparse.ArgumentParser:
    """Return the top-level argument parser with every available sub-command."""
    parser = argparse.ArgumentParser(
        prog="brdflab",
        description="BRDF validation and visualisation workbench for Nori scenes.",
    )
    parser.add_argument("--debug", action="store_true", help="show Python tracebacks for errors")
    parser.add_argument("--version", action="version", version=f"brdflab {__version__}",
                        help="print the brdflab version and exit")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in COMMANDS:
        try:
            mod = importlib.import_module(f"brdflab.cli.{name}_cmd")
        except ModuleNotFoundError as exc:
            if exc.name == f"brdflab.cli.{name}_cmd":
                continue
            raise
        mod.register(sub)
    for sub_parser in sub.choices.values():
        # ``brdflab render --debug scene.xml`` works as well as ``brdflab --debug render scene.xml``; SUPPRESS keeps
        # the sub-parser from resetting a --debug given before the sub-command.
        sub_parser.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                                help="show Python tracebacks for errors")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the ``brdflab`` command; return the process exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        status = args.func(args)
    except BrdflabError as exc:
        if args.debug:
            raise
        print(f"brdflab: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("brdflab: interrupted", file=sys.stderr)
        return 130
    return int(status or 0)


if __name__ == "__main__":
    sys.exit(main())
