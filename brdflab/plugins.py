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
sequence of 3 numbers → color; :mod:`brdflab.parameters`). The same conversion serves the scene loader and
``--param K=V``: unknown names, wrong types and non-finite numbers are errors naming the parameter (and file
and line).

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
import sys
from collections.abc import Iterable
from difflib import get_close_matches
from importlib.metadata import entry_points
from pathlib import Path
from typing import Any

from brdflab.builtin_types import BUILTIN, UNSUPPORTED
from brdflab.builtin_types import is_builtin_class as _is_builtin_class
from brdflab.errors import BrdflabError, SceneError, clean, code_location, first_line
from brdflab.parameters import (  # noqa: F401 (re-exported: they lived here)
    _KINDS,
    _init_defaults,
    _kind_of,
    build_bsdf,
    convert_value,
    parameter_kinds,
    properties_for,
)
from brdflab.scene.properties import PropertyList  # noqa: F401 (re-exported)

#: Entry-point group through which installed packages register BSDFs.
ENTRY_POINT_GROUP = "brdflab.bsdfs"

#: BSDF classes registered by users (files, import paths, entry points, :func:`register_bsdf`).
_USER_BSDFS: dict[str, type] = {}
#: Where each user BSDF came from (for messages).
_ORIGIN: dict[str, str] = {}
#: Classes registered under another name than their own ``type_name``: name → (class, its own name).
_RENAMED: dict[str, tuple[type, str]] = {}
_ENTRY_POINTS_LOADED = False
#: ``--plugin`` specs loaded in this process, in order (forwarded to cluster workers).
LOADED_SPECS: list[str] = []



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
    if cls.type_name != name:  # registered under another name (an entry point's): unregister restores it
        _RENAMED[name] = (cls, cls.type_name)
    cls.type_name = name
    _USER_BSDFS[name] = cls
    _ORIGIN[name] = origin
    return cls


def load_plugin(spec: str | Path, base: str | Path | None = None) -> list[str]:
    """Load users' BSDFs from a Python file or a ``package.module:Class`` import path.

    Parameters
    ----------
    spec
        A path to a ``.py`` file (every :class:`brdflab.BSDF` subclass defined in it that has a
        ``type_name`` is registered), ``path/to/file.py:Class`` (that class only), ``package.module``
        (likewise, from an importable module) or ``package.module:Class`` (that class only).
    base
        The folder relative paths and modules are resolved from first — a scene's own folder for the types a
        scene names (``<bsdf type="my_bsdfs.py:Phong">`` beside the scene); the working directory otherwise
        (also for ``--bsdf package.module:Class``, as ``python -m`` would find it).

    Returns
    -------
    list of str
        The type names registered.

    Raises
    ------
    BrdflabError
        If the file does not exist or is not a regular file, fails to import (the first line of the error and
        the plugin's own file and line are shown), or defines no BSDF.
    """
    text = str(spec)
    left, colon, clsname = text.rpartition(":") if text.count(":") else (text, "", "")
    if not colon or "/" in clsname or clsname.endswith(".py"):  # "C:/…"-like or no class part
        left, clsname = text, ""
    is_package = Path(left).is_dir() and (Path(left) / "__init__.py").is_file() and "/" not in left
    if left.endswith(".py") or (not clsname and Path(left).exists() and not is_package):
        path = Path(left)
        if base is not None and not path.is_absolute():
            path = Path(base) / path
        return _load_file(path, clsname, text)
    return _load_module(left, clsname, text, base)


def _load_file(path: Path, clsname: str, text: str) -> list[str]:
    from brdflab.bsdf.base import BSDF
    from brdflab.limits import check_input

    check_input(path, "plugin file")  # not found, a directory, a FIFO, a device: said as such
    modname = f"brdflab_plugin_{abs(hash(str(path.resolve()))):x}"
    if modname in sys.modules:
        module = sys.modules[modname]
    else:
        try:
            mspec = importlib.util.spec_from_file_location(modname, path)
            module = importlib.util.module_from_spec(mspec)
            sys.modules[modname] = module
            mspec.loader.exec_module(module)
        except BaseException as exc:
            sys.modules.pop(modname, None)
            if isinstance(exc, KeyboardInterrupt):
                raise
            raise BrdflabError(f"{_short(str(path), 80)}: the plugin failed to import: {first_line(exc, 120)}"
                               f"{plugin_location(exc)}") from exc
    if clsname:
        cls = vars(module).get(clsname)
        if not (isinstance(cls, type) and issubclass(cls, BSDF)):
            raise BrdflabError(f"plugin '{_short(text, 100)}': {_short(str(path), 100)} defines no BSDF class "
                               f"'{_short(clsname)}'")
        classes = [cls]
    else:
        classes = [c for c in vars(module).values()
                   if isinstance(c, type) and issubclass(c, BSDF) and c.__module__ == modname and c.type_name]
    return _register_loaded(classes, f"{path.resolve()}" + (f":{clsname}" if clsname else ""), str(path))


def _load_module(modname: str, clsname: str, text: str, base: str | Path | None) -> list[str]:
    from brdflab.bsdf.base import BSDF

    base = Path.cwd() if base is None else base  # as `python -m` would: the working directory first
    added = str(base) not in sys.path
    if added:
        sys.path.insert(0, str(base))
    try:
        module = importlib.import_module(modname)
    except BaseException as exc:
        if isinstance(exc, KeyboardInterrupt):
            raise
        hint = " (a folder of that name exists: name a .py file in it)" if Path(text).is_dir() else ""
        raise BrdflabError(f"plugin '{_short(text)}': cannot import module '{_short(modname)}': "
                           f"{_first_line(exc)}{plugin_location(exc)}{hint}") from exc
    finally:
        if added:
            sys.path.remove(str(base))
    if clsname:
        cls = getattr(module, clsname, None)
        if not isinstance(cls, type):
            defined = [c.__name__ for c in vars(module).values()
                       if isinstance(c, type) and issubclass(c, BSDF) and c.__module__ == module.__name__]
            there = f"; defined there: {', '.join(_short(n) for n in defined[:6])}" if defined else \
                "; it defines no brdflab.BSDF subclass"
            raise BrdflabError(f"plugin '{_short(text)}': module '{_short(modname)}' has no class '{_short(clsname)}'"
                               + there)
        classes = [cls]
    else:
        classes = [c for c in vars(module).values()
                   if isinstance(c, type) and issubclass(c, BSDF) and c.__module__ == module.__name__
                   and c.type_name]
    spec = text
    file = getattr(module, "__file__", None)
    if file and Path(file).resolve().is_relative_to(Path(base).resolve()):
        spec = f"{Path(file).resolve()}" + (f":{clsname}" if clsname else "")  # workers load it by path
    return _register_loaded(classes, spec, text)


def _register_loaded(classes: list[type], spec: str, origin: str) -> list[str]:
    classes = [c for c in classes if not _is_builtin_class(c)]
    if not classes:
        raise BrdflabError(f"plugin '{_short(origin, 100)}' defines no subclass of brdflab.BSDF with a `type_name`")
    names = [register_bsdf(c, origin=origin).type_name for c in classes]
    if spec not in LOADED_SPECS:
        LOADED_SPECS.append(spec)
    return names


#: The plugin's own file and line of an error (:func:`brdflab.errors.code_location`).
plugin_location = code_location


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
            scene_file = getattr(spec, "file", None)
            try:
                name = load_plugin(type_name, base=Path(scene_file).parent if scene_file else None)[0]
            except BrdflabError as exc:
                raise SceneError(exc.message, getattr(spec, "file", None), getattr(spec, "line", None)) from exc
            return _USER_BSDFS[name]
    table = BUILTIN.get(tag, {})
    target = table.get(type_name)
    if target is None:
        valid = list(table) + (list(_USER_BSDFS) if tag == "bsdf" else [])
        shown = ", ".join(sorted(valid)) or "none"
        if type_name in UNSUPPORTED.get(tag, ()):
            msg = f'<{tag} type="{_short(type_name)}"> is a Nori plugin that brdflab does not support; ' \
                  f"supported types: {shown}"
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


def bsdf_parameters(name: str, cls: type | None = None) -> dict[str, Any]:
    """Parameter name → default value of BSDF type ``name`` (its ``__init__`` keyword defaults); ``cls``, when
    given, is the already-resolved class (``name`` is then not looked up)."""
    cls = cls if cls is not None else bsdf_class(name)
    defaults = _init_defaults(cls)
    kinds = parameter_kinds(cls)
    if "KNOWN" in cls.__dict__ or _is_builtin_class(cls):  # built-ins: scene names may differ from argument order
        args = list(defaults)
        return {k: defaults.get(k, defaults[args[i]] if i < len(args) else None) for i, k in enumerate(kinds)}
    return {k: defaults[k] for k in kinds}


def property_list(name: str, params: dict[str, Any] | None, owner: str | None = None,
                  cls: type | None = None) -> PropertyList:
    """A :class:`PropertyList` for BSDF ``name`` from ``params`` (strings are converted by kind).

    ``cls`` is the BSDF class when the caller has resolved it already (the explorer's allow-list): ``name``
    is then only used in messages and is never looked up.
    """
    cls = cls if cls is not None else bsdf_class(name)
    return properties_for(cls, name, params, owner)


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


# -- helpers ----------------------------------------------------------------------------------------------
def _short(text: str, n: int = 60) -> str:
    """An echoed value made safe for a one-line message (:func:`brdflab.errors.clean`)."""
    return clean(text, n)


def _first_line(exc: BaseException) -> str:
    return first_line(exc)


def unregister_bsdf(name: str) -> None:
    """Remove a user BSDF (tests and notebooks that redefine a class); a class registered under another name
    than its own ``type_name`` gets its name back."""
    _USER_BSDFS.pop(name, None)
    _ORIGIN.pop(name, None)
    if name in _RENAMED:
        cls, original = _RENAMED.pop(name)
        cls.type_name = original

