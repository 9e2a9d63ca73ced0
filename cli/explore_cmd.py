"""``brdflab explore [--plugin FILE] [--port P] [--no-browser]``: the live BRDF explorer in a browser."""

from __future__ import annotations

import argparse

from brdflab.errors import BrdflabError


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``explore`` sub-command."""
    from brdflab.cli.argtypes import count
    from brdflab.cli.options import add_plugin_option

    p = sub.add_parser("explore", help="live BRDF explorer in the browser (local Bokeh server on 127.0.0.1)",
                       description="Choose a BSDF (built-ins and --plugin types), move θ_i, φ_i and every parameter, "
                       "and watch the polar plot, 3D lobe, θh×θd slice, albedo and samples-over-pdf views update. "
                       "Serves on 127.0.0.1 only; Ctrl-C stops it.")
    add_plugin_option(p)
    p.add_argument("--port", type=count(1, 65535), default=5006, help="port on 127.0.0.1 (default 5006)")
    p.add_argument("--no-browser", action="store_true", help="do not open a browser tab")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Load the plugins and serve until interrupted."""
    from brdflab.cli.options import load_plugins

    load_plugins(args)
    try:
        from brdflab.viz.explorer import serve
    except ImportError as exc:  # bokeh is a dependency; a broken install gets a clear message
        raise BrdflabError(f"the explorer needs Bokeh ({exc}); pip install -e '.[test]'") from None
    try:
        serve(args.port, open_browser=not args.no_browser)
    except OSError as exc:
        raise BrdflabError(f"cannot serve on 127.0.0.1:{args.port}: {exc.strerror or exc}") from None
    return 0
