"""Kernel of the film splat (compiled engine): :meth:`brdflab.film.Film.splat` for tabulated filters.

Each sample adds w_x·w_y·(L, 1) to the taps² pixels around it, with the first tap and the sub-pixel
phase found as in :meth:`~brdflab.film.Film._taps` and the weights read from the filter's phase table
(:class:`~brdflab.film.Filter`). The NumPy code sums the same products in another order (per channel with
``bincount``, then the y pass as a matrix product), so the two agree to rounding (1e-12 relative), not to
the bit. The sums accumulate in a pixel-interleaved buffer (one cache line per tap) before they are added
to the film's channel planes.
"""

from __future__ import annotations

import math

import numpy as np

from brdflab.kernels.jit import I8, IDX, IN1, IN2, OUT3, inline, kernel


@inline
def _first_tap(s, nph, bits, offset, shift, extent, taps):
    """(first tap, phase) of position ``s`` on one axis (:meth:`Film._taps`)."""
    if bits >= 0:
        t = int(math.floor(s * nph - 0.5 * nph))
        ph = t & (nph - 1)
        first = t >> bits
    else:
        q = s - 0.5
        fq = math.floor(q)
        ph = min(int((q - fq) * nph), nph - 1)
        first = int(fq)
    first += offset[ph] + shift
    return min(max(first, 0), extent - taps), ph


@kernel(IN1, IN1, IN2, OUT3, IN2, IDX, I8, I8, I8, I8, I8)
def splat(sx, sy, values, data, wt, offset, nph, bits, taps, shift_x, shift_y):
    """Add samples at (sx, sy) with RGB ``values`` into ``data`` (4, rows, columns)."""
    bh, bw = data.shape[1], data.shape[2]
    acc = np.zeros((bh, bw, 4))
    for i in range(sx.shape[0]):
        fx, phx = _first_tap(sx[i], nph, bits, offset, shift_x, bw, taps)
        fy, phy = _first_tap(sy[i], nph, bits, offset, shift_y, bh, taps)
        r, g, b = values[i, 0], values[i, 1], values[i, 2]
        for ky in range(taps):
            wy = wt[ky, phy]
            for kx in range(taps):
                w = wy * wt[kx, phx]
                cell = acc[fy + ky, fx + kx]
                cell[0] += w * r
                cell[1] += w * g
                cell[2] += w * b
                cell[3] += w
    for y in range(bh):
        for x in range(bw):
            for c in range(4):
                data[c, y, x] += acc[y, x, c]


def splat_film(film, sx: np.ndarray, sy: np.ndarray, values: np.ndarray) -> None:
    """:meth:`brdflab.film.Film.splat`, compiled (the film's filter must have phase tables)."""
    f = film.filter
    bits = -1 if f.phase_bits is None else f.phase_bits
    splat(np.asarray(sx, np.float64), np.asarray(sy, np.float64), np.asarray(values, np.float64), film.data,
 f.phase_weights_t, f.phase_offset, f.phases, bits, f.phase_taps,
          film.border - film.x0, film.border - film.y0)
