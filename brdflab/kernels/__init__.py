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
scene) does not pay for them. They are built ahead of time into an extension module
(:mod:`brdflab.kernels.aot`), which later processes import in milliseconds, without numba. **No run waits
for that build** (15–60 s of one core): when no engine is asked for and the module is not built yet, the
process says so in one line (``compiled kernels not built yet: this run uses the NumPy engine; building them
in the background``), starts the build detached and runs on the NumPy engine; the next process picks up the
module. Forked render workers inherit their parent's decision and a cluster's workers are told the
client's, so that one render uses one engine. Asking for ``numba`` by name waits for the build (or uses
numba's JIT where it cannot be had, as ``BRDFLAB_AOT=0`` does). A damaged, foreign or unbuildable cache
costs one warning line and the NumPy engine (:mod:`brdflab.kernels.cache`).

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
from brdflab.kernels import aot, cache, jit

#: The engines, by the name ``BRDFLAB_ENGINE`` and ``--engine`` take.
ENGINES = ("numba", "numpy")
_ENV = "BRDFLAB_ENGINE"
_numba_ok: bool | None = None


def asked() -> str:
    """The engine asked for: ``"numba"``, ``"numpy"`` (``BRDFLAB_ENGINE``, ``--engine``) or ``""`` (none).

    Raises
    ------
    BrdflabError
        When ``BRDFLAB_ENGINE`` holds something else.
    """
    name = os.environ.get(_ENV, "").strip().lower()
    if name and name not in ENGINES:
        raise BrdflabError(f"BRDFLAB_ENGINE must be one of {', '.join(ENGINES)}, not {clean(name, 40)}")
    return name


def engine() -> str:
    """The engine in force: ``"numba"`` (the compiled kernels) or ``"numpy"``.

    Asked for by name (``BRDFLAB_ENGINE``), it is that engine; ``numba`` then waits for a first build if
    needed (numba's JIT if it cannot be had). Not asked for, the process decides once: the compiled
    kernels when the prebuilt module is there, else the NumPy engine while the module is built in the
    background (see the module docstring). A compiled engine that cannot load costs one warning line and
    the NumPy engine, never the run.

    Raises
    ------
    BrdflabError
        When ``BRDFLAB_ENGINE`` holds something else, or asks for ``numba`` where neither numba nor a
        prebuilt module is installed.
    """
    global _auto
    name = asked()
    if name == "numpy" or _broken:
        return "numpy"
    if name == "numba":
        return "numba" if _prepare(strict=True) else "numpy"
    if _auto is None:
        _auto = "numba" if _prepare(strict=False) else "numpy"
    return _auto


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


class KernelNotice(UserWarning):
    """What became of the compiled engine in this process, when it is not the prebuilt kernels (one line)."""


#: Seconds this process spent loading the kernels (the prebuilt module, or numba and its cached machine
#: code) and building them (waiting for a build, or JIT compiles: ``numba:compile`` events, outermost
#: only); see :func:`costs`.
_COSTS = {"import": 0.0, "compile": 0.0}
_timer_installed = False
#: The kernel modules are imported (a backend was chosen and works).
_ready = False
#: The compiled engine failed in this process (numba's import, the module's init…): NumPy from now on.
_broken = False
#: This process's engine when none is asked for, once decided.
_auto: str | None = None
#: Why this process does not run the prebuilt module (None: it does, or has not decided).
aot_error: str | None = None


def backend() -> str:
    """``"aot"`` (the prebuilt extension module) or ``"jit"`` (numba), once the kernels are loaded; ``""``
    before (and with the NumPy engine)."""
    return jit.BACKEND.mode if _ready else ""


def _say(text: str) -> None:
    warnings.warn(clean(text, 400), KernelNotice, stacklevel=4)


def _prepare(strict: bool) -> bool:
    """Load the compiled kernels if they can be had now; False: this process uses the NumPy engine.

    ``strict`` (the compiled engine was asked for): wait for a build, else use numba's JIT. Otherwise:
    the prebuilt module if it is there and verified; if not, start its build in the background."""
    global aot_error
    if _ready or _broken:
        return _ready
    if not aot.enabled():
        return _import_kernels("jit", None, strict)
    t0 = time.perf_counter()
    entry = aot.lookup()
    if entry.state == "built":
        return _import_kernels("aot", entry.path, strict)
    if entry.state in ("missing", "damaged") and not strict:
        aot_error = entry.message or "not built yet"
        if not _numba_available():  # nothing could build it: the NumPy engine, quietly
            return False
        started, why = aot.build_in_background()
        damaged = entry.state == "damaged"
        head = f"the compiled kernels in the cache are not usable ({entry.message})" if damaged \
            else "compiled kernels not built yet"
        tail = why or (f"{'re' if damaged else ''}building them in the background" if started
                       else "another process is building them")
        _say(f"{head}: this run uses the NumPy engine; {tail}")
        return False
    if not _numba_available():  # asked for by name: say why it cannot be had
        raise BrdflabError("the numba engine needs the numba package (pip install numba), or use --engine numpy")
    if entry.state in ("missing", "damaged"):  # strict: wait for the build
        entry = aot.build()
        _COSTS["compile"] += time.perf_counter() - t0
        if entry.state == "built":
            return _import_kernels("aot", entry.path, strict)
    aot_error = entry.message
    fallback = "numba's JIT compiles them instead" if strict else "this run uses the NumPy engine"
    if entry.state == "refused":
        _say(f"{entry.message}; {fallback}")
    elif not entry.reported:
        where = f" (delete {entry.root / aot.key()} to try again)" if entry.root is not None else ""
        _say(f"the compiled kernels could not be prebuilt ({aot.summary(entry.message)}){where}; {fallback}")
        if entry.root is not None:
            with contextlib.suppress(OSError):
                (entry.root / aot.key() / cache.REPORTED).touch()
    return _import_kernels("jit", None, strict) if strict else False


def _import_kernels(mode: str, path, strict: bool) -> bool:
    """Import every kernel module with the ``"aot"`` module at ``path`` or the ``"jit"``; on any failure
    (the module's init raising, kernels missing from it, numba failing at import) one warning line, and
    the JIT instead of a failed prebuilt module when ``strict``, else the NumPy engine."""
    global _ready, _broken, aot_error
    t0, c0 = time.perf_counter(), _COSTS["compile"]
    try:
        if mode == "aot":
            jit.BACKEND.ext = aot.load_module(path)
            jit.BACKEND.mode = "aot"
        else:
            jit.BACKEND.mode = "jit"
            _install_compile_timer()
        for name in MODULES:
            importlib.import_module(f"brdflab.kernels.{name}")
    except (Exception, SystemExit) as e:
        for name in MODULES:  # nothing half-imported stays
            sys.modules.pop(f"brdflab.kernels.{name}", None)
        jit.BACKEND.mode, jit.BACKEND.ext = "jit", None
        what = f"the prebuilt kernel module {path}" if mode == "aot" else "numba's JIT"
        aot_error = f"{what} could not be loaded ({type(e).__name__}: {e})"
        if mode == "aot" and strict and _numba_available():
            _say(f"{aot_error}; numba's JIT compiles the kernels instead")
            return _import_kernels("jit", None, strict)
        _say(f"{aot_error}; this run uses the NumPy engine")
        _broken = True
        return False
    _ready = True
    _COSTS["import"] += time.perf_counter() - t0 - (_COSTS["compile"] - c0)
    return True


def load(name: str) -> ModuleType:
    """The kernel module ``brdflab.kernels.<name>`` (on first use: loads the kernels as the compiled engine
    would, waiting for a first build if needed).

    Raises
    ------
    BrdflabError
        When the compiled kernels cannot be loaded in this process.
    """
    if not _ready and not _prepare(strict=True):
        raise BrdflabError(f"the compiled kernels are not available ({clean(aot_error or '', 200)})")
    return sys.modules[f"brdflab.kernels.{name}"]


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


def ensure_built() -> bool:
    """Wait for the prebuilt kernels (building them now if needed), unless the NumPy engine is asked for or
    numba is missing: for runs whose every process must use the compiled engine from the start (the test
    suite's first step, ``brdflab bench``). True when the compiled kernels are loaded in this process."""
    if asked() == "numpy" or not _numba_available():
        return False
    with use_engine("numba"):
        return compiled()


def preload() -> None:
    """Decide the engine and load the kernels now (in a process about to fork workers, which then share
    them and the decision); nothing with the NumPy engine."""
    engine()


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


__all__ = ["ENGINES", "asked", "engine", "KernelNotice", "set_engine", "use_engine", "compiled", "load",
           "for_object", "twin", "preload", "ensure_built", "MODULES", "costs", "backend"]
