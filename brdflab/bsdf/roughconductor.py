"""``roughconductor``: Beckmann microfacet conductor with Schlick Fresnel (spec §10.5; PBR §8.4).

=============  ===========================================  =======  ============================================
parameter      tag                                          default  meaning
=============  ===========================================  =======  ============================================
``R0``         color, or child ``texture name="R0"``        0.5      reflectance at normal incidence (Schlick)
``alpha``      float, or child ``texture name="alpha"``     0.1      Beckmann roughness α (> 0; a texture's
                                                                     luminance is used)
=============  ===========================================  =======  ============================================

Evaluation (Torrance–Sparrow, PBR eq. 8.18 without the extra cos θ_h, as the course references require):

    f(ω_i, ω_o) = D(ω_h) · F_Schlick(ω_h·ω_i; R0) · G1(ω_i, ω_h) G1(ω_o, ω_h) / (4 cos θ_i cos θ_o),

ω_h = normalize(ω_i + ω_o), zero unless cos θ_i, cos θ_o > 0; D and G1 in :mod:`brdflab.bsdf.microfacet`.

Sampling: ω_h from the Beckmann warp (density D cos θ_h), ω_o = reflect(ω_i, ω_h), so
p(ω_o) = D(ω_h) cos θ_h / (4 |ω_o·ω_h|) (PBR eq. 8.13); weight = f cos θ_o / p. Samples whose ω_o lies
below the surface keep their direction and density but get weight 0; samples from microfacets facing away
from ω_i (ω_i·ω_h ≤ 0) fail (pdf 0): those directions cannot be produced consistently.
"""

from __future__ import annotations

import numpy as np

from brdflab.bsdf.base import BSDF, BSDFSample, cos_weight, uv_or_zeros
from brdflab.bsdf.fresnel import fresnel_schlick
from brdflab.bsdf.microfacet import beckmann_d, half_vector, reflect, reflection_pdf, smith_g1
from brdflab.kernels import twin
from brdflab.math import warps
from brdflab.scene.properties import PropertyList
from brdflab.texture import Texture, as_texture


def alpha_values(tex: Texture, uv: np.ndarray | None, n: int) -> np.ndarray | float:
    """Roughness per query: the constant, or the luminance of a texture at ``uv``."""
    if tex.constant:
        return tex.luminance()  # the weights sum to 1, so a grey value is kept exactly
    return tex.luminance(uv_or_zeros(uv, n))


def check_alpha(props: PropertyList) -> float:
    """Read ``alpha`` and require a finite value > 0."""
    return props.positive_float("alpha", 0.1)


class RoughConductor(BSDF):
    """Beckmann rough conductor with a Schlick Fresnel term (see module docstring).

    Parameters
    ----------
    R0
        Reflectance at normal incidence: a number, an RGB triple or a texture.
    alpha
        Beckmann roughness (> 0): a number or a texture (its luminance is used).

    Examples
    --------
    >>> import numpy as np
    >>> from brdflab import RoughConductor
    >>> m = RoughConductor(R0=0.9, alpha=0.1)
    >>> wi = np.array([[0.0, 0.0, 1.0]])
    >>> s = m.sample(wi, np.full((1, 3), 0.5))
    >>> bool(np.allclose(s.weight, m.eval(wi, s.wo) * s.wo[:, 2:] / s.pdf[:, None]))
    True
    """

    #: Instances differing only in constants are evaluated as one batch (:mod:`brdflab.bsdf.family`).
    batchable = True
    type_name = "roughconductor"
    #: Compiled twin in :mod:`brdflab.kernels.bsdf` (own body only: subclasses stay on NumPy).
    kernel = "roughconductor"
    texture_slots = ("R0", "alpha")
    KNOWN = {"R0": "color", "alpha": "float"}

    def __init__(self, R0: Texture | np.ndarray | float = 0.5, alpha: Texture | float = 0.1) -> None:  # noqa: N803
        self.R0 = as_texture(R0)
        self.alpha = as_texture(alpha)

    @classmethod
    def from_properties(cls, props: PropertyList) -> RoughConductor:
        """Build from a ``<bsdf type="roughconductor">`` property list."""
        props.check_known(cls.KNOWN)
        return cls(props.reflectance("R0", np.full(3, 0.5)), check_alpha(props))

    @property
    def alpha_value(self) -> float:
        """The (mean) roughness, for reports."""
        return float(np.mean(self.alpha.mean()))

    def _terms(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None, need_f: bool,
               need_pdf: bool) -> tuple[np.ndarray | None, np.ndarray | None]:
        """f and/or p of the same directions, sharing ω_h, D(ω_h) and ω_i·ω_h."""
        n = len(wi)
        a = alpha_values(self.alpha, uv, n)
        ci = wi[:, 2]
        wh, okh = half_vector(wi, wo)
        hi = wh[:, 0] * wi[:, 0] + wh[:, 1] * wi[:, 1] + wh[:, 2] * wi[:, 2]
        d = beckmann_d(wh[:, 2], a)
        f = pdf = None
        if need_f:
            co = wo[:, 2]
            ok = (ci > 0) & (co > 0) & okh
            g = smith_g1(wi, wh, a, hi) * smith_g1(wo, wh, a)
            with np.errstate(divide="ignore", invalid="ignore"):
                s = np.where(ok, d * g / (4.0 * ci * co), 0.0)
            s = np.where(np.isfinite(s), s, 0.0)
            r0 = self.R0.value if self.R0.constant else self.R0.eval(uv_or_zeros(uv, n))
            f = fresnel_schlick(np.clip(hi, 0.0, 1.0), r0, s)
        if need_pdf:
            ok = (ci > 0) & okh & (hi > 0)
            pdf = np.where(ok, reflection_pdf(wh, wo, a, d), 0.0)
        return f, pdf

    @twin("bsdf", "eval_bsdf")
    def eval(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None = None) -> np.ndarray:
        """f(ω_i, ω_o) (N, 3), without the cosine."""
        return self._terms(wi, wo, uv, True, False)[0]

    @twin("bsdf", "pdf_bsdf")
    def pdf(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None = None) -> np.ndarray:
        """p(ω_o) = D(ω_h) cos θ_h / (4 |ω_o·ω_h|), 0 for cos θ_i ≤ 0 or ω_i·ω_h ≤ 0."""
        return self._terms(wi, wo, uv, False, True)[1]

    @twin("bsdf", "eval_pdf_bsdf")
    def eval_pdf(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """f and p together (one half vector and one D(ω_h))."""
        return self._terms(wi, wo, uv, True, True)

    @twin("bsdf", "sample_bsdf")
    def sample(self, wi: np.ndarray, u: np.ndarray, uv: np.ndarray | None = None) -> BSDFSample:
        """Sample ω_h ∝ D cos θ_h and reflect ω_i about it.

        f and p are then evaluated from (ω_i, ω_o) exactly as :meth:`eval` and :meth:`pdf` do, so the
        weight is eval·cos/pdf and the pdf equals :meth:`pdf` to the last bit. A microfacet facing away
        from ω_i (ω_i·ω_h < 0) gives an ω_o whose half vector is −ω_h, below the surface: D = 0 there, so
        such samples fail (pdf 0).
        """
        a = alpha_values(self.alpha, uv, len(wi))
        wo = reflect(wi, warps.square_to_beckmann(u[:, :2], a))
        f, pdf = self.eval_pdf(wi, wo, uv)
        return BSDFSample(wo, cos_weight(f, wo, pdf), pdf)
