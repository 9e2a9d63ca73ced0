"""``brdflab explore [--plugin FILE] [--port P] [--no-browser]``: the live BRDF explorer in a browser."""

from __future__ import annotations

import argparse


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
    """Serve until interrupted (:func:`brdflab.workflows_extra.explore`)."""
    from brdflab.workflows_extra import explore

    explore(plugins=args.plugin, port=args.port, browser=not args.no_browser)
    return 0
