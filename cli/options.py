"""Options shared by the sub-commands: ``--plugin``, and ``--bsdf``/``--param``/``--alpha``/``--theta``.

Parsing only: the registry (:mod:`brdflab.plugins`) converts and checks the values.
"""

from __future__ import annotations

import argparse
import math

from brdflab.errors import BrdflabError
from brdflab.limits import MIN_ALPHA, check_alpha

from .argtypes import number


def add_plugin_option(p: argparse.ArgumentParser) -> None:
    """``--plugin FILE|module[:Class]`` (repeatable): users' BSDFs for scenes and ``--bsdf``."""
    p.add_argument("--plugin", action="append", default=[], metavar="FILE",
                   help="a Python file (or package.module[:Class]) defining brdflab.BSDF subclasses with a "
                   "type_name; scenes and --bsdf can then name them (repeatable)")


def add_force_option(p: argparse.ArgumentParser, what: str = "files in the output folder") -> None:
    """``--force``: replace outputs brdflab did not write (:mod:`brdflab.outputs`; never an input of the run)."""
    p.add_argument("--force", action="store_true", help=f"replace {what} that brdflab did not write (never an "
                   "input of the run)")


def add_effort_option(p: argparse.ArgumentParser) -> None:
    """``--effort quick|normal|full``: the quadrature budget (:mod:`brdflab.effort`)."""
    p.add_argument("--effort", choices=("quick", "normal", "full"), default=None,
                   help="quadrature budget of the expected counts, ∫p and albedo (fit: the table nodes used): quick "
                   "(a first look; tabulated BSDFs in seconds), normal (default), full (a final verdict on a "
                   "stepped lobe)")


def load_plugins(args: argparse.Namespace) -> list[str]:
    """Load the ``--plugin`` specs of ``args``; return the registered type names."""
    from brdflab.plugins import load_plugins as _load

    return _load(getattr(args, "plugin", None) or [])


def add_bsdf_options(p: argparse.ArgumentParser, required: bool = False, repeat: bool = False) -> None:
    """``--bsdf NAME`` (a built-in, a plugin's type_name or package.module:Class), ``--param K=V``,
    ``--alpha A`` and ``--theta T`` (both repeatable), and ``--plugin``."""
    p.add_argument("--bsdf", action="append" if repeat else "store", required=required, metavar="NAME",
                   help="BSDF type: diffuse, roughconductor, roughsubstrate (or roughsubstrate/specular, "
                   "roughsubstrate/diffuse for one lobe), a plugin's type_name, or package.module:Class")
    p.add_argument("--param", action="append", default=[], metavar="K=V",
                   help="BSDF parameter named as in scene files, e.g. R0=0.9 or R0=0.9,0.8,0.7 or intIOR=1.33 "
                   "(repeatable; converted by the parameter's type)")
    p.add_argument("--alpha", type=number(MIN_ALPHA), action="append", metavar="A",
                   help=f"roughness α ≥ {MIN_ALPHA:g} (repeatable; only for a BSDF with an alpha parameter)")
    p.add_argument("--theta", type=number(0.0, 180.0, open_hi=True), action="append", metavar="DEG",
                   help="incident angle θ_i in degrees, in [0, 90) (repeatable); up to 180 for a two-sided BSDF "
                   "(dielectric, roughdielectric: ω_i inside)")
    add_plugin_option(p)


def parse_params(items: list[str]) -> dict[str, str]:
    """``["K=V", …]`` → ``{K: V}`` (values stay text; the registry converts them by kind)."""
    from brdflab.parameters import key_values

    return key_values(items, "--param")


def resolve_bsdf(name: str) -> str:
    """The registry name of ``--bsdf NAME`` (a ``module:Class`` path is loaded and replaced by its type)."""
    from brdflab.plugins import bsdf_class, load_plugin

    base, _, lobe = name.partition("/")
    if ":" in base:
        base = load_plugin(base)[0]
    bsdf_class(base)  # unknown names fail here, listing the valid ones
    return f"{base}/{lobe}" if lobe else base


def bsdf_spec_from_args(args: argparse.Namespace,
                        name: str) -> tuple[str, dict, list[float] | None, list[float] | None]:
    """(registry name, typed parameters, alphas, thetas) of the BSDF options, all checked.

    Raises
    ------
    BrdflabError
        Unknown BSDF or parameter, a value of the wrong type or non-finite, ``--alpha`` for a BSDF without
        an ``alpha`` parameter or not > 0, ``--theta`` outside [0, 90) ([0, 180) for a two-sided BSDF).
    """
    from brdflab.plugins import bsdf_class, is_builtin, parameter_kinds, property_list

    name = resolve_bsdf(name)
    base = name.split("/")[0]
    props = property_list(base, parse_params(args.param), owner=f"--bsdf {base}")
    params = {k: props._props[k].value for k in props.names()}
    if isinstance(params.get("alpha"), float | int):
        check_alpha(params["alpha"], "--param alpha")
    alphas = args.alpha
    if alphas:
        if "alpha" not in parameter_kinds(bsdf_class(base)):
            raise BrdflabError(f"--alpha applies only to a BSDF with an 'alpha' parameter; '{base}' has "
                               f"{', '.join(parameter_kinds(bsdf_class(base))) or 'none'}")
        for a in alphas:
            if not (math.isfinite(a) and a > 0):
                raise BrdflabError(f"--alpha must be > 0 (and finite), got {a}")
    top = 180 if getattr(bsdf_class(base), "two_sided", False) else 90  # two-sided: ω_i may be inside
    for t in args.theta or []:
        if not (math.isfinite(t) and 0 <= t < top):
            raise BrdflabError(f"--theta must be in [0, {top}) degrees for {base}, got {t:g}")
    if is_builtin(base):  # a built-in's own input errors (a missing table file) are usage errors, before any test
        from brdflab.judges.material.battery import make_named_bsdf

        make_named_bsdf(name, alphas[0] if alphas else None, params)
    return name, params, alphas, args.theta


def bsdf_from_args(args: argparse.Namespace, name: str | None = None):
    """The BSDF instance the options describe (first ``--alpha`` if several)."""
    from brdflab.judges.material.battery import make_named_bsdf

    load_plugins(args)
    raw = name or (args.bsdf[0] if isinstance(args.bsdf, list) else args.bsdf)
    name, params, alphas, _ = bsdf_spec_from_args(args, raw)
    return make_named_bsdf(name, alphas[0] if alphas else None, params)


def _short(text: str, n: int = 60) -> str:
    from brdflab.plugins import _short as short

    return short(text, n)
