"""Entry point of the ``brdflab`` command.

Sub-commands live in ``cli/<name>_cmd.py`` modules (installed as ``brdflab.cli.<name>_cmd``); each exposes
``register(subparsers)`` which adds its parser and sets ``func`` (a callable taking the parsed arguments and
returning an exit status).
User errors (:class:`brdflab.errors.BrdflabError`) are printed as one line without a traceback and give
exit status 2; ``--debug`` shows the traceback.

Exit status (:data:`EXIT_STATUS`, also in the README):

=====  ==================================================================================
0      success
1      a check failed (``chi2``, ``validate``: a test did not pass)
2      usage error or bad input (scene, mesh, image, option value, resource limit)
129    interrupted by SIGHUP
130    interrupted by Ctrl-C (SIGINT)
141    the output pipe was closed (``brdflab compare … | head -1``)
143    interrupted by SIGTERM
=====  ==================================================================================
"""

from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys
import warnings

from brdflab import __version__
from brdflab.cli.signals import exit_status, ignore_while_exiting, install_default_handlers
from brdflab.errors import EXIT_USAGE, MESSAGE_CHARS, BrdflabError, Interrupted, clean
from brdflab.kernels import ENGINES, asked, set_engine

EXIT_BROKEN_PIPE = 141
#: Exit statuses of the command.
EXIT_STATUS = {0: "success", 1: "a check failed", 2: "usage error or bad input", 129: "SIGHUP",
               130: "Ctrl-C (SIGINT)", 141: "output pipe closed", 143: "SIGTERM"}

#: Sub-command modules, in the order they appear in ``--help``. Missing modules are skipped.
COMMANDS = ("render", "chi2", "validate", "compare", "report", "check", "bench", "plot", "explore", "fit")


def requested_command(argv: list[str]) -> str | None:
    """The sub-command named on the command line (the first word that is not a global option or its value), if it
    is one of :data:`COMMANDS`; else None."""
    skip = False
    for word in argv:
        if skip:
            skip = False
        elif word == "--engine":
            skip = True
        elif word == "--":
            return None
        elif not word.startswith("-"):
            return word if word in COMMANDS else None
    return None


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """Return the top-level argument parser with every available sub-command, or with ``only`` that one (a run of
    one command imports only its module: 0.03–0.04 s less start-up than importing all ten)."""
    parser = argparse.ArgumentParser(
        prog="brdflab",
        description="BRDF validation and visualisation workbench for Nori scenes.",
    )
    parser.add_argument("--debug", action="store_true", help="show Python tracebacks for errors")
    parser.add_argument("--engine", choices=ENGINES, default=None,
                        help="numba (compiled kernels for the built-in materials, the default) or numpy (the "
                             "reference path everywhere); also BRDFLAB_ENGINE")
    parser.add_argument("--version", action="version", version=f"brdflab {__version__}",
                        help="print the brdflab version and exit")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in COMMANDS if only is None else (only,):
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
        sub_parser.add_argument("--engine", choices=ENGINES, default=argparse.SUPPRESS,
                                help="numba (default) or numpy: see brdflab --help")
    return parser


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """Every warning as one short line (``brdflab: warning: …``), control characters escaped; NumPy's
    floating-point warnings (which have no location in the user's input) are named as such."""
    text = str(message)
    if issubclass(category, RuntimeWarning) and "encountered" in text:
        text = f"numerical problem ({text}); the result may contain non-finite values"
    try:
        print(f"brdflab: warning: {clean(text, MESSAGE_CHARS)}", file=sys.stderr)
    except (OSError, ValueError):
        pass


def main(argv: list[str] | None = None) -> int:
    """Run the ``brdflab`` command; return the process exit status (see :data:`EXIT_STATUS`)."""
    install_default_handlers()
    words = sys.argv[1:] if argv is None else argv
    parser = build_parser(requested_command(words))
    args = parser.parse_args(words)
    debug = getattr(args, "debug", False)
    previous_show = warnings.showwarning
    warnings.showwarning = _show_warning
    try:
        if getattr(args, "engine", None):  # process-wide (forked workers and Dask tasks inherit it)
            set_engine(args.engine)
        asked()  # a bad BRDFLAB_ENGINE is a usage error before any work starts
        if getattr(args, "effort", None):  # process-wide for this command (forked workers inherit it)
            from brdflab.effort import use

            with use(args.effort):
                status = args.func(args)
        else:
            status = args.func(args)
        sys.stdout.flush()  # a closed pipe is noticed here, not in the interpreter's final flush
    except BrdflabError as exc:
        if debug:
            raise
        print(f"brdflab: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except Interrupted as exc:
        print(f"brdflab: {exc.message} ({signal.Signals(exc.signum).name})", file=sys.stderr)
        return exit_status(exc.signum)
    except KeyboardInterrupt:
        print("brdflab: interrupted", file=sys.stderr)
        return exit_status(signal.SIGINT)
    except BrokenPipeError:
        # The reader of our output went away (``brdflab compare … | head -1``): stop quietly. Point stdout at
        # /dev/null so that the interpreter's final flush does not raise again.
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
        except (OSError, ValueError):
            pass
        return EXIT_BROKEN_PIPE
    except OSError as exc:
        # A file-system error no specific check caught (a folder removed or made read-only mid-run, a full
        # disk): one line naming the file, exit status 2.
        if debug:
            raise
        name = exc.filename if exc.filename is not None else ""
        reason = exc.strerror or str(exc) or type(exc).__name__
        print(f"brdflab: error: {clean(name, 120) + ': ' if name else ''}{clean(reason, 120)}", file=sys.stderr)
        return EXIT_USAGE
    except MemoryError:
        if debug:
            raise
        print("brdflab: error: out of memory (lower the resolution, spp or workers, or see BRDFLAB_MEMORY_LIMIT_GB)",
              file=sys.stderr)
        return EXIT_USAGE
    finally:
        warnings.showwarning = previous_show
    return int(status or 0)


def run(argv: list[str] | None = None) -> int:
    """The ``brdflab`` console entry point: :func:`main`, whose status it returns for the exit.

    An exit status decided by a signal (130, 143, 129) is kept through the interpreter's shutdown:
    :func:`brdflab.cli.signals.ignore_while_exiting`.
    """
    status = main(argv)
    ignore_while_exiting(status)
    return status


if __name__ == "__main__":
    sys.exit(run())
