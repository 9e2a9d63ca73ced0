"""The one plugin registry: built-in types, users' ``--plugin`` files, ``module:Class`` and entry points.

Every command and the scene loader look scene-object types up here:

* **built-ins** — the BSDFs, emitters and integrators of :data:`BUILTIN`, imported on first use;
* **plugin files** — ``load_plugin("my_bsdf.py")`` (the CLI's ``--plugin FILE``) imports the file and
  registers every :class:`~brdflab.bsdf.base.BSDF` subclass it defines with a ``type_name``;
* **classes by import path** — ``load_plugin("package.module:Class")`` (also ``--bsdf package.module:Class``);
* **installed packages** — an entry point in the group ``brdflab.bsdfs`` (``name = "package.module:Class"``)
  is registered the first time a BSDF name is looked up;
* **programmatically** — :func:`register_bsdf` (``bl.register_bsdf``), usable as a class decorator.

Parameters
----------
A BSDF's parameters are the keyword arguments of its ``__init__``, named as in the scene file
(``<float name="exponent" value="20"/>`` → ``exponent=20.0``). Their kinds are the class's ``KNOWN`` table
(name → ``"float"``, ``"integer"``, ``"boolean"``, ``"string"`` or ``"color"``) when it has one, otherwise the
types of the defaults (``float`` → float, ``int`` → integer, ``bool`` → boolean, ``str`` → string, a
sequence of 3 numbers → color). The same conversion serves the scene loader and ``--param K=V``: unknown
names, wrong types and non-finite numbers are errors naming the parameter (and file and line).

A class may declare ``sweep = {"exponent": [5.0, 20.0, 100.0]}``: the values ``brdflab validate`` runs its
battery over (an ``alpha`` parameter is swept over the usual roughness grid without it).

Examples
--------
>>> import numpy as np
>>> import brdflab as bl
>>> @bl.register_bsdf
... class Flat(bl.BSDF):
...     # a Lambertian lobe with uniform hemisphere sampling
...     type_name = "flat_doc_example"
...     def __init__(self, albedo=(0.5, 0.5, 0.5)):
...         self.albedo = np.asarray(albedo, float)
...     def eval(self, wi, wo, uv=None):
...         up = (wi[:, 2] > 0) & (wo[:, 2] > 0)
...         return up[:, None] * self.albedo / np.pi
...     def pdf(self, wi, wo, uv=None):
...         return np.where((wi[:, 2] > 0) & (wo[:, 2] > 0), 1 / (2 * np.pi), 0.0)
...     def sample(self, wi, u, uv=None):
...         wo = bl.warps.square_to_uniform_hemisphere(u[:, :2])
...         pdf = self.pdf(wi, wo)
...         return bl.BSDFSample(wo, self.eval(wi, wo) * (wo[:, 2] / np.maximum(pdf, 1e-300))[:, None], pdf)
>>> bl.plugins.bsdf_parameters("flat_doc_example")
{'albedo': (0.5, 0.5, 0.5)}
>>> bl.make_bsdf("flat_doc_example", {"albedo": "0.2,0.3,0.4"}).albedo
array([0.2, 0.3, 0.4])
>>> bl.chi2_test(bl.make_bsdf("flat_doc_example"), theta=30, samples=20_000).passed
True
"""

from __future__ import annotations

import importlib
import importlib.util
import inspect
import sys
from collections.abc import Iterable
from difflib import get_close_matches
from importlib.metadata import entry_points
from pathlib import Path
from typing import Any

import numpy as np

from brdflab.errors import BrdflabError, SceneError, clean
from brdflab.scene.properties import PropertyList

#: Built-in scene-object types: tag → type name → ``"module:Class"`` (imported on first use).
BUILTIN: dict[str, dict[str, str]] = {
    "bsdf": {
        "diffuse": "brdflab.bsdf.diffuse:Diffuse",
        "roughconductor": "brdflab.bsdf.roughconductor:RoughConductor",
        "roughsubstrate": "brdflab.bsdf.roughsubstrate:RoughSubstrate",
    },
    "emitter": {
        "area": "brdflab.emitter.area:AreaEmitter",
        "pointlight": "brdflab.emitter.point:PointLight",
        "environment": "brdflab.emitter.environment:EnvironmentEmitter",
    },
    "integrator": {
        "normals": "brdflab.integrator.normals:NormalsIntegrator",
        "direct_ems": "brdflab.integrator.direct_ems:DirectEMS",
        "direct_mats": "brdflab.integrator.direct_mats:DirectMATS",
        "direct_mis": "brdflab.integrator.direct_mis:DirectMIS",
        "direct_whitted": "brdflab.integrator.direct_whitted:DirectWhitted",
    },
}
#: Nori plugins brdflab deliberately leaves out (no path tracing, no delta BSDFs).
UNSUPPORTED = {
    "bsdf": ("mirror", "dielectric", "roughdielectric"),
    "integrator": ("depth", "path", "path_nee", "path_mis", "vpl"),
}
#: Entry-point group through which installed packages register BSDFs.
ENTRY_POINT_GROUP = "brdflab.bsdfs"

#: BSDF classes registered by users (files, import paths, entry points, :func:`register_bsdf`).
_USER_BSDFS: dict[str, type] = {}
#: Where each user BSDF came from (for messages).
_ORIGIN: dict[str, str] = {}
_ENTRY_POINTS_LOADED = False
#: ``--plugin`` specs loaded in this process, in order (forwarded to cluster workers).
LOADED_SPECS: list[str] = []

_KINDS = ("float", "integer", "boolean", "string", "color")


# -- registration ---------------------------------------------------------------------------------------
def register_bsdf(cls: type, name: str | None = None, *, origin: str = "register_bsdf") -> type:
    """Register a user BSDF class under ``name`` (default: its ``type_name``); returns the class.

    Parameters
    ----------
    cls
        A subclass of :class:`brdflab.BSDF` implementing ``eval``, ``pdf`` and ``sample`` on (N, 3) local
        directions (see :mod:`brdflab.bsdf.base`).
    name
        The type name scene files and ``--bsdf`` use; default ``cls.type_name``.
    origin
        Where the class came from, for messages.

    Raises
    ------
    BrdflabError
        If the class is not a BSDF subclass, has no name, lacks a method of the contract, shadows a built-in
        type, or its ``__init__`` parameters have no usable defaults.
    """
    from brdflab.bsdf.base import BSDF

    if not (isinstance(cls, type) and issubclass(cls, BSDF)) or cls is BSDF:
        raise BrdflabError(f"{origin}: {getattr(cls, '__name__', cls)!s:.60} is not a subclass of brdflab.BSDF")
    name = name or cls.type_name
    if not name or not isinstance(name, str):
        raise BrdflabError(f"{origin}: class {cls.__name__} needs a non-empty `type_name` (the name scenes use)")
    if name in BUILTIN["bsdf"] and not _is_builtin_class(cls):
        raise BrdflabError(f"{origin}: type name '{name}' of {cls.__name__} is a built-in BSDF; choose another name")
    missing = [m for m in ("eval", "pdf", "sample") if getattr(cls, m) is getattr(BSDF, m)]
    if missing:
        raise BrdflabError(f"{origin}: {cls.__name__} does not implement {', '.join(missing)} "
                           "(the BSDF contract: eval, pdf and sample on (N, 3) local directions)")
    parameter_kinds(cls, origin=origin)  # reject unusable signatures now, not at first use
    cls.type_name = name
    _USER_BSDFS[name] = cls
    _ORIGIN[name] = origin
    return cls


def _is_builtin_class(cls: type) -> bool:
    return any(f"{cls.__module__}:{cls.__qualname__}" == t for t in BUILTIN["bsdf"].values())


def load_plugin(spec: str | Path) -> list[str]:
    """Load users' BSDFs from a Python file or a ``package.module:Class`` import path.

    Parameters
    ----------
    spec
        A path to a ``.py`` file (every :class:`brdflab.BSDF` subclass defined in it that has a
        ``type_name`` is registered), ``package.module`` (likewise, from an importable module) or
        ``package.module:Class`` (that class only).

    Returns
    -------
    list of str
        The type names registered.

    Raises
    ------
    BrdflabError
        If the file does not exist, fails to import (the first line of the error is shown), or defines no
        BSDF.
    """
    from brdflab.bsdf.base import BSDF

    text = str(spec)
    path = Path(text)
    if text.endswith(".py") or path.is_file():
        if not path.is_file():
            raise BrdflabError(f"plugin file '{_short(text)}' not found")
        modname = f"brdflab_plugin_{abs(hash(str(path.resolve()))):x}"
        if modname in sys.modules:
            module = sys.modules[modname]
        else:
            try:
                mspec = importlib.util.spec_from_file_location(modname, path)
                module = importlib.util.module_from_spec(mspec)
                sys.modules[modname] = module
                mspec.loader.exec_module(module)
            except Exception as exc:
                sys.modules.pop(modname, None)
                raise BrdflabError(f"{path}: the plugin failed to import: {_first_line(exc)}") from exc
        classes = [c for c in vars(module).values()
                   if isinstance(c, type) and issubclass(c, BSDF) and c.__module__ == modname and c.type_name]
        origin = str(path)
    else:
        modname, _, clsname = text.partition(":")
        try:
            module = importlib.import_module(modname)
        except Exception as exc:
            raise BrdflabError(f"plugin '{_short(text)}': cannot import module '{_short(modname)}': "
                               f"{_first_line(exc)}") from exc
        if clsname:
            cls = getattr(module, clsname, None)
            if cls is None:
                raise BrdflabError(f"plugin '{_short(text)}': module '{modname}' has no class '{_short(clsname)}'")
            classes = [cls]
        else:
            classes = [c for c in vars(module).values()
                       if isinstance(c, type) and issubclass(c, BSDF) and c.__module__ == module.__name__
                       and c.type_name]
        origin = text
    classes = [c for c in classes if not _is_builtin_class(c)]
    if not classes:
        raise BrdflabError(f"plugin '{_short(text)}' defines no subclass of brdflab.BSDF with a `type_name`")
    names = [register_bsdf(c, origin=origin).type_name for c in classes]
    if text not in LOADED_SPECS:
        LOADED_SPECS.append(text)
    return names


def load_plugins(specs: Iterable[str | Path] | None) -> list[str]:
    """:func:`load_plugin` for each spec (the CLI's repeatable ``--plugin``); returns all names."""
    names: list[str] = []
    for s in specs or ():
        names += load_plugin(s)
    return names


def _load_entry_points() -> None:
    global _ENTRY_POINTS_LOADED
    if _ENTRY_POINTS_LOADED:
        return
    _ENTRY_POINTS_LOADED = True
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        try:
            cls = ep.load()
        except Exception as exc:
            raise BrdflabError(f"entry point '{ep.name}' ({ep.value}) of group {ENTRY_POINT_GROUP} failed to load: "
                               f"{_first_line(exc)}") from exc
        register_bsdf(cls, ep.name, origin=f"entry point {ep.value}")


# -- look-up ----------------------------------------------------------------------------------------------
def bsdf_names() -> list[str]:
    """The BSDF type names available: built-ins first, then registered users' types."""
    _load_entry_points()
    return list(BUILTIN["bsdf"]) + [n for n in _USER_BSDFS if n not in BUILTIN["bsdf"]]


def is_builtin(name: str) -> bool:
    """True for brdflab's own BSDF types (which may take the material-family fast paths)."""
    return name in BUILTIN["bsdf"]


def plugin_class(tag: str, type_name: str, spec: Any = None) -> type:
    """The class registered for ``<tag type="type_name">``.

    Parameters
    ----------
    tag
        ``"bsdf"``, ``"emitter"`` or ``"integrator"``.
    type_name
        The type; for BSDFs also a ``package.module:Class`` import path (loaded on the fly).
    spec
        The scene object (:class:`~brdflab.scene.xmlparser.ObjectSpec`) for file and line in messages.

    Raises
    ------
    SceneError
        For an unknown or unsupported type, listing the valid ones.
    """
    if tag == "bsdf":
        _load_entry_points()
        if type_name in _USER_BSDFS:
            return _USER_BSDFS[type_name]
        if ":" in type_name and type_name not in BUILTIN["bsdf"]:
            try:
                name = load_plugin(type_name)[0]
            except BrdflabError as exc:
                raise SceneError(exc.message, getattr(spec, "file", None), getattr(spec, "line", None)) from exc
            return _USER_BSDFS[name]
    table = BUILTIN.get(tag, {})
    target = table.get(type_name)
    if target is None:
        valid = list(table) + (list(_USER_BSDFS) if tag == "bsdf" else [])
        shown = ", ".join(sorted(valid)) or "none"
        if type_name in UNSUPPORTED.get(tag, ()):
            msg = f'<{tag} type="{_short(type_name)}"> is a Nori plugin that brdflab does not support ' \
                  f"(direct illumination only); supported types: {shown}"
        else:
            hint = get_close_matches(type_name, valid, n=1)
            msg = f'unknown {tag} type "{_short(type_name)}"' + (f" (did you mean '{hint[0]}'?)" if hint else "") \
                + f"; valid types: {shown}"
            if tag == "bsdf":
                msg += " (a plugin's types need --plugin FILE)"
        raise SceneError(msg, getattr(spec, "file", None), getattr(spec, "line", None))
    module, cls = target.split(":")
    return getattr(importlib.import_module(module), cls)


def bsdf_class(name: str) -> type:
    """The BSDF class of type ``name`` (built-in, registered, or a ``module:Class`` path)."""
    return plugin_class("bsdf", name)


# -- parameters -------------------------------------------------------------------------------------------
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

    Built-ins declare theirs in ``KNOWN``; for other classes they come from the ``__init__`` defaults.
    """
    known = cls.__dict__.get("KNOWN") or (getattr(cls, "KNOWN", None) if _is_builtin_class(cls) else None)
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


def bsdf_parameters(name: str) -> dict[str, Any]:
    """Parameter name → default value of BSDF type ``name`` (its ``__init__`` keyword defaults)."""
    cls = bsdf_class(name)
    defaults = _init_defaults(cls)
    kinds = parameter_kinds(cls)
    if "KNOWN" in cls.__dict__ or _is_builtin_class(cls):  # built-ins: scene names may differ from argument order
        args = list(defaults)
        return {k: defaults.get(k, defaults[args[i]] if i < len(args) else None) for i, k in enumerate(kinds)}
    return {k: defaults[k] for k in kinds}


def convert_value(kind: str, text: str, what: str) -> Any:
    """Convert the text of a ``--param`` value to ``kind``; raise a BrdflabError naming ``what``."""
    t = text.strip()
    try:
        if kind == "float":
            v = float(t)
        elif kind == "integer":
            v = int(t)
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


def property_list(name: str, params: dict[str, Any] | None, owner: str | None = None) -> PropertyList:
    """A :class:`PropertyList` for BSDF ``name`` from ``params`` (strings are converted by kind)."""
    cls = bsdf_class(name)
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


def make_bsdf(name: str, params: dict[str, Any] | None = None, alpha: float | None = None) -> Any:
    """Construct BSDF ``name`` from parameters named as in scene files.

    Parameters
    ----------
    name
        A built-in type, a registered plugin's ``type_name`` or ``package.module:Class``.
    params
        Parameter values; strings (``--param K=V``) are converted by the parameter's kind.
    alpha
        Roughness, only for a BSDF with an ``alpha`` parameter (an error otherwise); overrides
        ``params["alpha"]``.

    Returns
    -------
    BSDF
        The material.

    Raises
    ------
    BrdflabError
        Unknown names, wrong types, non-finite or out-of-range values (with what was expected).

    Examples
    --------
    >>> from brdflab.plugins import make_bsdf
    >>> round(make_bsdf("roughconductor", {"R0": "0.9,0.8,0.7"}, alpha=0.2).alpha_value, 12)
    0.2
    """
    cls = bsdf_class(name)
    params = dict(params or {})
    if alpha is not None:
        if "alpha" not in parameter_kinds(cls):
            raise BrdflabError(f"--alpha applies only to a BSDF with an 'alpha' parameter; '{name}' has "
                               f"{', '.join(parameter_kinds(cls)) or 'none'}")
        params["alpha"] = alpha
    return build_bsdf(cls, property_list(name, params))


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
                          f"{_first_line(exc)}") from exc


# -- helpers ----------------------------------------------------------------------------------------------
def _short(text: str, n: int = 60) -> str:
    """An echoed value made safe for a one-line message (:func:`brdflab.errors.clean`)."""
    return clean(text, n)


def _first_line(exc: BaseException) -> str:
    lines = str(exc).strip().splitlines()
    return _short(f"{type(exc).__name__}: {lines[0] if lines else ''}", 160)


def unregister_bsdf(name: str) -> None:
    """Remove a user BSDF (tests and notebooks that redefine a class)."""
    _USER_BSDFS.pop(name, None)
    _ORIGIN.pop(name, None)

