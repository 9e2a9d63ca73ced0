"""The one decorator every kernel uses, the argument types of the kernels, and the two ways they are built.

A kernel is a scalar Numba function ``void(*argtypes)``. What :func:`kernel` returns depends on the
backend the process chose before it imported the kernel modules (:func:`brdflab.kernels.load`):

* ``"aot"`` (when it can be had): the function of the same name in the kernels' extension module, built
  ahead of time by :mod:`brdflab.kernels.aot` and loaded **without importing numba** (a few ms instead of
  0.5 s per process), behind a guard that checks the arrays' dtype, dimensions and writability (a
  compiled function given the wrong array would read or write out of bounds).
* ``"jit"``: ``numba.jit`` with the options below, compiled when the module is imported or loaded from
  numba's disk cache; also what the ahead-of-time build compiles from.

The compile options (both backends):

* ``nopython``: no Python objects inside a kernel.
* One explicit signature per kernel, with arrays of any layout (``"A"``: C, Fortran or strided views all
  fit) and inputs typed read-only (writable arrays fit too). The wrappers convert arguments to these types
  (float64 directions, int64 indices).
* ``cache=True``: the JIT's machine code is stored on disk, in ``jit/<hash of every kernel source>`` under the
  kernels' cache folder (:func:`brdflab.kernels.cache.writable_root`; no disk cache without one). Numba's own
  default, ``__pycache__`` beside the module, is keyed by the function's own file only: after an edit of a
  helper inlined from another file (``scalar.py``, ``shading.py``) it loaded the old machine code — and so
  did the ahead-of-time build, which compiles through the JIT (a mutation of ``scalar.beckmann_d`` ran the
  unmutated kernels; ``tests/test_kernel_cache.py`` edits a helper and checks).
* ``error_model="numpy"``: a division by zero gives ±inf/NaN as in NumPy (the NumPy code relies on it
  and masks afterwards), not a Python exception.
* ``fastmath=False``: IEEE arithmetic, no reassociation and no fused multiply-add contraction, so the
  kernels round like the NumPy code they mirror.
* ``nogil=True`` (JIT only): threads can run kernels side by side (brdflab's workers are processes).
"""

from __future__ import annotations

import functools
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

import numpy as np

from brdflab.kernels import cache

OPTIONS = dict(nopython=True, cache=True, error_model="numpy", fastmath=False, nogil=True)


@dataclass(frozen=True)
class Arg:
    """One kernel argument: a NumPy dtype name, 0 for a scalar or the number of array dimensions, and
    whether the kernel writes it."""

    dtype: str
    ndim: int = 0
    out: bool = False

    def numba_type(self):
        """The Numba type (arrays of any layout, read-only unless an output)."""
        from numba import types

        t = types.boolean if self.dtype == "bool" else getattr(types, self.dtype)
        return t if self.ndim == 0 else types.Array(t, self.ndim, "A", readonly=not self.out)


F8, F4, I8, BOOL = Arg("float64"), Arg("float32"), Arg("int64"), Arg("bool")
IN1, IN2, IN1_F4, IDX, FLAGS = Arg("float64", 1), Arg("float64", 2), Arg("float32", 1), Arg("int64", 1), Arg("bool", 1)
OUT1, OUT2, OUT3 = Arg("float64", 1, True), Arg("float64", 2, True), Arg("float64", 3, True)
OUT1_F4, OUT2_F4, OUT_IDX = Arg("float32", 1, True), Arg("float32", 2, True), Arg("int64", 1, True)
OUT_FLAGS = Arg("bool", 1, True)


class _Backend:
    mode = "jit"
    ext: ModuleType | None = None


BACKEND = _Backend()

#: Every kernel defined in this process under the JIT backend: (export name, dispatcher, argument types),
#: what the ahead-of-time build exports.
KERNELS: list[tuple[str, Callable, tuple[Arg, ...]]] = []


def export_name(fn: Callable) -> str:
    """``<module>__<function>``: the kernel's name in the extension module (``bsdf__diffuse``)."""
    return f"{fn.__module__.rsplit('.', 1)[-1]}__{fn.__name__}"


def kernel(*argtypes: Arg):
    """A kernel ``void(*argtypes)``: the prebuilt function (``"aot"`` backend) or ``numba.jit`` with
    :data:`OPTIONS`, compiled or loaded from the disk cache now (``"jit"``)."""
    def wrap(fn):
        if BACKEND.mode == "aot":
            return guarded(getattr(BACKEND.ext, export_name(fn)), export_name(fn), argtypes)
        from numba import types

        disp = _jit(fn, types.void(*(a.numba_type() for a in argtypes)))
        KERNELS.append((export_name(fn), disp, argtypes))
        return disp

    return wrap


def inline(fn):
    """A scalar helper called from kernels (compiled into its callers; left as Python under ``"aot"``,
    where nothing calls it)."""
    if BACKEND.mode == "aot":
        return fn
    return _jit(fn, inline="always")


@functools.cache
def jit_cache_folder() -> Path | None:
    """Where the JIT keeps its machine code: ``<cache root>/jit/<hash of the kernel sources>`` (None: no safe
    cache folder, or ``BRDFLAB_JIT_CACHE=0`` as the ahead-of-time builder sets: no disk cache)."""
    if os.environ.get("BRDFLAB_JIT_CACHE", "1").strip() == "0":  # the ahead-of-time builder: compiles afresh
        return None
    root, _ = cache.writable_root()
    return None if root is None else root / "jit" / cache.sources_hash()[:20]


def _jit(fn, *args, **options):
    """``numba.jit(*args, **OPTIONS, **options)(fn)`` with its disk cache in :func:`jit_cache_folder` (numba
    reads the folder when the dispatcher is made, so it is set only around that; a user's own numba
    functions keep theirs)."""
    import numba
    from numba.core import config

    folder = jit_cache_folder()
    saved = config.CACHE_DIR
    if folder is not None:
        config.CACHE_DIR = str(folder)
    try:
        return numba.jit(*args, **{**OPTIONS, **options, "cache": folder is not None})(fn)
    finally:
        config.CACHE_DIR = saved


def guarded(fn: Callable, name: str, argtypes: tuple[Arg, ...]) -> Callable:
    """``fn`` (a prebuilt kernel, which trusts its arguments' memory layout) behind a check of the argument
    count and of each array argument's type, dtype, dimensions and, for outputs, writability."""
    arrays = [(i, np.dtype(a.dtype), a.ndim, a.out) for i, a in enumerate(argtypes) if a.ndim]
    count = len(argtypes)

    def call(*args):
        if len(args) != count:
            raise TypeError(f"kernel {name} takes {count} arguments, not {len(args)}")
        for i, dt, nd, out in arrays:
            a = args[i]
            if not isinstance(a, np.ndarray) or a.dtype != dt or a.ndim != nd or (out and not a.flags.writeable):
                raise TypeError(f"kernel {name}: argument {i} must be a {'writable ' if out else ''}{nd}-d {dt} "
                                f"array, not {_describe(a)}")
        fn(*args)

    call.__name__ = call.__qualname__ = name
    return call


def _describe(a: object) -> str:
    if not isinstance(a, np.ndarray):
        return f"a {type(a).__name__}"
    return f"a {a.ndim}-d {a.dtype} array{'' if a.flags.writeable else ' (read-only)'}"
