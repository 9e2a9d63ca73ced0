"""Mesh ``area`` emitter: one-sided, uniform over the mesh surface (spec §9.1).

=============  ========================================  =========  ==============================
parameter      tag                                       default    meaning
=============  ========================================  =========  ==============================
``radiance``   color, or child ``texture name=radiance`` (1, 1, 1)  emitted radiance L_e
``scale``      float                                     1          multiplies the radiance
=============  ========================================  =========  ==============================

Emission: L_e(y → x) = radiance(uv)·scale if n_l·(y − x) < 0, else 0, with n_l the **shading** normal
at y (interpolated ``vn``, renormalised; else the winding normal).

Sampling: a triangle with probability A_k / A (``np.searchsorted`` on the cumulative areas), a uniform
point in it by the folding warp with barycentrics (ξ1, ξ2, 1 − ξ1 − ξ2), area density 1/A, converted to
solid angle at the receiver x: p_ω = ‖y − x‖² / (A |n_l·ω|) (PBR eq. 13.x, change of variables dω =
|cos θ_l| dA / r²).
"""

from __future__ import annotations

import numpy as np

from brdflab.emitter.base import Emitter, EmitterSample
from brdflab.math import warps
from brdflab.math.frame import dot
from brdflab.scene.properties import PropertyList
from brdflab.texture import Texture, as_texture

LUMINANCE = np.array([0.212671, 0.715160, 0.072169])


class AreaEmitter(Emitter):
    """A one-sided diffuse emitter attached to one mesh of the scene geometry.

    Parameters
    ----------
    radiance
        Emitted radiance (colour or texture).
    scale
        Multiplier of the radiance.
    """

    type_name = "area"
    texture_slots = ("radiance",)
    KNOWN = {"radiance": "color", "scale": "float"}

    def __init__(self, radiance: Texture | np.ndarray | float = 1.0, scale: float = 1.0) -> None:
        self.radiance = as_texture(radiance)
        self.scale = float(scale)
        self.mesh_index = -1

    @classmethod
    def from_properties(cls, props: PropertyList) -> AreaEmitter:
        """Build from an ``<emitter type="area">`` property list."""
        props.check_known(cls.KNOWN)
        scale = props.positive_float("scale", 1.0, allow_zero=True)
        return cls(props.nonnegative_color("radiance", np.ones(3)), scale)

    def set_texture(self, slot: str, texture: Texture) -> None:
        """Attach the ``radiance`` texture."""
        self.radiance = texture

    def attach(self, geometry, mesh_index: int) -> None:
        """Bind to mesh ``mesh_index`` of ``geometry`` and build the triangle distribution."""
        self.geometry = geometry
        self.mesh_index = mesh_index
        self.tris = np.flatnonzero(geometry.tri_mesh == mesh_index)
        areas = geometry.tri_area[self.tris]
        self.area = float(areas.sum())
        self.cdf = np.cumsum(areas) / self.area if self.area > 0 else None

    def le(self, uv: np.ndarray) -> np.ndarray:
        """Radiance (N, 3) emitted toward the front side at surface coordinates ``uv``."""
        return self.radiance.eval(uv) * self.scale

    def sample(self, ref_p: np.ndarray, u: np.ndarray) -> EmitterSample:
        """Sample a point uniformly by area and return the solid-angle sample seen from ``ref_p``."""
        g = self.geometry
        k = np.minimum(np.searchsorted(self.cdf, u[:, 2], side="right"), len(self.tris) - 1)
        prim = self.tris[k]
        b = warps.square_to_uniform_triangle(u[:, :2])
        # Spec §9.1: barycentrics (ξ1, ξ2, 1 − ξ1 − ξ2) for (p0, p1, p2); Hits use (1 − u − v, u, v).
        bu, bv = b[:, 1], 1.0 - b[:, 0] - b[:, 1]
        h = g.hit_records(np.ones(len(prim), bool), prim, bu, bv, np.zeros(len(prim)))
        delta = h.p - ref_p
        dist2 = dot(delta, delta)
        dist = np.sqrt(dist2)
        wi = delta / np.where(dist > 0, dist, 1.0)[:, None]
        cos_l = -dot(h.ns, wi)
        front = cos_l > 0
        with np.errstate(divide="ignore", invalid="ignore"):
            pdf = np.where(front, dist2 / (self.area * np.abs(cos_l)), 0.0)
        ok = front & np.isfinite(pdf) & (pdf > 0)
        radiance = np.zeros((len(prim), 3), order="F")
        radiance[ok] = self.le(h.uv[ok]) if not self.radiance.constant else self.radiance.value * self.scale
        return EmitterSample(wi, dist, radiance, np.where(ok, pdf, 0.0))

    def eval_hit(self, ns: np.ndarray, uv: np.ndarray, d: np.ndarray) -> np.ndarray:
        """Radiance arriving along rays of direction ``d`` that hit this emitter (shading normal ``ns``)."""
        front = dot(ns, d) < 0
        return np.where(front[:, None], self.le(uv), 0.0)

    def pdf_hit(self, dist: np.ndarray, ns: np.ndarray, d: np.ndarray) -> np.ndarray:
        """Solid-angle density with which :meth:`sample` would produce the hit at ``dist`` along ``d``."""
        cos_l = -dot(ns, d)
        with np.errstate(divide="ignore", invalid="ignore"):
            pdf = np.where(cos_l > 0, dist * dist / (self.area * np.abs(cos_l)), 0.0)
        return np.where(np.isfinite(pdf), pdf, 0.0)

    def power(self) -> float:
        """Luminance of the mean radiance times the area (spec §8)."""
        return float(LUMINANCE @ (self.radiance.mean() * self.scale)) * self.area * np.pi
