"""Compiled kernels (Numba) for the built-in materials and the film: the *compiled engine*.

The NumPy code in :mod:`brdflab.bsdf`, :mod:`brdflab.emitter` and :mod:`brdflab.film` is the specification
and the path of every plugin; the kernels here are scalar loops over the same equations, used only for
the built-in classes that declare a ``kernel`` name in their own class body (a subclass, e.g. a user's
plugin derived from :class:`~brdflab.RoughConductor`, does not inherit it and stays on the NumPy path).

Engine selection
----------------
``BRDFLAB_ENGINE=numpy`` (or ``--engine numpy`` on the command line, which sets that variable for the
process and its workers) forces the NumPy path everywhere; ``numba`` (the default) uses the kernels where
they exist. The two engines agree to 1e-12 relative (``tests/test_kernels.py``): the kernels evaluate the
same formulas in the same order; only the transcendental functions (``exp``, ``log1p``, ``sin``, ``cos``)
may round differently in the last bit.

The kernels are loaded lazily, when one first runs, so that start-up (``brdflab --help``, loading a
scene) does not pay for them. The first process after an install or an edit builds them ahead of time
into an extension module (:mod:`brdflab.kernels.aot`, a few seconds); every later process imports that
module in milliseconds, without numba. Where that build cannot be had, numba's JIT compiles them, cached on
disk (:mod:`brdflab.kernels.jit`).

Examples
--------
>>> from brdflab import kernels
>>> with kernels.use_engine("numpy"):
...     kernels.engine()
'numpy'
"""

from __future__ import annotations

import contextlib
import functools
import importlib
import os
import sys
import time
import warnings
from collections.abc import Iterator
from types import ModuleType

from brdflab.errors import BrdflabError, clean
from brdflab.kernels import aot, jit

#: The engines, by the name ``BRDFLAB_ENGINE`` and ``--engine`` take.
ENGINES = ("numba", "numpy")
_ENV = "BRDFLAB_ENGINE"
_numba_ok: bool | None = None


def engine() -> str:
    """The engine in force: ``"numba"`` (the default; ``"numpy"`` when numba is not installed) or ``"numpy"``.

    Raises
    ------
    BrdflabError
        When ``BRDFLAB_ENGINE`` holds something else.
    """
    asked = os.environ.get(_ENV, "").strip().lower()
    name = asked or "numba"
    if name not in ENGINES:
        raise BrdflabError(f"BRDFLAB_ENGINE must be one of {', '.join(ENGINES)}, not {clean(name, 40)}")
    if name == "numba" and not _numba_available():
        if asked:  # asked for by name: say why it cannot be had; by default, fall back quietly
            raise BrdflabError("the numba engine needs the numba package (pip install numba), or use --engine numpy")
        return "numpy"
    return name


def set_engine(name: str) -> None:
    """Select the engine for this process and the workers it starts (sets ``BRDFLAB_ENGINE``)."""
    if name not in ENGINES:
        raise BrdflabError(f"the engine must be one of {', '.join(ENGINES)}, not {clean(name, 40)}")
    os.environ[_ENV] = name


@contextlib.contextmanager
def use_engine(name: str) -> Iterator[None]:
    """Context manager: run a block with engine ``name``, then restore the previous setting."""
    old = os.environ.get(_ENV)
    set_engine(name)
    try:
        yield
    finally:
        if old is None:
            os.environ.pop(_ENV, None)
        else:
            os.environ[_ENV] = old


def compiled() -> bool:
    """True when the compiled engine is in force."""
    return engine() == "numba"


def _numba_available() -> bool:
    global _numba_ok
    if _numba_ok is None:
        _numba_ok = importlib.util.find_spec("numba") is not None
    return _numba_ok


#: Seconds this process spent loading the kernels (the prebuilt module, or numba and its cached machine
#: code) and building them (the ahead-of-time build, or JIT compiles: ``numba:compile`` events, outermost
#: only); see :func:`costs`.
_COSTS = {"import": 0.0, "compile": 0.0}
_timer_installed = False
_chosen = False
#: Why this process runs the JIT instead of the prebuilt module (None: it does not, or has not chosen).
aot_error: str | None = None


def backend() -> str:
    """``"aot"`` (the prebuilt extension module) or ``"jit"`` (numba), once a kernel module is loaded;
    ``""`` before."""
    return jit.BACKEND.mode if _chosen else ""


def _choose_backend() -> None:
    """Before the first kernel module is imported: the prebuilt module when there is one for this key
    (building it first if needed), else the JIT (:mod:`brdflab.kernels.aot`)."""
    global _chosen, aot_error
    if _chosen:
        return
    _chosen = True
    if not aot.enabled():
        return
    t0 = time.perf_counter()
    path, error = aot.find()
    if path is None and error is None:
        path, error = aot.build()
        _COSTS["compile"] += time.perf_counter() - t0
        t0 = time.perf_counter()
        if path is None:  # said once, when the build fails; later processes use the JIT quietly
            warnings.warn(f"the compiled kernels could not be prebuilt ({clean(aot.summary(error or ''), 160)}); "
                          f"numba's JIT compiles them instead (about 0.5 s per process)", stacklevel=3)
    if path is not None:
        try:
            jit.BACKEND.ext = aot.load_module(path)
            jit.BACKEND.mode = "aot"
        except (ImportError, OSError) as e:  # a damaged or foreign build: the JIT, as without one
            path, error = None, f"{path}: {type(e).__name__}: {e}"
    if path is None:
        aot_error = error
        return
    _COSTS["import"] += time.perf_counter() - t0


def load(name: str) -> ModuleType:
    """The kernel module ``brdflab.kernels.<name>`` (on first use: loads the prebuilt kernels, building
    them once if needed, or imports numba and compiles the module's kernels or loads them from numba's
    disk cache)."""
    mod = sys.modules.get(f"brdflab.kernels.{name}")
    if mod is None:
        _choose_backend()
        t0, c0 = time.perf_counter(), _COSTS["compile"]
        if jit.BACKEND.mode == "jit":
            _install_compile_timer()
        mod = importlib.import_module(f"brdflab.kernels.{name}")
        _COSTS["import"] += time.perf_counter() - t0 - (_COSTS["compile"] - c0)
    return mod


def _install_compile_timer() -> None:
    global _timer_installed
    if _timer_installed:
        return
    from numba.core import event

    class CompileTimer(event.Listener):
        depth, t0 = 0, 0.0

        def on_start(self, ev) -> None:
            if self.depth == 0:
                self.t0 = time.perf_counter()
            self.depth += 1

        def on_end(self, ev) -> None:
            self.depth -= 1
            if self.depth == 0:
                _COSTS["compile"] += time.perf_counter() - self.t0

    event.register("numba:compile", CompileTimer())
    _timer_installed = True


def costs() -> dict[str, float]:
    """{"import": s, "compile": s} spent on the kernels in this process so far: loading them (the prebuilt
    module, or numba and the JIT's cached machine code), and building them (the ahead-of-time build or JIT
    compiles: the first run after an install or an edit)."""
    return dict(_COSTS)


def for_object(obj: object, kind: str) -> ModuleType | None:
    """The kernel module for a built-in object, or None for the NumPy path.

    ``obj``'s class must name its kernel in its **own** body (``kernel = "roughconductor"``): subclasses
    (users' plugins) do not inherit it. ``kind`` is the kernel module (``"bsdf"``).
    """
    if type(obj).__dict__.get("kernel") is None or not compiled():
        return None
    return load(kind)


#: The kernel modules (one per stage).
MODULES = ("bsdf", "direct", "emitter", "film", "shading")


def preload() -> None:
    """Import numba and the kernel modules now (in a process about to fork workers, which then share them
    instead of each importing numba); nothing with the NumPy engine."""
    if compiled():
        for name in MODULES:
            load(name)


def twin(kind: str, name: str):
    """Decorator of a built-in's NumPy method that has a compiled twin ``brdflab.kernels.<kind>.<name>``.

    The decorated method stays the specification; when :func:`for_object` finds a kernel for the object,
    ``<name>(obj, *args)`` runs instead (unless it returns ``NotImplemented``: a case the kernel does not
    cover, such as a textured light).
    """
    def wrap(method):
        @functools.wraps(method)
        def run(self, *args, **kwargs):
            k = for_object(self, kind)
            if k is not None:
                out = getattr(k, name)(self, *args, **kwargs)
                if out is not NotImplemented:
                    return out
            return method(self, *args, **kwargs)

        return run

    return wrap


__all__ = ["ENGINES", "engine", "set_engine", "use_engine", "compiled", "load", "for_object", "twin",
           "preload", "MODULES", "costs", "backend"]
