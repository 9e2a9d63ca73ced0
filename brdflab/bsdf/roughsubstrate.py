"""``roughsubstrate``: Ashikhmin–Shirley diffuse substrate under a Beckmann or GGX dielectric coating
(spec §10.6; Ashikhmin & Shirley 2000, eq. 5; PBR §8.5; the coat's options: issue 45).

==================  =========================================  ============  =====================================
parameter           tag                                        default       meaning
==================  =========================================  ============  =====================================
``kd``              color, or child ``texture name="kd"``      0.5           diffuse albedo of the substrate
``alpha``           float, or child ``texture name="alpha"``   0.1           roughness α of the coating (> 0);
                                                                             sets α_u and α_v
``alpha_u``         float                                      ``alpha``     the coat's α along the shading
                                                                             frame's x axis
``alpha_v``         float                                      ``alpha``     the coat's α along the y axis
``distribution``    string: ``beckmann`` or ``ggx``            ``beckmann``  the coat's microfacet distribution D
``sample_visible``  boolean                                    true for ggx  sample the coat's visible normals
                                                                             (Heitz 2018)
``intIOR``          float                                      1.5046        interior index of refraction η_i
``extIOR``          float                                      1.000277      exterior index of refraction η_e
==================  =========================================  ============  =====================================

    f = f_diff + f_mf,
    f_diff = (28 k_d / 23π)(1 − R_n)(1 − (1 − ½cos θ_i)⁵)(1 − (1 − ½cos θ_o)⁵),  R_n = ((η_e − η_i)/(η_e + η_i))²,
    f_mf   = D(ω_h) · F_dielectric(ω_h·ω_i; η_e, η_i) · G1(ω_i, ω_h) G1(ω_o, ω_h) / (4 cos θ_i cos θ_o),

both zero unless cos θ_i, cos θ_o > 0. D and G1 (:mod:`brdflab.bsdf.microfacet`): by default the course's
Beckmann D and rational G1 (its original code path, bit for bit); with ``distribution``/``alpha_u``/``alpha_v``
GGX (exact G1) or Beckmann, anisotropic with α_u along the shading frame's x axis, as ``roughconductor``.

Sampling is a mixture: with probability p_s = min(F_dielectric(cos θ_i), 0.95) (on the macro normal) the
microfacet lobe (ω_h ∝ D cos θ_h, or with ``sample_visible`` a visible normal; reflection), otherwise the
cosine-weighted hemisphere; the lobe choice uses the third uniform. The cap keeps the diffuse lobe reachable
under total internal reflection (η_e > η_i, where F = 1 but f_diff > 0), which would otherwise bias
BSDF-sampled estimates.
p(ω_o) = p_s · D cos θ_h / (4 |ω_o·ω_h|) + (1 − p_s) · cos θ_o / π, weight = f cos θ_o / p; with visible
normals D cos θ_h is G1(ω_i) max(0, ω_i·ω_h) D / cos θ_i (exact G1; :func:`~brdflab.bsdf.microfacet.visible_pdf`).
Only the default coat has a compiled twin: other coats run the NumPy code under either engine.
"""

from __future__ import annotations

import numpy as np

from brdflab.bsdf import microfacet as mf
from brdflab.bsdf.base import BSDF, BSDFSample, cos_weight, uv_or_zeros
from brdflab.bsdf.fresnel import fresnel_dielectric, pow5
from brdflab.bsdf.microfacet import half_vector, reflect, reflection_pdf
from brdflab.bsdf.microfacet_options import (
    KNOWN_OPTIONS,
    MicrofacetOptions,
    alpha_values,
    check_alpha,
    option_properties,
)
from brdflab.kernels import twin
from brdflab.math import warps
from brdflab.math.frame import take_rows
from brdflab.scene.properties import PropertyList
from brdflab.texture import Texture, as_texture

#: Upper bound of the specular lobe's selection probability (see the module docstring).
P_SPECULAR_MAX = 0.95


class RoughSubstrate(MicrofacetOptions, BSDF):
    """Diffuse substrate under a rough dielectric coating (see module docstring).

    Parameters
    ----------
    kd, alpha, intIOR, extIOR
        As in the table of the module docstring (``RoughSubstrate(kd=0.3, alpha=0.1, intIOR=1.5)``).
    lobe
        ``"both"`` (default), or ``"specular"``/``"diffuse"`` to evaluate, sample and integrate a single
        lobe (used by the validation harness).
    distribution, alpha_u, alpha_v, sample_visible
        The coat's microfacet options (:mod:`brdflab.bsdf.microfacet_options`), as ``roughconductor``'s.

    Examples
    --------
    >>> import numpy as np
    >>> from brdflab import RoughSubstrate
    >>> m = RoughSubstrate(kd=0.3, distribution="ggx", alpha_u=0.05, alpha_v=0.2, intIOR=1.5)
    >>> wi = np.array([[0.6, 0.0, 0.8]])
    >>> s = m.sample(wi, np.array([[0.3, 0.6, 0.01]]))     # ξ3 < p_s: the coat's visible-normal lobe
    >>> bool(np.allclose(s.pdf, m.pdf(wi, s.wo)))
    True
    """

    #: Instances differing only in constants are evaluated as one batch (:mod:`brdflab.bsdf.family`).
    batchable = True
    type_name = "roughsubstrate"
    #: Compiled twin in :mod:`brdflab.kernels.bsdf` (own body only: subclasses stay on NumPy).
    kernel = "roughsubstrate"
    texture_slots = ("kd", "alpha")
    KNOWN = {"kd": "color", "alpha": "float", **KNOWN_OPTIONS, "intIOR": "float", "extIOR": "float"}

    def __init__(self, kd: Texture | np.ndarray | float = 0.5, alpha: Texture | float = 0.1,
                 intIOR: float = 1.5046, extIOR: float = 1.000277, lobe: str = "both",  # noqa: N803
                 distribution: str = mf.BECKMANN, alpha_u: float | None = None, alpha_v: float | None = None,
                 sample_visible: bool | None = None) -> None:
        self.kd = as_texture(kd)
        self.alpha = as_texture(alpha)
        self.set_options(distribution, alpha_u, alpha_v, sample_visible)
        self.int_ior, self.ext_ior = float(intIOR), float(extIOR)
        self.lobe = lobe
        rn = ((self.ext_ior - self.int_ior) / (self.ext_ior + self.int_ior)) ** 2
        self.diffuse_scale = 28.0 / (23.0 * np.pi) * (1.0 - rn)

    @classmethod
    def from_properties(cls, props: PropertyList) -> RoughSubstrate:
        """Build from a ``<bsdf type="roughsubstrate">`` property list."""
        props.check_known(cls.KNOWN)
        options = option_properties(props)
        return cls(props.reflectance("kd", np.full(3, 0.5)), check_alpha(props),
                   props.positive_float("intIOR", 1.5046), props.positive_float("extIOR", 1.000277), **options)

    def scalar_parameters(self) -> tuple:
        """(η_int, η_ext, lobe, the coat's options): materials of one family must share them."""
        return (self.int_ior, self.ext_ior, self.lobe, *self.option_parameters())

    def _p_specular(self, cos_i: np.ndarray) -> np.ndarray:
        if self.lobe == "specular":
            return np.ones_like(cos_i)
        if self.lobe == "diffuse":
            return np.zeros_like(cos_i)
        return np.minimum(fresnel_dielectric(cos_i, self.ext_ior, self.int_ior), P_SPECULAR_MAX)

    def _terms(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None, need_f: bool,
               need_pdf: bool, ps: np.ndarray | None = None) -> tuple[np.ndarray | None, np.ndarray | None]:
        """f and/or p of the same directions, sharing ω_h, D(ω_h) and ω_i·ω_h (``ps``: p_s if known)."""
        n = len(wi)
        ci, co = wi[:, 2], wo[:, 2]
        f = pdf = None
        wh = okh = hi = d = None
        if need_pdf or self.lobe != "diffuse":
            wh, okh = half_vector(wi, wo)
            hi = wh[:, 0] * wi[:, 0] + wh[:, 1] * wi[:, 1] + wh[:, 2] * wi[:, 2]
            coat = need_f and self.lobe != "diffuse"
            d, g, alphas = self.d_g1(wh, wi if coat else None, wo, uv, n, hi)
        if need_f:
            ok = (ci > 0) & (co > 0)
            f = np.zeros((n, 3), order="F")
            if self.lobe != "specular":
                s = self.diffuse_scale * (1.0 - pow5(1.0 - 0.5 * ci)) * (1.0 - pow5(1.0 - 0.5 * co))
                f += self.kd.eval(uv_or_zeros(uv, n)) * np.where(ok, s, 0.0)[:, None]
            if self.lobe != "diffuse":
                fr = fresnel_dielectric(np.clip(hi, 0.0, 1.0), self.ext_ior, self.int_ior)
                with np.errstate(divide="ignore", invalid="ignore"):
                    m = np.where(ok & okh, d * fr * g / (4.0 * ci * co), 0.0)
                f += np.where(np.isfinite(m), m, 0.0)[:, None]
        if need_pdf:
            if ps is None:
                ps = self._p_specular(ci)
            if self.sample_visible:
                p_mf = mf.visible_pdf(self.distribution, wi, wh, wo, *alphas, d, hi)
            else:
                p_mf = reflection_pdf(wh, wo, None, d)
            p_mf = np.where(okh & (hi > 0), p_mf, 0.0)
            p_d = warps.square_to_cosine_hemisphere_pdf(wo)
            pdf = np.where(ci > 0, ps * p_mf + (1.0 - ps) * p_d, 0.0)
        return f, pdf

    @twin("bsdf", "eval_bsdf")
    def eval(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None = None) -> np.ndarray:
        """f(ω_i, ω_o) (N, 3), without the cosine."""
        return self._terms(wi, wo, uv, True, False)[0]

    @twin("bsdf", "pdf_bsdf")
    def pdf(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None = None) -> np.ndarray:
        """Mixture density p_s · p_mf(ω_o) + (1 − p_s) · cos θ_o/π (0 for cos θ_i ≤ 0)."""
        return self._terms(wi, wo, uv, False, True)[1]

    @twin("bsdf", "eval_pdf_bsdf")
    def eval_pdf(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """f and p together (one half vector and one D(ω_h))."""
        return self._terms(wi, wo, uv, True, True)

    @twin("bsdf", "sample_bsdf")
    def sample(self, wi: np.ndarray, u: np.ndarray, uv: np.ndarray | None = None) -> BSDFSample:
        """Choose a lobe with the third uniform, sample it, and weight by the mixture density."""
        ps = self._p_specular(wi[:, 2])
        n = len(wi)
        ax, ay = (alpha_values(self.alpha, uv, n), None) if self.default_options else self.alphas(uv, n)
        # Most samples pick the diffuse lobe (p_s is the Fresnel reflectance, ~4 % at normal incidence):
        # warp all of them cosine-weighted, then only the specular picks through the Beckmann warp.
        wo = warps.square_to_cosine_hemisphere(u[:, :2])
        spec = np.flatnonzero(u[:, 2] < ps)
        if len(spec):
            ax_s, ay_s = (v if np.ndim(v) == 0 else np.take(v, spec) for v in (ax, ay))
            wi_s = take_rows(wi, spec)
            with np.errstate(invalid="ignore", divide="ignore"):
                wo_s = reflect(wi_s, self.normals_for(wi_s, take_rows(u, spec), ax_s, ay_s))
            if not self.default_options:  # a failed normal (ξ1 = 1 of an unbounded warp): a direction that fails
                wo_s = np.where(np.isfinite(wo_s), wo_s, np.array([0.0, 0.0, -1.0]))
            wo[spec] = wo_s
        f, pdf = self._terms(wi, wo, uv, True, True, ps)
        return BSDFSample(wo, cos_weight(f, wo, pdf), pdf)
