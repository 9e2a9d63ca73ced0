"""Kernels of the film and camera (compiled engine): the splat and the camera rays of a unit.

**Camera rays** (:meth:`brdflab.film.Camera.unit_rays`): per sample, s = ξ + pixel + tile origin, the
image-plane point x = c_x·s_x + t_x, y = c_y·s_y + t_y, ℓ = ‖(x, y, 1)‖, the direction
d_j = (m_j0 x + m_j1 y + m_j2)/ℓ (zero matrix entries skipped, as the NumPy code skips them), the origin
moved to the near plane, o = c + d·ℓ·near (float32), and tmax = ℓ·(far − near): the same operations in the
same order as the NumPy code, so the two agree to the bit.

**Splat** (:meth:`brdflab.film.Film.splat` for tabulated filters).

Each sample adds w_x·w_y·(L, 1) to the taps² pixels around it, with the first tap and the sub-pixel
phase found as in :meth:`~brdflab.film.Film._taps` and the weights read from the filter's phase table
(:class:`~brdflab.film.Filter`). Two passes, as in the NumPy code, chosen by their cost:

* ``splat`` (direct): taps² multiply-adds of (L, 1) per sample, accumulated in a pixel-interleaved buffer
  (one cache line per tap) and then added to the film's channel planes;
* ``splat_rows`` (separable, when there are at least phases/taps samples per pixel, e.g. from 4 spp with the
  default Gaussian): the x pass of each sample, w_x·(L, 1) over its taps, into a row of
  G[first row, y phase] (taps multiply-adds instead of taps²), then every row of G that received a sample
  added to the taps image rows below it with the weights w_y of its phase. 2.6× faster than the direct pass
  at 64 spp (14 against 36 ns per sample), slower below 4 spp (G has pixels × phases rows).

The NumPy code sums the same products in another order (per channel with ``bincount``, then the y pass as a
matrix product), so the engines agree to rounding (1e-12 relative), not to the bit.
"""

from __future__ import annotations

import math

import numpy as np

from brdflab.kernels.buffers import columns
from brdflab.kernels.jit import F8, I8, IDX, IN1, IN2, OUT1, OUT2, OUT2_F4, OUT3, inline, kernel


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


@kernel(IN1, IN1, IN2, OUT3, IN2, IDX, I8, I8, I8, I8, I8)
def splat_rows(sx, sy, values, data, wt, offset, nph, bits, taps, shift_x, shift_y):
    """:func:`splat` by the separable pass (module doc): the same arguments and sums, in another order."""
    bh, bw = data.shape[1], data.shape[2]
    g = np.zeros((bh, nph, 4, bw))
    used = np.zeros((bh, nph), np.bool_)
    for i in range(sx.shape[0]):
        fx, phx = _first_tap(sx[i], nph, bits, offset, shift_x, bw, taps)
        fy, phy = _first_tap(sy[i], nph, bits, offset, shift_y, bh, taps)
        r, gr, b = values[i, 0], values[i, 1], values[i, 2]
        used[fy, phy] = True
        row = g[fy, phy]
        for kx in range(taps):
            w = wt[kx, phx]
            x = fx + kx
            row[0, x] += w * r
            row[1, x] += w * gr
            row[2, x] += w * b
            row[3, x] += w
    acc = np.zeros((4, bh, bw))
    for fy in range(bh):
        for ph in range(nph):
            if not used[fy, ph]:
                continue
            row = g[fy, ph]
            for ky in range(taps):
                wy = wt[ky, ph]
                out = acc[:, fy + ky]
                for c in range(4):
                    for x in range(bw):
                        out[c, x] += wy * row[c, x]
    for c in range(4):
        for y in range(bh):
            for x in range(bw):
                data[c, y, x] += acc[c, y, x]


#: Largest row buffer G of the separable pass, in bytes (above it, the direct pass).
ROWS_BYTES = 1 << 24


def separable(n: int, film) -> bool:
    """Whether ``n`` samples into ``film`` take the separable pass: at least phases/taps samples per buffer
    pixel (there it costs less than the direct pass), with G within :data:`ROWS_BYTES`."""
    f = film.filter
    cells = film.bh * film.bw * f.phases
    return n * f.phase_taps >= cells and 32 * cells <= ROWS_BYTES


def splat_film(film, sx: np.ndarray, sy: np.ndarray, values: np.ndarray, rows: bool | None = None) -> None:
    """:meth:`brdflab.film.Film.splat`, compiled (the film's filter must have phase tables); ``rows``
    forces the separable (True) or direct (False) pass, else :func:`separable` picks."""
    f = film.filter
    bits = -1 if f.phase_bits is None else f.phase_bits
    if rows is None:
        rows = separable(len(sx), film)
    (splat_rows if rows else splat)(
        np.asarray(sx, np.float64), np.asarray(sy, np.float64), np.asarray(values, np.float64), film.data,
        f.phase_weights_t, f.phase_offset, f.phases, bits, f.phase_taps, film.border - film.x0,
        film.border - film.y0)


@inline
def _combination(x, y, k0, k1, k2):
    """k0·x + k1·y + k2 with the zero coefficients skipped, in the order of
    :func:`~brdflab.math.frame.sparse_combination`."""
    if k0 != 0.0:
        c = x * k0
        if k1 != 0.0:
            c += y * k1
    elif k1 != 0.0:
        c = y * k1
    else:
        return k2
    if k2 != 0.0:
        c += k2
    return c


@kernel(IN2, IN1, IN1, F8, F8, IN1, IN2, IN1, OUT1, OUT1, OUT2_F4, OUT2, OUT1)
def camera_rays(jitter, px, py, x0, y0, coef, m, origin, sx, sy, o, d, tmax):
    """Sample positions, float32 origins, unit directions and tmax of a unit's camera rays (module doc).
    ``coef`` = (c_x, t_x, c_y, t_y, near, far − near); ``m`` the camera-to-world rotation rows."""
    cx, tx, cy, ty, near, span = coef[0], coef[1], coef[2], coef[3], coef[4], coef[5]
    for i in range(px.shape[0]):
        a = jitter[0, i] + px[i]
        a += x0
        b = jitter[1, i] + py[i]
        b += y0
        sx[i], sy[i] = a, b
        x = a * cx
        x += tx
        y = b * cy
        y += ty
        ln = x * x
        ln += y * y
        ln += 1.0
        ln = math.sqrt(ln)
        inv = 1.0 / ln
        nl = ln * near
        for j in range(3):
            c = _combination(x, y, m[j, 0], m[j, 1], m[j, 2]) * inv
            d[i, j] = c
            oc = c * nl
            oc += origin[j]
            o[i, j] = np.float32(oc)
        tmax[i] = ln * span


def unit_rays(cam, jitter: np.ndarray, px: np.ndarray, py: np.ndarray, x0: int, y0: int):
    """:meth:`brdflab.film.Camera.unit_rays`, compiled."""
    from brdflab.math.transform import Transform

    n = px.shape[0]
    xf = cam.to_world if cam.to_world is not None else Transform()
    coef = np.array([*cam.ray_coefficients(), cam.near, cam.far - cam.near])
    d, sx, sy, tmax = columns(n, [3, None, None, None])
    o = np.empty((n, 3), np.float32)
    camera_rays(np.asarray(jitter, np.float64), np.asarray(px, np.float64), np.asarray(py, np.float64), float(x0),
                float(y0), coef, np.asarray(xf.matrix, np.float64), np.asarray(xf.origin(), np.float64), sx, sy, o, d,
                tmax)
    return sx, sy, o, d, tmax
