"""The vectorised BSDF interface shared by all materials (spec §10.1).

All directions are unit vectors of shape (N, 3) in the local shading frame (z = shading normal,
cos θ = z). ``wi`` points toward the previous vertex (the camera), ``wo`` toward the light/next vertex.

* ``eval(wi, wo, uv)`` → f(wi, wo) of shape (N, 3), **without** the cosine; 0 unless cos θi > 0 and
  cos θo > 0 (one-sided).
* ``pdf(wi, wo, uv)`` → solid-angle density (N,) of ``wo`` as realised by ``sample``.
* ``eval_pdf(wi, wo, uv)`` → both at once (bit-identical to the two calls; shares the half vector, D …).
* ``sample(wi, u, uv)`` → :class:`BSDFSample` with ``wo``, ``pdf`` and ``weight`` = f·cos θo / pdf,
  exactly ``eval·cos/pdf``; 0 where the sample failed (cos θi ≤ 0, wo below the surface, pdf = 0).
  ``u`` has shape (N, 3): (ξ1, ξ2) drive the direction warp, ξ3 the lobe choice. All randomness comes
  from the caller.

Delta lobes and transmission (issue 44; the defaults keep every older material and plugin as it was):

* class attributes ``has_delta`` (some lobe is a Dirac delta), ``all_delta`` (every lobe is: no emitter
  sampling at such a vertex), ``two_sided`` (the material handles cos θi < 0 itself; a one-sided material
  returns 0 there) and ``has_transmission`` (wo may lie on the other side of the surface from wi);
* :class:`BSDFSample` has a 4th field ``delta``: None (no delta sample, the old 3-field form) or an (N,) bool
  array, True where the sample came from a delta lobe. There ``weight`` is the whole throughput factor
  (f·|cos θo|/pdf in the limit), ``pdf`` the discrete probability of the chosen lobe (informational: never
  a density), and ``eval``/``pdf`` of that direction return 0 (a delta has measure zero);
* for ``has_transmission`` materials ``eval`` is nonzero for wi and wo on opposite sides, ``pdf`` covers the
  whole sphere and weight = f·|cos θo|/pdf (:func:`abs_cos_weight`); :meth:`BSDF.eta_ratio` gives η_o/η_i
  (the index on wo's side over wi's), with which the radiance form of f obeys the generalised reciprocity
  f(wi, wo)/η_i² = f(wo, wi)/η_o² (Veach 1997, eq. 5.14).
"""

from __future__ import annotations

import copy
from typing import NamedTuple

import numpy as np

from brdflab.texture import PointValues, Texture


class BSDFSample(NamedTuple):
    """Result of :meth:`BSDF.sample` for N queries."""

    wo: np.ndarray
    """(N, 3) sampled local directions."""
    weight: np.ndarray
    """(N, 3) f·cos θo / pdf (0 where sampling failed)."""
    pdf: np.ndarray
    """(N,) solid-angle density of ``wo`` (for a delta sample: the discrete probability of its lobe)."""
    delta: np.ndarray | None = None
    """(N,) bool, True where the sample came from a delta lobe; None: no delta sample (the old 3 fields)."""


class BSDF:
    """Base class of vectorised BSDFs (see module docstring for the contract)."""

    #: Registered Nori type name.
    type_name: str = ""
    #: Texture slots accepted as ``<texture name="...">`` children.
    texture_slots: tuple[str, ...] = ()
    #: True when f(ω_i, ω_o) = f(ω_o, ω_i) (checked by ``brdflab validate``); a class that is not
    #: reciprocal by design says so here and the check only reports the asymmetry.
    reciprocal: bool = True
    #: Some lobe is a Dirac delta (mirror, dielectric): its samples carry ``delta`` = True.
    has_delta: bool = False
    #: Every lobe is a delta: eval and pdf are 0 everywhere, emitter sampling is skipped at such a vertex.
    all_delta: bool = False
    #: The material handles cos θi < 0 itself (one-sided materials return 0 there).
    two_sided: bool = False
    #: wo may lie on the other side of the surface from wi (eval, pdf cover the whole sphere).
    has_transmission: bool = False
    #: The material depends on the azimuth of ω_i, ω_o about n (anisotropic roughness): on a mesh with uvs its
    #: shading frame's x axis follows the uv tangent dp/du (:mod:`brdflab.math.frame`); other materials keep
    #: the frame built from the normal alone. A property where it depends on the parameters.
    anisotropic: bool = False

    def eval(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None = None) -> np.ndarray:
        """Return f(wi, wo), shape (N, 3), without the cosine."""
        raise NotImplementedError

    def pdf(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None = None) -> np.ndarray:
        """Return the solid-angle density (N,) with which :meth:`sample` produces ``wo``."""
        raise NotImplementedError

    def eval_pdf(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(:meth:`eval`, :meth:`pdf`) of the same directions; materials override it to share the work."""
        return self.eval(wi, wo, uv), self.pdf(wi, wo, uv)

    def sample(self, wi: np.ndarray, u: np.ndarray, uv: np.ndarray | None = None) -> BSDFSample:
        """Sample ``wo`` given ``wi`` and uniforms ``u`` of shape (N, 3)."""
        raise NotImplementedError

    def eta_ratio(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """η_o/η_i (N,): the refractive index on wo's side over the one on wi's side (1 without transmission).

        With it the radiance form of f obeys f(wi, wo) = f(wo, wi)·(η_i/η_o)² (generalised reciprocity), and
        the energy a sample carries is its weight·(η_o/η_i)² (the white furnace of transmissive materials).
        """
        return np.ones(len(wi))

    def set_texture(self, slot: str, texture: Texture) -> None:
        """Attach a child texture to ``slot`` (one of :attr:`texture_slots`)."""
        setattr(self, slot, texture)

    def scalar_parameters(self) -> tuple:
        """The parameters that are not texture slots (e.g. indices of refraction), as a hashable tuple."""
        return ()

    def family_key(self) -> tuple | None:
        """Materials with equal keys can be evaluated as one batch with per-point parameters.

        Two instances of one class whose texture slots are all constant and whose
        :meth:`scalar_parameters` agree differ only in their constants: a batch of shading points on
        either is evaluated by one :meth:`with_point_values` copy instead of one call per material.
        Returns None when the material must be evaluated on its own (a texture that varies with uv), and
        for every class that does not declare ``batchable = True`` in its own body: a user's BSDF (or a
        subclass of a built-in) keeps its parameters in attributes the family tables know nothing of, so
        it always takes the plain per-material path.
        """
        if not type(self).__dict__.get("batchable", False):
            return None
        if not all(getattr(self, slot).constant for slot in self.texture_slots):
            return None
        return (type(self), *self.scalar_parameters())

    def with_point_values(self, values: dict[str, PointValues]) -> BSDF:
        """A shallow copy whose texture slots hold the given per-point values (one batch of points)."""
        clone = copy.copy(self)
        for slot, tex in values.items():
            setattr(clone, slot, tex)
        return clone


def cos_weight(f: np.ndarray, wo: np.ndarray, pdf: np.ndarray) -> np.ndarray:
    """Return f·cos θo / pdf (N, 3), 0 where pdf ≤ 0 or cos θo ≤ 0 or the result is not finite."""
    return _weight(f, wo[:, 2], pdf)


def abs_cos_weight(f: np.ndarray, wo: np.ndarray, pdf: np.ndarray) -> np.ndarray:
    """Return f·|cos θo| / pdf (N, 3) for transmissive BSDFs, 0 where pdf ≤ 0, cos θo = 0 or not finite."""
    return _weight(f, np.abs(wo[:, 2]), pdf)


def _weight(f: np.ndarray, cos_o: np.ndarray, pdf: np.ndarray) -> np.ndarray:
    ok = (pdf > 0) & (cos_o > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        w = f * np.where(ok, cos_o / np.where(ok, pdf, 1.0), 0.0)[:, None]
    return np.where(np.isfinite(w), w, 0.0)


def uv_or_zeros(uv: np.ndarray | None, n: int) -> np.ndarray:
    """Return ``uv`` or an (n, 2) array of zeros when no uv is supplied (constant textures)."""
    return np.zeros((n, 2)) if uv is None else uv
