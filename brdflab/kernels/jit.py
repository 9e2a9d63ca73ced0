"""The one Numba decorator every kernel uses.

* ``nopython``: no Python objects inside a kernel.
* ``cache=True``: compiled code is stored beside the module (``__pycache__``), so a second process loads
  it instead of compiling.
* ``error_model="numpy"``: a division by zero gives ±inf/NaN as in NumPy (the NumPy code relies on it
  and masks afterwards), not a Python exception.
* ``fastmath=False``: IEEE arithmetic, no reassociation and no fused multiply-add contraction, so the
  kernels round like the NumPy code they mirror.
* ``nogil=True``: threads (Dask's threaded workers) can run kernels side by side.
"""

from __future__ import annotations

import numba

OPTIONS = dict(nopython=True, cache=True, error_model="numpy", fastmath=False, nogil=True)


def kernel(fn):
    """Compile ``fn`` with :data:`OPTIONS` (lazily, per argument types; cached on disk)."""
    return numba.jit(**OPTIONS)(fn)


def inline(fn):
    """A scalar helper called from kernels (compiled into its callers)."""
    return numba.jit(inline="always", **OPTIONS)(fn)
