"""``environment``: a lat-long HDR map around the scene, importance-sampled (spec §9.3, §16.1–16.2).

==============  ======  =========  =========================================================================
parameter       tag     default    meaning
==============  ======  =========  =========================================================================
``filename``    string  (none)     OpenEXR lat-long map (half or float, any compression); without it the
                                   environment is the constant ``radiance`` (no 1/255 factor)
``radiance``    color   (1,1,1)    multiplier
``rotate``      float   0          accepted but **ignored**, as in the course code (every user scene has
                                   180); ``EnvironmentEmitter(apply_rotate=True)`` applies it as a rotation
                                   about +Y that shifts u by rotate/360
==============  ======  =========  =========================================================================

Lookup, exactly as the course code (spec §9.3): for a unit world direction ω,
φ = atan2(ω_z, ω_x) wrapped to [0, 2π), θ = arccos(ω_y), u = φ/2π, v = θ/π, continuous texel position
x = (1 − u)·W, y = (1 − v)·H with texel (c, r) at the integer point (c, r) and row 0 at the top;
bilinear blend of texels (⌊x⌋, ⌊y⌋) … (⌊x⌋+1, ⌊y⌋+1) with indices wrapped modulo W and H; the
result is divided by 255 and multiplied by ``radiance``. Consequently +Y looks up the **bottom** rows
(a sky-on-top map appears upside down, as in the course) and φ runs toward decreasing columns.

Importance sampling: a :class:`~brdflab.math.distribution.Distribution2D` over the cells
[c, c+1) × [r, r+1) of the (x, y) domain with weight (mean luminance of the cell's four corner texels)
× sin θ(cell centre) — the cell integral of the bilinear map times the solid-angle Jacobian — so every
direction with non-zero radiance has non-zero density. A point (x, y) maps back to a direction, and
since dω = sin θ dθ dφ = sin θ (π/H)(2π/W) dx dy the solid-angle density is

    p_ω(ω) = p_xy(x, y) · W H / (2π² sin θ).

``pdf(ω)`` evaluates exactly this density, which is what MIS needs.
"""

from __future__ import annotations

import warnings

import numpy as np

from brdflab.emitter.area import LUMINANCE
from brdflab.emitter.base import Emitter, EmitterSample
from brdflab.errors import BrdflabError, SceneError, quoted
from brdflab.limits import check_memory
from brdflab.math.distribution import Distribution2D
from brdflab.math.frame import stack_cols
from brdflab.scene.properties import PropertyList


class EnvironmentEmitter(Emitter):
    """Infinitely distant lat-long environment light (see module docstring).

    Parameters
    ----------
    image
        (H, W, 3) linear texels, or None for a constant environment.
    radiance
        Multiplier (3,).
    rotate
        Rotation in degrees (used only with ``apply_rotate``).
    apply_rotate
        Apply ``rotate`` as a rotation about +Y (the course code ignores it).
    """

    type_name = "environment"
    is_environment = True
    KNOWN = {"filename": "string", "radiance": "color", "rotate": "float"}

    def __init__(self, image: np.ndarray | None, radiance: np.ndarray, rotate: float = 0.0,
                 apply_rotate: bool = False) -> None:
        self.radiance = np.asarray(radiance, dtype=np.float64)
        self.rotate = float(rotate)
        self.u_shift = (self.rotate / 360.0) if apply_rotate else 0.0
        self.image = None
        if image is not None:
            img = np.asarray(image, dtype=np.float64)
            if not np.all(np.isfinite(img)) or np.any(img < 0):
                warnings.warn("environment map has negative or non-finite texels; they are set to 0", stacklevel=2)
                img = np.where(np.isfinite(img) & (img > 0), img, 0.0)
            self.image = img
            self.h, self.w = img.shape[:2]
            self._scaled = img * (self.radiance / 255.0)  # texels already multiplied by radiance/255
            # One contiguous plane per channel for 1-D gathers in eval, padded with two wrapped rows and
            # columns so that the corners (⌊x⌋ + {0, 1}, ⌊y⌋ + {0, 1}) of any x ∈ [0, W], y ∈ [0, H] index
            # it directly (no modulo).
            padded = np.pad(self._scaled, ((0, 2), (0, 2), (0, 0)), mode="wrap")
            self._pw = self.w + 2
            self._planes = np.ascontiguousarray(np.moveaxis(padded, -1, 0).reshape(3, -1))
            lum = img @ LUMINANCE
            corners = (lum + np.roll(lum, -1, axis=1) + np.roll(lum, -1, axis=0)
                       + np.roll(np.roll(lum, -1, axis=0), -1, axis=1)) / 4.0
            theta_c = np.pi * (1.0 - (np.arange(self.h) + 0.5) / self.h)
            self.dist = Distribution2D(corners * np.sin(theta_c)[:, None])

    @classmethod
    def from_properties(cls, props: PropertyList, resolve_path) -> EnvironmentEmitter:
        """Build from an ``<emitter type="environment">``; ``resolve_path(name)`` finds the map file."""
        from brdflab.imageio import exr_size, read_exr

        props.check_known(cls.KNOWN)
        radiance = props.nonnegative_color("radiance", np.ones(3))
        rotate = props.finite_float("rotate", 0.0)
        name = props.get_string("filename", "")
        image = None
        if name and name != "null":
            path = resolve_path(name)
            if path is None:
                raise props.error("filename", f"environment map {quoted(name)} not found")
            try:
                width, height = exr_size(path)
                # The float64 texels, their scaled and padded copies, the per-channel planes, the luminance
                # and corner sums and the 2-D sampling distribution: about 160 bytes per texel.
                check_memory(160 * width * height, f"the {width}×{height} environment map {quoted(name)}")
                image = read_exr(path)
            except BrdflabError as exc:
                raise SceneError(f"environment map: {exc}", *props.where("filename")) from None
        return cls(image, radiance, rotate)

    # -- mapping between directions and texel coordinates -------------------------------------------------
    def _to_xy(self, d: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        u = np.arctan2(d[:, 2], d[:, 0])  # φ ∈ [−π, π]
        u *= 0.5 / np.pi
        if self.u_shift:
            u += self.u_shift
        u -= np.floor(u)  # φ/2π (+ shift) wrapped to [0, 1)
        cos_t = np.clip(d[:, 1], -1.0, 1.0)
        v = np.arccos(cos_t) / np.pi
        return (1.0 - u) * self.w, (1.0 - v) * self.h, np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))

    def _from_xy(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        u = np.mod(1.0 - x / self.w - self.u_shift, 1.0)
        v = 1.0 - y / self.h
        phi, theta = 2 * np.pi * u, np.pi * v
        st = np.sin(theta)
        return stack_cols(st * np.cos(phi), np.cos(theta), st * np.sin(phi)), st

    # -- emitter interface -------------------------------------------------------------------------------
    def eval(self, d: np.ndarray) -> np.ndarray:
        """Radiance (N, 3) arriving from unit world directions ``d``."""
        if self.image is None:
            return np.broadcast_to(self.radiance, (len(d), 3)).copy()
        return self._lookup(*self._to_xy(d)[:2])

    def eval_pdf(self, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`eval` and :meth:`pdf` of the same directions, sharing the direction → texel mapping."""
        if self.image is None:
            return self.eval(d), self.pdf(d)
        x, y, st = self._to_xy(d)
        return self._lookup(x.copy(), y.copy()), self._pdf_xy(x, y, st)

    def _lookup(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Bilinear lookup at continuous texel positions (x, y) (modified in place)."""
        np.clip(x, 0.0, self.w, out=x)
        np.clip(y, 0.0, self.h, out=y)
        fx, fy = np.floor(x), np.floor(y)
        i00 = fy.astype(np.intp)
        i00 *= self._pw
        i00 += fx.astype(np.intp)
        fx = x - fx
        fy = y - fy
        gx, gy = 1.0 - fx, 1.0 - fy
        corners = ((i00, gx * gy), (i00 + 1, fx * gy), (i00 + self._pw, gx * fy), (i00 + (self._pw + 1), fx * fy))
        out = np.zeros((len(x), 3), order="F")
        for c in range(3):
            plane, col = self._planes[c], out[:, c]
            for idx, w in corners:
                col += np.take(plane, idx, mode="clip") * w
        return out

    def pdf(self, d: np.ndarray) -> np.ndarray:
        """Solid-angle density (N,) with which :meth:`sample` produces the directions ``d``."""
        if self.image is None:
            return np.full(len(d), 0.25 / np.pi)
        return self._pdf_xy(*self._to_xy(d))

    def _pdf_xy(self, x: np.ndarray, y: np.ndarray, st: np.ndarray) -> np.ndarray:
        p = self.dist.pdf(stack_cols(np.minimum(x, np.nextafter(self.w, 0)), np.minimum(y, np.nextafter(self.h, 0))))
        with np.errstate(divide="ignore", invalid="ignore"):
            out = p * (self.w * self.h) / (2 * np.pi**2 * st)
        return np.where((st > 0) & np.isfinite(out), out, 0.0)

    def sample(self, ref_p: np.ndarray, u: np.ndarray) -> EmitterSample:
        """Importance-sample a direction (∝ luminance × sin θ); distance is infinite."""
        n = len(ref_p)
        if self.image is None:
            from brdflab.math import warps

            d = warps.square_to_uniform_sphere(u[:, :2])
            return EmitterSample(d, np.full(n, np.inf), self.eval(d), np.full(n, 0.25 / np.pi))
        pts, p_xy = self.dist.sample(u[:, :2])
        d, st = self._from_xy(pts[:, 0], pts[:, 1])
        with np.errstate(divide="ignore", invalid="ignore"):
            pdf = p_xy * (self.w * self.h) / (2 * np.pi**2 * st)
        ok = (st > 0) & np.isfinite(pdf) & (pdf > 0)
        radiance = self._lookup(pts[:, 0].copy(), pts[:, 1].copy())  # the sampled texel position itself
        radiance *= ok[:, None]
        return EmitterSample(d, np.full(n, np.inf), radiance, np.where(ok, pdf, 0.0))

    def power(self) -> float:
        """Luminance of the mean radiance (over the sphere), a relative power for emitter selection."""
        if self.image is None:
            return float(LUMINANCE @ self.radiance) * 4 * np.pi
        return float(LUMINANCE @ self._scaled.mean(axis=(0, 1))) * 4 * np.pi
