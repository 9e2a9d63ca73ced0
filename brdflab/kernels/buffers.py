"""Output arrays of the kernels, laid out so that their columns do not alias in the cache.

A render unit holds 65 536 samples (32 × 32 pixels × 64 spp), so an (N, 3) Fortran-ordered float64 array
has columns exactly 512 KiB apart, and arrays of one size allocated one after the other start a few bytes
apart modulo 4 KiB. A kernel that streams through a dozen such columns (the shading points write p, n_g,
n_s, ω_i, σ and a while reading d) then loads and stores addresses equal in their low 12 bits at every
step, which the CPU treats as possible dependencies (*4K aliasing*): the shading-point kernel took 29 ns a
point with the outputs so placed and 13 ns with :func:`columns` (course Cornell box, 2026-12-03, Intel Xeon).

:func:`columns` carves a kernel's outputs from one buffer, each column starting :data:`STEP` bytes (three
cache lines) after the previous one modulo 4 KiB. The arrays are ordinary strided NumPy views (column
slices contiguous, not ``f_contiguous`` as a whole); the values a kernel writes are the same.
"""

from __future__ import annotations

import numpy as np

#: The aliasing period (bytes) and the stagger between consecutive columns (three 64-byte cache lines).
PAGE, STEP = 4096, 192


def columns(m: int, widths: list[int | None], dtype=np.float64) -> list[np.ndarray]:
    """Uninitialised arrays of ``m`` rows from one buffer: ``(m, w)`` for an int ``w``, ``(m,)`` for None,
    each column starting :data:`STEP` bytes after the previous one modulo :data:`PAGE`.

    Examples
    --------
    >>> p, pdf = columns(65536, [3, None])
    >>> p.shape, pdf.shape, p.strides[1] % PAGE
    ((65536, 3), (65536,), 192)
    >>> sorted({a.__array_interface__["data"][0] % PAGE for a in (p[:, 0], p[:, 1], p[:, 2], pdf)})
    [0, 192, 384, 576]
    """
    item = np.dtype(dtype).itemsize
    n_cols = sum(1 if w is None else w for w in widths)
    size = m * item
    stride = size + (STEP - size) % PAGE  # ≥ the column, ≡ STEP (mod PAGE)
    buf = np.empty((stride * n_cols + PAGE) // item, dtype)
    start = (-buf.__array_interface__["data"][0]) % PAGE  # the first column on a page boundary
    out, q = [], 0
    for w in widths:
        shape, strides = ((m,), (item,)) if w is None else ((m, w), (item, stride))
        out.append(np.ndarray(shape, dtype, buf, offset=start + q * stride, strides=strides))
        q += 1 if w is None else w
    return out
