"""The one Numba decorator every kernel uses, and the argument types of the kernels.

* ``nopython``: no Python objects inside a kernel.
* One explicit signature per kernel, with arrays of any layout (``"A"``: C, Fortran or strided views all
  fit) and inputs typed read-only (writable arrays fit too): each kernel is compiled once, when its module
  is imported, so a process that imports the kernels before it forks its workers hands them the machine
  code (:func:`brdflab.kernels.preload`) instead of each worker loading it on its first call. The
  wrappers convert arguments to these types (float64 directions, int64 indices).
* ``cache=True``: the machine code is stored beside the module (``__pycache__``), so a second process loads
  it instead of compiling.
* ``error_model="numpy"``: a division by zero gives ±inf/NaN as in NumPy (the NumPy code relies on it
  and masks afterwards), not a Python exception.
* ``fastmath=False``: IEEE arithmetic, no reassociation and no fused multiply-add contraction, so the
  kernels round like the NumPy code they mirror.
* ``nogil=True``: threads (Dask's threaded workers) can run kernels side by side.
"""

from __future__ import annotations

import numba
from numba import types

OPTIONS = dict(nopython=True, cache=True, error_model="numpy", fastmath=False, nogil=True)

F8, F4, I8, BOOL = types.float64, types.float32, types.int64, types.boolean


def array(dtype, ndim: int, out: bool = False):
    """Array type of any layout; read-only unless it is an output."""
    return types.Array(dtype, ndim, "A", readonly=not out)


IN1, IN2, IN1_F4, IDX, FLAGS = array(F8, 1), array(F8, 2), array(F4, 1), array(I8, 1), array(BOOL, 1)
OUT1, OUT2, OUT3 = array(F8, 1, True), array(F8, 2, True), array(F8, 3, True)


def kernel(*argtypes):
    """Compile the decorated function for ``void(*argtypes)`` with :data:`OPTIONS` (or load it from the
    disk cache), now."""
    def wrap(fn):
        return numba.jit(types.void(*argtypes), **OPTIONS)(fn)

    return wrap


def inline(fn):
    """A scalar helper called from kernels (compiled into its callers)."""
    return numba.jit(inline="always", **OPTIONS)(fn)
