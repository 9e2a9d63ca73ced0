"""``dielectric``: a smooth, two-sided dielectric interface (glass, water) with exact Fresnel (spec §10.4).

=============  ======  ==========  ========================================================
parameter      tag     default     meaning
=============  ======  ==========  ========================================================
``intIOR``     float   1.5046      refractive index of the interior (opposite the normal)
``extIOR``     float   1.000277    refractive index of the exterior (the normal's side)
=============  ======  ==========  ========================================================

Two delta lobes (PBR §8.2: eqs. 8.1–8.3 for Fresnel, 8.8 for Snell's law):

* media: (η_i, η_t) = (ext, int) if cos θ_i ≥ 0, else (int, ext) (the BSDF handles ω_i inside itself);
* F = F_dielectric(cos θ_i; ext, int) exactly (:func:`brdflab.bsdf.fresnel.dielectric_refraction`, spec §11.1);
* with probability F (ξ3 < F, the contract's lobe-choice uniform): reflect, ω_o = (−ω_i,x, −ω_i,y, ω_i,z),
  weight 1, ``pdf`` = F;
* otherwise refract: η = η_i/η_t, cos θ_t = √(1 − η²(1 − cos²θ_i)),
  ω_o = (−η ω_i,x, −η ω_i,y, ∓cos θ_t) (z opposite to ω_i's), ``pdf`` = 1 − F;
* total internal reflection gives F = 1: always reflected.

**Radiance scale at refraction (the choice, contract item 4).** Radiance crossing into a medium of index η_t
scales by (η_t/η_i)² (Veach 1997, §5.2; PBR §8.2.3), so the refracted sample's weight — the whole throughput
factor from ω_o's side (the light) to ω_i's (the camera) — is **(η_i/η_t)² = η²**, where η_i is the index on
ω_i's side. The spec's Nori returns η_t/η_i instead; both products telescope to 1 along any path that
enters and leaves the glass into air again (air → glass: (1/1.5)², glass → air: 1.5²), so the course's
scenes have the same expectation either way, and ours is also right for a light or camera inside a medium.
:meth:`Dielectric.eta_ratio` gives η_o/η_i, with which weight·(η_o/η_i)² is the transported energy:
F·1 + (1 − F)·η²·η⁻² = 1 (the furnace of :mod:`brdflab.judges.material.delta`).

``eval`` and ``pdf`` return 0 (delta lobes have measure zero); every sample has ``delta`` = True.
"""

from __future__ import annotations

import numpy as np

from brdflab.bsdf.base import BSDF, BSDFSample
from brdflab.bsdf.fresnel import dielectric_refraction
from brdflab.bsdf.mirror import mirror_direction
from brdflab.scene.properties import PropertyList

#: Default indices of refraction (spec §10.4: Nori's glass and air).
INT_IOR, EXT_IOR = 1.5046, 1.000277


def check_iors(props: PropertyList) -> tuple[float, float]:
    """(intIOR, extIOR) of a property list, each a finite float > 0."""
    return props.positive_float("intIOR", INT_IOR), props.positive_float("extIOR", EXT_IOR)


def side_eta_ratio(wi: np.ndarray, wo: np.ndarray, int_ior: float, ext_ior: float) -> np.ndarray:
    """η_o/η_i (N,) for an interface whose exterior is z ≥ 0: 1 on one side, int/ext entering, ext/int leaving."""
    out_i, out_o = wi[:, 2] >= 0, wo[:, 2] >= 0
    return np.where(out_i == out_o, 1.0, np.where(out_i, int_ior / ext_ior, ext_ior / int_ior))


def refract_about_normal(wi: np.ndarray, cos_t: np.ndarray, eta: np.ndarray) -> np.ndarray:
    """Snell refraction through the plane z = 0: (−η ω_i,x, −η ω_i,y, ∓cos θ_t), z opposite to ω_i's."""
    z = np.where(wi[:, 2] >= 0, -cos_t, cos_t)
    return np.stack([-eta * wi[:, 0], -eta * wi[:, 1], z], axis=1)


class Dielectric(BSDF):
    """Smooth dielectric interface: Fresnel-weighted choice of mirror reflection and refraction.

    Parameters
    ----------
    intIOR, extIOR
        Refractive indices inside and outside (the normal points outside).

    Examples
    --------
    >>> import numpy as np
    >>> from brdflab import Dielectric
    >>> g = Dielectric(intIOR=1.5, extIOR=1.0)
    >>> wi = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    >>> s = g.sample(wi, np.array([[0.5, 0.5, 0.01], [0.5, 0.5, 0.9]]))   # ξ3 < F = 0.04: reflect
    >>> s.wo.tolist(), np.round(s.weight[:, 0], 4).tolist(), np.round(s.pdf, 4).tolist()
    ([[-0.0, -0.0, 1.0], [-0.0, -0.0, -1.0]], [1.0, 0.4444], [0.04, 0.96])
    """

    type_name = "dielectric"
    KNOWN = {"intIOR": "float", "extIOR": "float"}
    has_delta = True
    all_delta = True
    two_sided = True
    has_transmission = True

    def __init__(self, intIOR: float = INT_IOR, extIOR: float = EXT_IOR) -> None:  # noqa: N803
        self.int_ior, self.ext_ior = float(intIOR), float(extIOR)

    @classmethod
    def from_properties(cls, props: PropertyList) -> Dielectric:
        """Build from a ``<bsdf type="dielectric">`` property list."""
        props.check_known(cls.KNOWN)
        return cls(*check_iors(props))

    def scalar_parameters(self) -> tuple:
        """(η_int, η_ext)."""
        return (self.int_ior, self.ext_ior)

    def eta_ratio(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """η_o/η_i (N,): int/ext for ω_i outside and ω_o inside, ext/int the other way, 1 on one side."""
        return side_eta_ratio(wi, wo, self.int_ior, self.ext_ior)

    def eval(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None = None) -> np.ndarray:
        """0 (N, 3): both lobes are deltas."""
        return np.zeros((len(wi), 3))

    def pdf(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None = None) -> np.ndarray:
        """0 (N,): no solid-angle density."""
        return np.zeros(len(wi))

    def fresnel(self, cos_i: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(F, cos θ_t, η = η_i/η_t) for cosines on either side (subclasses of the judges' negative controls
        override this)."""
        return dielectric_refraction(cos_i, self.ext_ior, self.int_ior)

    def sample(self, wi: np.ndarray, u: np.ndarray, uv: np.ndarray | None = None) -> BSDFSample:
        """Reflect with probability F (ξ3 < F, weight 1), else refract (weight η², see the module docstring)."""
        f, cos_t, eta = self.fresnel(wi[:, 2])
        refl = u[:, 2] < f
        wo = np.where(refl[:, None], mirror_direction(wi), refract_about_normal(wi, cos_t, eta))
        w = np.where(refl, 1.0, eta * eta)
        pdf = np.where(refl, f, 1.0 - f)
        return BSDFSample(wo, np.repeat(w[:, None], 3, axis=1), pdf, np.ones(len(wi), dtype=bool))
