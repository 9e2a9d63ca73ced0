"""Kernels of the film and camera (compiled engine): the splat and the camera rays of a unit.

**Camera rays** (:meth:`brdflab.film.Camera.unit_rays`): per sample, s = ξ + pixel + tile origin, the
image-plane point x = c_x·s_x + t_x, y = c_y·s_y + t_y, ℓ = ‖(x, y, 1)‖, the direction
d_j = (m_j0 x + m_j1 y + m_j2)/ℓ (zero matrix entries skipped, as the NumPy code skips them), the origin
moved to the near plane, o = c + d·ℓ·near (float32), and tmax = ℓ·(far − near): the same operations in the
same order as the NumPy code, so the two agree to the bit.

**Splat** (:meth:`brdflab.film.Film.splat` for tabulated filters).

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


def splat_film(film, sx: np.ndarray, sy: np.ndarray, values: np.ndarray) -> None:
    """:meth:`brdflab.film.Film.splat`, compiled (the film's filter must have phase tables)."""
    f = film.filter
    bits = -1 if f.phase_bits is None else f.phase_bits
    splat(np.asarray(sx, np.float64), np.asarray(sy, np.float64), np.asarray(values, np.float64), film.data,
 f.phase_weights_t, f.phase_offset, f.phases, bits, f.phase_taps,
          film.border - film.x0, film.border - film.y0)


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
    sx, sy, tmax = np.empty(n), np.empty(n), np.empty(n)
    o, d = np.empty((n, 3), np.float32), np.empty((n, 3), order="F")
    camera_rays(np.asarray(jitter, np.float64), np.asarray(px, np.float64), np.asarray(py, np.float64), float(x0),
                float(y0), coef, np.asarray(xf.matrix, np.float64), np.asarray(xf.origin(), np.float64), sx, sy, o, d,
                tmax)
    return sx, sy, o, d, tmax
