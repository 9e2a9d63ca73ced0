"""Lambertian ``diffuse`` BSDF (spec §10.2).

==============  ======================================  =======
parameter       tag                                     default
==============  ======================================  =======
``albedo``      color, or child ``texture name=albedo``  0.5
==============  ======================================  =======

f = albedo(uv)/π for cos θi, cos θo > 0. Sampling is cosine-weighted (Malley, PBR 13.6.3):
pdf = cos θo/π, weight = albedo.
"""

from __future__ import annotations

import numpy as np

from brdflab.bsdf.base import BSDF, BSDFSample, cos_weight, uv_or_zeros
from brdflab.kernels import twin
from brdflab.math import warps
from brdflab.scene.properties import PropertyList
from brdflab.texture import Texture, as_texture


class Diffuse(BSDF):
    """Lambertian reflector with a constant or textured albedo."""

    #: Instances differing only in constants are evaluated as one batch (:mod:`brdflab.bsdf.family`).
    batchable = True
    type_name = "diffuse"
    #: Compiled twin in :mod:`brdflab.kernels.bsdf` (own body only: subclasses stay on NumPy).
    kernel = "diffuse"
    texture_slots = ("albedo",)
    KNOWN = {"albedo": "color"}

    def __init__(self, albedo: Texture | np.ndarray | float = 0.5) -> None:
        self.albedo = as_texture(albedo)

    @classmethod
    def from_properties(cls, props: PropertyList) -> Diffuse:
        """Build from a ``<bsdf type="diffuse">`` property list."""
        props.check_known(cls.KNOWN)
        return cls(props.reflectance("albedo", np.full(3, 0.5)))

    @twin("bsdf", "eval_bsdf")
    def eval(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None = None) -> np.ndarray:
        """f = albedo/π where both directions are above the surface."""
        ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
        return self.albedo.scaled(uv if self.albedo.constant else uv_or_zeros(uv, len(wi)), ok * warps.INV_PI)

    @twin("bsdf", "pdf_bsdf")
    def pdf(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None = None) -> np.ndarray:
        """cos θo/π for cos θi > 0 (cosine-weighted hemisphere)."""
        return np.where(wi[:, 2] > 0, warps.square_to_cosine_hemisphere_pdf(wo), 0.0)

    @twin("bsdf", "eval_pdf_bsdf")
    def eval_pdf(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """f and p together."""
        return self.eval(wi, wo, uv), self.pdf(wi, wo, uv)

    @twin("bsdf", "sample_bsdf")
    def sample(self, wi: np.ndarray, u: np.ndarray, uv: np.ndarray | None = None) -> BSDFSample:
        """Cosine-weighted sample; the weight is the albedo."""
        wo = warps.square_to_cosine_hemisphere(u[:, :2])
        pdf = self.pdf(wi, wo, uv)
        return BSDFSample(wo, cos_weight(self.eval(wi, wo, uv), wo, pdf), pdf)
