"""BSDF parameters: their kinds, the conversion of scene and ``--param`` values, and construction from a
property list — one conversion for scene files, the command line and the API (:mod:`brdflab.plugins` looks the
classes up by name).

A BSDF's parameters are the keyword arguments of its ``__init__``, named as in the scene file. Their kinds are
the class's ``KNOWN`` table (name → ``"float"``, ``"integer"``, ``"boolean"``, ``"string"`` or ``"color"``)
when it has one, otherwise the types of the defaults (``float`` → float, ``int`` → integer, ``bool`` →
boolean, ``str`` → string, a sequence of 3 numbers → color). Unknown names, wrong types (a bool is not a
number, 2.5 is not an integer, "maybe" is not a boolean) and non-finite numbers are errors naming the parameter.
"""

from __future__ import annotations

import inspect
from difflib import get_close_matches
from typing import Any

import numpy as np

from brdflab.builtin_types import is_builtin_class as _is_builtin_class
from brdflab.errors import BrdflabError, ascii_int, clean, code_location, first_line
from brdflab.scene.properties import PropertyList

_KINDS = ("float", "integer", "boolean", "string", "color")


def _short(text: str, n: int = 60) -> str:
    return clean(text, n)


def _init_defaults(cls: type) -> dict[str, Any]:
    """``__init__`` keyword parameters → defaults (``inspect.Parameter.empty`` where there is none)."""
    sig = inspect.signature(cls.__init__)
    out = {}
    for p in list(sig.parameters.values())[1:]:
        if p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD):
            continue
        out[p.name] = p.default
    return out


def _kind_of(value: Any) -> str | None:
    if isinstance(value, bool | np.bool_):
        return "boolean"
    if isinstance(value, int | np.integer):
        return "integer"
    if isinstance(value, float | np.floating):
        return "float"
    if isinstance(value, str):
        return "string"
    if isinstance(value, list | tuple | np.ndarray) and np.shape(value) == (3,):
        return "color"
    return None


def parameter_kinds(cls: type, origin: str | None = None) -> dict[str, str]:
    """Parameter name → kind (``float``, ``integer``, ``boolean``, ``string``, ``color``) of a BSDF class.

    Built-ins declare theirs in ``KNOWN`` (a subclass that keeps a built-in's ``__init__`` keeps them); for other
    classes they come from the ``__init__`` defaults.
    """
    known = cls.__dict__.get("KNOWN") or (getattr(cls, "KNOWN", None) if _is_builtin_class(cls) else None)
    if known is None:  # a subclass that keeps a built-in's __init__ keeps its parameters (and their kinds)
        owner = next((c for c in cls.__mro__ if "__init__" in c.__dict__), None)
        if owner is not None and owner is not cls and _is_builtin_class(owner) and "KNOWN" in owner.__dict__:
            known = owner.__dict__["KNOWN"]
    if known is not None:
        return dict(known)
    out = {}
    for name, default in _init_defaults(cls).items():
        kind = _kind_of(default)
        if kind is None:
            where = origin or cls.__name__
            what = "has no default" if default is inspect.Parameter.empty else \
                f"has a default of type {type(default).__name__}"
            raise BrdflabError(f"{where}: parameter '{name}' of {cls.__name__} {what}; brdflab needs a default "
                               "of type float, int, bool, str or a 3-sequence (colour) to convert scene values")
        out[name] = kind
    return out


def key_values(items, option: str = "--param") -> dict[str, str]:
    """``["K=V", …]`` → ``{K: V}``: the values stay text (converted by kind where they are used); an item without
    ``=`` or with an empty key is a :class:`BrdflabError` naming ``option``.

    Examples
    --------
    >>> key_values(["alpha=0.1", "R0=0.9,0.6,0.5"])
    {'alpha': '0.1', 'R0': '0.9,0.6,0.5'}
    """
    out: dict[str, str] = {}
    for item in items:
        k, sep, v = str(item).partition("=")
        if not sep or not k.strip():
            raise BrdflabError(f"{option} expects K=V, got '{clean(item, 60)}'")
        out[k.strip()] = v
    return out


def convert_value(kind: str, text: str, what: str) -> Any:
    """Convert the text of a ``--param`` value to ``kind``; raise a BrdflabError naming ``what``."""
    t = text.strip()
    try:
        if kind == "float":
            v = float(t)
        elif kind == "integer":
            v = ascii_int(t, signed=True)
            if v is None:
                raise ValueError
        elif kind == "boolean":
            if t.lower() not in ("true", "false", "1", "0", "yes", "no"):
                raise ValueError
            return t.lower() in ("true", "1", "yes")
        elif kind == "string":
            return text
        elif kind == "color":
            parts = [float(x) for x in t.replace(" ", ",").split(",") if x]
            if len(parts) == 1:
                parts *= 3
            if len(parts) != 3:
                raise ValueError
            v = np.array(parts)
        else:
            raise ValueError
    except (ValueError, OverflowError):
        expect = {"color": "a colour (one number or three, e.g. 0.9,0.8,0.7)", "integer": "an integer",
                  "boolean": "true or false", "float": "a number"}.get(kind, kind)
        raise BrdflabError(f"{what}: expected {expect}, got '{_short(text)}'") from None
    if not np.all(np.isfinite(v)):
        raise BrdflabError(f"{what}: expected a finite value, got '{_short(text)}'")
    return v


def properties_for(cls: type, name: str, params: dict[str, Any] | None, owner: str | None = None) -> PropertyList:
    """A :class:`PropertyList` for BSDF class ``cls`` (type ``name``, for messages) from ``params``; strings
    (``--param K=V``) are converted by kind, other values checked against it."""
    kinds = parameter_kinds(cls)
    props = PropertyList(owner or f'bsdf "{name}"')
    for key, value in (params or {}).items():
        if key not in kinds:
            hint = get_close_matches(key, list(kinds), n=1)
            raise BrdflabError(f"{props.owner}: unknown parameter '{_short(key)}'"
                               + (f" (did you mean '{hint[0]}'?)" if hint else "")
                               + f"; its parameters: {', '.join(kinds) or 'none'}")
        kind = kinds[key]
        what = f"{props.owner} parameter '{key}'"
        if isinstance(value, str):
            value = convert_value(kind, value, what)
        elif kind == "color":
            value = np.broadcast_to(np.asarray(value, float), (3,)).copy()
        elif kind == "boolean":
            if not isinstance(value, bool | np.bool_):  # bool(2), bool(0.5): no silent truthiness
                raise BrdflabError(f"{what}: expected true or false, got {_short(repr(value))}")
            value = bool(value)
        elif kind in ("float", "integer"):
            if isinstance(value, bool | np.bool_) or not isinstance(value, int | float | np.integer | np.floating):
                raise BrdflabError(f"{what}: expected {'a number' if kind == 'float' else 'an integer'}, "
                                   f"got {_short(repr(value))}")
            if kind == "integer" and not (np.isfinite(value) and float(value) == int(value)):
                raise BrdflabError(f"{what}: expected an integer, got {_short(repr(value))}")  # no truncation
            value = float(value) if kind == "float" else int(value)
        if kind in ("float", "color") and not np.all(np.isfinite(value)):
            raise BrdflabError(f"{what}: expected a finite value, got {value}")
        props.set(key, kind, value)
    return props


def build_bsdf(cls: type, props: PropertyList) -> Any:
    """Construct ``cls`` from a property list: its own ``from_properties`` for built-ins, otherwise the
    generic mapping of property names to ``__init__`` keyword arguments (with the kinds checked)."""
    if _is_builtin_class(cls) or "from_properties" in cls.__dict__:
        return cls.from_properties(props)
    kinds = parameter_kinds(cls)
    props.check_known(kinds)
    kwargs = {}
    for key in props.names():
        kind = kinds[key]
        getter = {"float": props.get_float, "integer": props.get_int, "boolean": props.get_bool,
                  "string": props.get_string, "color": props.get_color}[kind]
        if kind == "float" and key in props and props._props[key].kind == "integer":
            value = float(props.get_int(key))
        else:
            value = getter(key)
        if kind in ("float", "color") and not np.all(np.isfinite(value)):
            raise props.error(key, f"'{key}' must be finite, got {value}")
        kwargs[key] = value
    try:
        return cls(**kwargs)
    except (ValueError, TypeError) as exc:  # the plugin's own argument checks
        raise props.error(None, f"{cls.__name__}({', '.join(kwargs)}) rejected its parameters: "
                          f"{first_line(exc)}{code_location(exc)}") from exc
    except BrdflabError:
        raise
    except BaseException as exc:  # anything else the plugin's constructor raises (even SystemExit)
        if isinstance(exc, KeyboardInterrupt):
            raise
        raise props.error(None, f"{cls.__name__}({', '.join(kwargs)}) failed: {first_line(exc)}"
                          f"{code_location(exc)}") from exc
