"""Camera rays, reconstruction filters and the film (spec §4–6).

Perspective camera (spec §4): a sample at continuous pixel position (p_x, p_y) (origin top-left) maps to
u = p_x/W, v = p_y/H and the camera-space direction d̂ = normalize((1 − 2u)T, (1 − 2v)T/a, 1), with
T = tan(fov/2), a = W/H, horizontal fov. Camera +x is the image's **left**. The world ray is
(M·0, M₃ₓ₃·d̂) with t ∈ [near/d̂_z, far/d̂_z].

Reconstruction filters (spec §6), tabulated at 32 entries over the radius as Nori does:

=============  =====================  =======================================================
``type``       parameters (float)     f(x), x ≥ 0
=============  =====================  =======================================================
``gaussian``   radius 2, stddev 0.5   max(0, exp(−x²/2σ²) − exp(−r²/2σ²))
``mitchell``   radius 2, B, C = 1/3   Mitchell–Netravali cubic in |2x/r|
``tent``       —                      max(0, 1 − |x|), radius 1
``box``        —                      1, radius 0.5
=============  =====================  =======================================================

Splatting: with q = s − (0.5, 0.5), pixels x ∈ [⌈q_x − r⌉, ⌊q_x + r⌋] (same for y) receive weight
F(|x − q_x|)·F(|y − q_y|); the pixel value is Σ wL / Σ w.

Because F is tabulated in bins of r/32, the taps and weights of a sample depend only on its sub-pixel
*phase* ⌊32·frac(q)/r⌋ whenever 32/r is an integer (all of Nori's default filters). The splat is then
separable and exact: the x taps are scattered with ``np.bincount`` into a buffer indexed by (row, y
phase, column), and a small dense product applies the y weights per phase. Other radii use the direct
2-D scatter.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from brdflab.kernels import compiled, load, twin
from brdflab.math.frame import sparse_combination
from brdflab.math.transform import Transform
from brdflab.scene.properties import PropertyList

FILTER_TABLE = 32


@dataclass
class Camera:
    """Nori's perspective camera (spec §4)."""

    width: int = 1280
    height: int = 720
    fov: float = 30.0
    near: float = 1e-4
    far: float = 1e4
    to_world: Transform | None = None

    KNOWN = {"width": "integer", "height": "integer", "fov": "float", "nearClip": "float",
             "farClip": "float", "toWorld": "transform"}
    MAX_PIXELS = 64_000_000

    @classmethod
    def from_properties(cls, props: PropertyList) -> Camera:
        """Build and validate a ``<camera type="perspective">``."""
        props.check_known(cls.KNOWN)
        w, h = props.get_int("width", 1280), props.get_int("height", 720)
        for name, v in (("width", w), ("height", h)):
            if v <= 0:
                raise props.error(name, f"'{name}' must be a positive integer, got {v}")
        if w * h > cls.MAX_PIXELS:
            mb = w * h * 3 * 4 * 4 / 2**20
            raise props.error("width", f"image of {w}×{h} pixels is too large (limit {cls.MAX_PIXELS:,} "
                              f"pixels; the film alone would need about {mb:,.0f} MiB)")
        fov = props.get_float("fov", 30.0)
        if not (0.0 < fov < 180.0):
            raise props.error("fov", f"'fov' must be strictly between 0 and 180 degrees, got {fov}")
        near = props.positive_float("nearClip", 1e-4)
        far = props.positive_float("farClip", 1e4)
        if far <= near:
            raise props.error("farClip", f"'farClip' ({far}) must be greater than 'nearClip' ({near})")
        return cls(w, h, fov, near, far, props.get_transform("toWorld", Transform()))

    #: The compiled twin of :meth:`unit_rays` (:mod:`brdflab.kernels.film`); subclasses take the NumPy path.
    kernel = "perspective"

    def ray_coefficients(self) -> tuple[float, float, float, float]:
        """(c_x, t_x, c_y, t_y) of the affine maps x = c_x·p_x + t_x and y = c_y·p_y + t_y from continuous
        pixel positions to the image plane at distance 1 (spec §4): x = (1 − 2 p_x/W)·T, y = (1 − 2 p_y/H)·T/a
        with T = tan(fov/2) and a = W/H."""
        a = self.width / self.height
        t = np.tan(np.radians(self.fov) * 0.5)
        return float(-2.0 * t / self.width), float(t), float(-2.0 * t / (a * self.height)), float(t / a)

    def generate_rays(self, px: np.ndarray, py: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Rays through continuous pixel positions; returns (origins, unit directions, tmax).

        The origins are float32 and C-ordered, the layout Embree takes (they serve only as ray origins);
        the directions are float64, Fortran-ordered.
        """
        cx, tx, cy, ty = self.ray_coefficients()
        xf = self.to_world if self.to_world is not None else Transform()
        m, origin = xf.matrix, xf.origin()
        x = px * cx
        x += tx
        y = py * cy
        y += ty
        length = x * x  # ‖(x, y, 1)‖ = 1/d̂_z
        length += y * y
        length += 1.0
        np.sqrt(length, out=length)
        inv_len = 1.0 / length
        n = len(px)
        d = np.empty((n, 3), order="F")
        o = np.empty((n, 3), np.float32)
        near = length * self.near  # t_min = near / d̂_z, applied by moving the origin along the ray
        for j in range(3):
            # d_j = (m_j0 x + m_j1 y + m_j2)/‖·‖ (zero matrix entries skipped).
            c = sparse_combination((x, y), (m[j, 0], m[j, 1]), m[j, 2], out=d[:, j])
            c *= inv_len
            oc = c * near
            oc += origin[j]
            o[:, j] = oc
        length *= self.far - self.near
        return o, d, length

    @twin("film", "unit_rays")
    def unit_rays(self, jitter: np.ndarray, px: np.ndarray, py: np.ndarray, x0: int,
                  y0: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The camera rays of a render unit: sample positions s = ξ + pixel + tile origin for ``jitter``
        (2, N) in [0, 1) (overwritten) and the pixel columns and rows ``px``, ``py`` of the tile; returns
        (s_x, s_y, origins, directions, tmax) as :meth:`generate_rays`."""
        sx = jitter[0]
        sx += px
        sx += x0
        sy = jitter[1]
        sy += py
        sy += y0
        return (sx, sy, *self.generate_rays(sx, sy))


class Filter:
    """A tabulated, separable reconstruction filter (spec §6)."""

    KNOWN = {
        "gaussian": {"radius": "float", "stddev": "float"},
        "mitchell": {"radius": "float", "B": "float", "C": "float"},
        "tent": {},
        "box": {},
    }

    #: Accepted filter radii in pixels: below 1/4 most pixels would receive no sample; above 64 the tile
    #: films' borders would dwarf the tiles.
    RADIUS_RANGE = (0.25, 64.0)
    #: Largest number of sub-pixel phases tabulated for the separable splat (radii ≥ 32/4096).
    MAX_PHASES = 4096

    def __init__(self, kind: str = "gaussian", radius: float = 2.0, stddev: float = 0.5,
                 b: float = 1.0 / 3.0, c: float = 1.0 / 3.0) -> None:
        self.kind = kind
        if kind == "tent":
            radius = 1.0
        elif kind == "box":
            radius = 0.5
        self.radius = radius
        x = radius * np.arange(FILTER_TABLE) / FILTER_TABLE
        if kind == "gaussian":
            s2 = 2 * np.float64(stddev) ** 2  # NumPy scalars: σ → 0 gives inf/nan (checked by the caller), no exception
            f = np.maximum(0.0, np.exp(-x * x / s2) - np.exp(-radius * radius / s2))
        elif kind == "tent":
            f = np.maximum(0.0, 1.0 - np.abs(x))
        elif kind == "box":
            f = np.ones_like(x)
        else:
            xx = np.abs(2.0 * x / radius)
            f = np.where(
                xx < 1,
                (12 - 9 * b - 6 * c) * xx**3 + (-18 + 12 * b + 6 * c) * xx**2 + (6 - 2 * b),
                np.where(xx < 2, (-b - 6 * c) * xx**3 + (6 * b + 30 * c) * xx**2 + (-12 * b - 48 * c) * xx
                         + (8 * b + 24 * c), 0.0),
            ) / 6.0
        self.table = np.append(f, 0.0)
        self.taps = int(np.floor(2 * radius)) + 1
        # Phase tables for the separable splat (see the module docstring).
        phases = FILTER_TABLE / radius
        self.phases = int(round(phases)) if abs(phases - round(phases)) < 1e-9 and phases <= self.MAX_PHASES else 0
        #: log₂ of the phase count when it is a power of two (the default filters: 16, 32, 64), else None.
        self.phase_bits = (self.phases.bit_length() - 1 if self.phases and self.phases & (self.phases - 1) == 0
                           else None)
        if self.phases:
            c = (np.arange(self.phases) + 0.5) / self.phases
            self.phase_offset = np.ceil(c - radius).astype(np.int64)
            self.phase_weights = self.weights(self.phase_offset[:, None] + np.arange(self.taps) - c[:, None])
            # Taps that are zero for every phase (the last one, for the filters above) are dropped.
            used = np.flatnonzero(np.any(self.phase_weights != 0, axis=0))
            self.phase_taps = int(used[-1]) + 1 if len(used) else 1
            self.phase_weights = self.phase_weights[:, : self.phase_taps]
            self.phase_weights_t = np.ascontiguousarray(self.phase_weights.T)  # (phase taps, phases)

    @classmethod
    def from_properties(cls, kind: str, props: PropertyList) -> Filter:
        """Build from an ``<rfilter>`` of the given type."""
        props.check_known(cls.KNOWN[kind])
        if kind == "gaussian":
            radius = props.finite_float("radius", 2.0, *cls.RADIUS_RANGE)
            stddev = props.positive_float("stddev", 0.5)
            name = "stddev"
            with np.errstate(all="ignore"):
                filt = cls(kind, radius, stddev)
        elif kind == "mitchell":
            radius = props.finite_float("radius", 2.0, *cls.RADIUS_RANGE)
            b, c = props.finite_float("B", 1 / 3), props.finite_float("C", 1 / 3)
            name = "B"
            filt = cls(kind, radius, b=b, c=c)
        else:
            return cls(kind)
        # A degenerate parameter (σ = 1e-200 divides by zero; B and C that cancel the cubic) leaves a table
        # with no positive weight: every pixel would stay black.
        if not (np.all(np.isfinite(filt.table)) and filt.table.max() > 0):
            raise props.error(name, f"the {kind} filter's weights are zero or not finite with these parameters")
        return filt

    def weights(self, d: np.ndarray) -> np.ndarray:
        """Tabulated filter value at distances ``d`` (entry ⌊d·32/r⌋, 0 beyond the radius)."""
        idx = np.minimum((np.abs(d) * (FILTER_TABLE / self.radius)).astype(np.int64), FILTER_TABLE)
        return self.table[idx]


class Film:
    """Accumulates filtered samples (Σ wL, Σ w) of a region of the image, with a border for the filter.

    The accumulator ``data`` is channel-first, shape (4, rows, columns): Σ wL_r, Σ wL_g, Σ wL_b, Σ w,
    so that every channel is one contiguous plane.

    Parameters
    ----------
    width, height
        Full image size.
    filt
        The reconstruction filter.
    x0, y0, w, h
        The accumulated region (default: the whole image).
    """

    def __init__(self, width: int, height: int, filt: Filter, x0: int = 0, y0: int = 0,
                 w: int | None = None, h: int | None = None, data: np.ndarray | None = None) -> None:
        self.width, self.height, self.filter = width, height, filt
        self.border = int(np.ceil(filt.radius)) + 1
        self.x0, self.y0 = x0, y0
        self.w = width if w is None else w
        self.h = height if h is None else h
        b = self.border
        self.bw, self.bh = self.w + 2 * b, self.h + 2 * b
        self.data = np.zeros((4, self.bh, self.bw)) if data is None else data

    def splat(self, sx: np.ndarray, sy: np.ndarray, values: np.ndarray) -> None:
        """Add samples at continuous image positions (sx, sy) with RGB ``values`` (N, 3)."""
        if len(sx) == 0:
            return
        if self.filter.phases and compiled():
            load("film").splat_film(self, sx, sy, values)
            return
        # The separable pass costs ∝ samples·taps + pixels·phases·taps, the direct one ∝ samples·taps²:
        # pick the cheaper.
        f = self.filter
        if f.phases and f.phase_taps >= 2 and 4 * len(sx) * f.phase_taps >= self.bh * self.bw * f.phases:
            self._splat_separable(sx, sy, values)
        else:
            self._splat_direct(sx, sy, values)

    def _taps(self, s: np.ndarray, origin: int, extent: int) -> tuple[np.ndarray, np.ndarray]:
        """First tap (buffer coordinate, clipped) and phase of continuous positions ``s`` on one axis."""
        f = self.filter
        if f.phase_bits is not None:
            # 2^k phases: ⌊(s − ½)·P⌋ = ⌊q⌋·P + phase exactly (scaling by a power of two is exact), so one
            # floor gives both, split by a shift and a mask.
            t = s * f.phases
            t -= 0.5 * f.phases
            np.floor(t, out=t)
            it = t.astype(np.intp)
            ph = it & (f.phases - 1)
            first = it >> f.phase_bits
        else:
            q = s - 0.5
            fq = np.floor(q)
            ph = ((q - fq) * f.phases).astype(np.intp)
            np.minimum(ph, f.phases - 1, out=ph)
            first = fq.astype(np.intp)
        first += np.take(f.phase_offset + (self.border - origin), ph)
        # Samples inside the film's region never leave the buffer (its border is ⌈r⌉ + 1); the clamp only
        # guards stray positions (np.clip's Python wrapper costs more than the two ufuncs).
        np.maximum(first, 0, out=first)
        np.minimum(first, extent - f.phase_taps, out=first)
        return first, ph

    def _splat_separable(self, sx: np.ndarray, sy: np.ndarray, values: np.ndarray) -> None:
        f = self.filter
        nph, taps, n = f.phases, f.phase_taps, len(sx)
        x0, phx = self._taps(sx, self.x0, self.bw)
        y0, phy = self._taps(sy, self.y0, self.bh)
        # x pass: scatter w_x·(L, 1) into buf[channel, row, y phase, column] (one bincount per channel
        # over all taps; tap-major index and weight vectors are filled slice by slice, no 2-D gathers).
        row = y0 * nph
        row += phy
        row *= self.bw
        row += x0
        idx = np.empty(taps * n, np.intp)
        wx = np.empty(taps * n)
        for k in range(taps):
            np.add(row, k, out=idx[k * n:(k + 1) * n])
            np.take(f.phase_weights_t[k], phx, out=wx[k * n:(k + 1) * n], mode="wrap")
        size = self.bh * nph * self.bw
        buf = np.empty((4, size))
        buf[3] = np.bincount(idx, wx, minlength=size)
        wv = np.empty(taps * n)
        for c in range(3):
            np.multiply(wx.reshape(taps, n), values[:, c], out=wv.reshape(taps, n))
            buf[c] = np.bincount(idx, wv, minlength=size)
        # y pass: data[c, row + k, x] += Σ_phase W[phase, k] · buf[c, row, phase, x].
        contrib = np.matmul(f.phase_weights_t, buf.reshape(4, self.bh, nph, self.bw))  # (4, rows, taps, cols)
        for k in range(taps):
            self.data[:, k:, :] += contrib[:, : self.bh - k, k, :]

    def _splat_direct(self, sx: np.ndarray, sy: np.ndarray, values: np.ndarray) -> None:
        f = self.filter
        n = len(sx)
        if f.phases:
            taps = f.phase_taps
            x0, phx = self._taps(sx, self.x0, self.bw)
            y0, phy = self._taps(sy, self.y0, self.bh)
            wx = [np.take(f.phase_weights_t[k], phx) for k in range(taps)]
            wy = [np.take(f.phase_weights_t[k], phy) for k in range(taps)]
            xs = [x0 + k for k in range(taps)]
            ys = [y0 + k for k in range(taps)]
        else:
            taps = f.taps
            qx, qy = sx - 0.5, sy - 0.5
            x_lo = np.ceil(qx - f.radius).astype(np.intp)
            y_lo = np.ceil(qy - f.radius).astype(np.intp)
            wx = [f.weights(x_lo + k - qx) for k in range(taps)]
            wy = [f.weights(y_lo + k - qy) for k in range(taps)]
            b = self.border
            xs = [np.clip(x_lo + k - self.x0 + b, 0, self.bw - 1) for k in range(taps)]
            ys = [np.clip(y_lo + k - self.y0 + b, 0, self.bh - 1) for k in range(taps)]
        m = taps * taps
        idx = np.empty(m * n, np.intp)
        w = np.empty(m * n)
        for j in range(taps):
            rj = ys[j] * self.bw
            for i in range(taps):
                s = slice((j * taps + i) * n, (j * taps + i + 1) * n)
                np.add(rj, xs[i], out=idx[s])
                np.multiply(wy[j], wx[i], out=w[s])
        size = self.bh * self.bw
        acc = self.data.reshape(4, size)
        acc[3] += np.bincount(idx, w, minlength=size)
        wv = np.empty(m * n)
        for c in range(3):
            np.multiply(w.reshape(m, n), values[:, c], out=wv.reshape(m, n))
            acc[c] += np.bincount(idx, wv, minlength=size)

    def add(self, other: Film) -> None:
        """Add another film's accumulation (a tile, including its border) into this one."""
        b = self.border
        ys = other.y0 - other.border - self.y0 + b
        xs = other.x0 - other.border - self.x0 + b
        y_from, x_from = max(0, -ys), max(0, -xs)
        y0, x0 = max(0, ys), max(0, xs)
        hh = min(self.bh - y0, other.bh - y_from)
        ww = min(self.bw - x0, other.bw - x_from)
        self.data[:, y0:y0 + hh, x0:x0 + ww] += other.data[:, y_from:y_from + hh, x_from:x_from + ww]

    def image(self) -> np.ndarray:
        """The normalised image Σ wL / Σ w (0 where Σ w = 0), shape (h, w, 3), float32."""
        b = self.border
        d = self.data[:, b:b + self.h, b:b + self.w]
        wsum = d[3]
        positive = wsum > 0
        out = np.empty((self.h, self.w, 3), np.float32)
        q = np.zeros((self.h, self.w))  # stays 0 where Σ w ≤ 0 (``where=`` skips those pixels)
        for c in range(3):  # a channel at a time: 4× less time than one masked division of all three
            np.divide(d[c], wsum, out=q, where=positive)
            out[..., c] = q
        return out
