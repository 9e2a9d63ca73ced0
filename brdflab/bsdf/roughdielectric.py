"""``roughdielectric``: a rough, two-sided dielectric interface — Walter et al. 2007 with Beckmann or GGX D
(spec §10.7; issue 45).

==================  ===========================================  ============  ====================================
parameter           tag                                          default       meaning
==================  ===========================================  ============  ====================================
``alpha``           float, or child ``texture name="alpha"``     0.1           roughness α (> 0; a texture's
                                                                               luminance is used); sets α_u, α_v
``alpha_u``         float                                        ``alpha``     α along the shading frame's x axis
``alpha_v``         float                                        ``alpha``     α along the shading frame's y axis
``distribution``    string: ``beckmann`` or ``ggx``              ``beckmann``  the microfacet distribution D
``sample_visible``  boolean                                      true for ggx  sample visible normals (Heitz 2018)
``intIOR``          float                                        1.5046        index of the interior (opposite
                                                                               the normal)
``extIOR``          float                                        1.000277      index of the exterior (the
                                                                               normal's side)
``ka``              color, or child ``texture name="m_ka"``      1             colour factor of the transmitted
                    (or ``name="ka"``)                                         lobe
==================  ===========================================  ============  ====================================

The spec (§10.7) lists the parameters only (the course's eval, pdf and sample throw), so ``ka``'s meaning is
brdflab's choice, stated here: a per-channel transmittance tint of the refracted lobe (coloured glass);
ka = 1 is Walter et al.'s model exactly, ka ≤ 1 keeps energy conservation.

Walter, Marschner, Li, Torrance, "Microfacet Models for Refraction through Rough Surfaces", EGSR 2007. Two-sided:
where cos θ_i < 0 the frame is flipped (z → −z) and the media swapped, so below
(η_i, η_t) = (ext, int) for ω_i on the normal's side and (int, ext) inside, cos θ_i > 0, D, G1 from
:mod:`brdflab.bsdf.microfacet` (the defaults: the course's Beckmann D and rational Smith G1, spec §11.1, bit for
bit as before; GGX with its exact G1; anisotropic α_u along the frame's x axis), and
F(ω_i·ω_h) the exact dielectric Fresnel (spec §11.1) of the microfacet:

* reflection (ω_o on ω_i's side), ω_h = normalize(ω_i + ω_o) (Walter eqs. 13, 20):
  f_r = F D(ω_h) G1(ω_i, ω_h) G1(ω_o, ω_h) / (4 |cos θ_i| |cos θ_o|);
* transmission (ω_o on the other side), ω_h = ±normalize(η_i ω_i + η_t ω_o) with cos θ_h > 0 (eq. 16):
  f_t = ka · |ω_i·ω_h| |ω_o·ω_h| η_i² (1 − F) D G1 G1 / (|cos θ_i| |cos θ_o| (η_i ω_i·ω_h + η_t ω_o·ω_h)²)
  (eq. 21 with Walter's o — the direction towards the viewer — being our ω_i); valid only where
  ω_i·ω_h > 0 > ω_o·ω_h. The η_i² makes f the radiance BTDF: f(ω_i, ω_o)/η_i² = f(ω_o, ω_i)/η_o²
  (generalised reciprocity, Veach 1997 eq. 5.14; :meth:`RoughDielectric.eta_ratio` gives η_o/η_i).
  In the smooth limit the refracted weight tends to (η_i/η_t)², the radiance scale of ``dielectric``.

The flip keeps the anisotropy: it leaves x and y alone, and D, Λ and G1 depend on the normal's x², y² and z
only (D(x, y, z) = D(−x, −y, z)), so the normals −ω_h that the interface shows from inside, flipped, have the
same D with α_u still along x.

Sampling (Walter §5.3): ω_h from the Beckmann warp (density D cos θ_h, ξ1, ξ2), or
:func:`~brdflab.bsdf.microfacet.sample_normals` (D cos θ_h), or with ``sample_visible`` the visible normals of
ω_i (:func:`~brdflab.bsdf.microfacet.sample_visible_normals`, density G1(ω_i) max(0, ω_i·ω_h) D/cos θ_i with
the exact G1 = 1/(1 + Λ(ω_i)); Heitz 2018 eq. 1, used for transmission as in pbrt-v4 and Mitsuba 3: the normal
is drawn once, the Fresnel choice and the Jacobians are those below); ω_i·ω_h ≤ 0 fails; with
probability F(ω_i·ω_h) (ξ3 < F) reflect, ω_o = 2(ω_i·ω_h)ω_h − ω_i, else refract,
ω_o = −η ω_i + (η ω_i·ω_h − cos θ_t) ω_h with η = η_i/η_t (Snell about ω_h); a direction that ends on the
wrong side of the macro surface fails (pdf 0, weight 0). Densities (eqs. 14, 17, 38):

    p(ω_o) = F D cos θ_h / (4 |ω_o·ω_h|)                                     (reflection)
    p(ω_o) = (1 − F) D cos θ_h · η_t² |ω_o·ω_h| / (η_i ω_i·ω_h + η_t ω_o·ω_h)²   (transmission)

with D cos θ_h replaced by G1(ω_i) max(0, ω_i·ω_h) D / cos θ_i for visible normals, and
weight = f |cos θ_o| / p (f and p evaluated from (ω_i, ω_o) as :meth:`eval` and :meth:`pdf` do).
"""

from __future__ import annotations

import numpy as np

from brdflab.bsdf import microfacet as mf
from brdflab.bsdf.base import BSDF, BSDFSample, abs_cos_weight, uv_or_zeros
from brdflab.bsdf.dielectric import EXT_IOR, INT_IOR, check_iors, side_eta_ratio
from brdflab.bsdf.fresnel import dielectric_refraction, fresnel_dielectric
from brdflab.bsdf.microfacet_options import KNOWN_OPTIONS, MicrofacetOptions, check_alpha, option_properties
from brdflab.scene.properties import PropertyList
from brdflab.texture import Texture, as_texture


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


class RoughDielectric(MicrofacetOptions, BSDF):
    """Rough dielectric interface (Walter et al. 2007, Beckmann or GGX), reflection and transmission; two-sided.

    Parameters
    ----------
    alpha, intIOR, extIOR, ka
        As in the table of the module docstring.
    distribution, alpha_u, alpha_v, sample_visible
        The microfacet options (:mod:`brdflab.bsdf.microfacet_options`): ``"beckmann"`` (default) or ``"ggx"``,
        anisotropic roughness along the local x and y axes (default: ``alpha``), visible-normal sampling
        (default: True for GGX).

    Examples
    --------
    >>> import numpy as np
    >>> from brdflab import RoughDielectric
    >>> g = RoughDielectric(alpha=0.2, intIOR=1.5, extIOR=1.0)
    >>> wi = np.tile([0.6, 0.0, 0.8], (4, 1))
    >>> s = g.sample(wi, np.random.default_rng(1).random((4, 3)))
    >>> f = g.eval(wi, s.wo)
    >>> bool(np.allclose(s.weight, f * np.abs(s.wo[:, 2:]) / s.pdf[:, None]))
    True
    >>> bool((s.wo[:, 2] < 0).any())      # some samples refract
    True
    >>> v = RoughDielectric(distribution="ggx", alpha_u=0.1, alpha_v=0.4, intIOR=1.5, extIOR=1.0)
    >>> s = v.sample(wi, np.random.default_rng(2).random((4, 3)))
    >>> bool(np.allclose(s.pdf, v.pdf(wi, s.wo)))
    True
    """

    type_name = "roughdielectric"
    texture_slots = ("alpha", "ka", "m_ka")
    KNOWN = {"alpha": "float", **KNOWN_OPTIONS, "intIOR": "float", "extIOR": "float", "ka": "color"}
    two_sided = True
    has_transmission = True

    def __init__(self, alpha: Texture | float = 0.1, intIOR: float = INT_IOR, extIOR: float = EXT_IOR,  # noqa: N803
                 ka: Texture | np.ndarray | float = 1.0, distribution: str = mf.BECKMANN, alpha_u: float | None = None,
                 alpha_v: float | None = None, sample_visible: bool | None = None) -> None:
        self.alpha = as_texture(alpha)
        self.set_options(distribution, alpha_u, alpha_v, sample_visible)
        self.int_ior, self.ext_ior = float(intIOR), float(extIOR)
        self.ka = as_texture(ka)

    @classmethod
    def from_properties(cls, props: PropertyList) -> RoughDielectric:
        """Build from a ``<bsdf type="roughdielectric">`` property list."""
        props.check_known(cls.KNOWN)
        options = option_properties(props)
        int_ior, ext_ior = check_iors(props)
        return cls(check_alpha(props), int_ior, ext_ior, props.reflectance("ka", np.ones(3)), **options)

    @property
    def m_ka(self) -> Texture:
        """The course's name of the ``ka`` texture slot (spec §10.7)."""
        return self.ka

    def set_texture(self, slot: str, texture: Texture) -> None:
        """Attach a texture to ``alpha`` or ``ka`` (``m_ka`` is the same slot under the course's name)."""
        setattr(self, "ka" if slot == "m_ka" else slot, texture)

    def scalar_parameters(self) -> tuple:
        """(η_int, η_ext, distribution, α_u, α_v, sample_visible)."""
        return (self.int_ior, self.ext_ior, *self.option_parameters())

    def eta_ratio(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """η_o/η_i (N,): int/ext for ω_i outside and ω_o inside, ext/int the other way, 1 on one side."""
        return side_eta_ratio(wi, wo, self.int_ior, self.ext_ior)

    # -- the model, in the frame flipped so that ω_i is above ------------------------------------------------
    def _media(self, wi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(s, η_i, η_t): s = +1 where ω_i is on the normal's side (cos θ_i ≥ 0), −1 inside."""
        s = np.where(wi[:, 2] >= 0, 1.0, -1.0)
        return s, np.where(s > 0, self.ext_ior, self.int_ior), np.where(s > 0, self.int_ior, self.ext_ior)

    def jacobian_t(self, wih: np.ndarray, woh: np.ndarray, eta_i: np.ndarray, eta_t: np.ndarray) -> np.ndarray:
        """dω_h/dω_o of refraction, η_t² |ω_o·ω_h| / (η_i ω_i·ω_h + η_t ω_o·ω_h)² (Walter eq. 17)."""
        den = eta_i * wih + eta_t * woh
        with np.errstate(divide="ignore", invalid="ignore"):
            return eta_t * eta_t * np.abs(woh) / (den * den)

    def fresnel(self, s: np.ndarray, wih: np.ndarray, wi_f: np.ndarray) -> np.ndarray:
        """F(ω_i·ω_h) of the microfacet, the cosine measured against the exterior normal (s·ω_i·ω_h)."""
        return fresnel_dielectric(s * wih, self.ext_ior, self.int_ior)

    def refraction(self, c: np.ndarray, wi_f: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(F, cos θ_t, η) of a microfacet for the sampler, c = ω_i·ω_h against the exterior normal (``wi_f``, ω_i in
        the flipped frame, is for the judges' negative controls)."""
        return dielectric_refraction(c, self.ext_ior, self.int_ior)

    def _terms(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None, need_f: bool,
               need_pdf: bool) -> tuple[np.ndarray | None, np.ndarray | None]:
        """f and/or p of the same directions, sharing ω_h, D, F and the Jacobian."""
        n = len(wi)
        s, eta_i, eta_t = self._media(wi)
        flip = np.stack([np.ones(n), np.ones(n), s], axis=1)
        wi_f, wo_f = wi * flip, wo * flip
        ci, co = wi_f[:, 2], wo_f[:, 2]
        refl, trans = co > 0, co < 0
        h = np.where(refl[:, None], wi_f + wo_f, -(eta_i[:, None] * wi_f + eta_t[:, None] * wo_f))
        norm = np.sqrt(_dot(h, h))
        okh = norm > 1e-12
        h = h / np.where(okh, np.where(h[:, 2] < 0, -norm, norm), 1.0)[:, None]
        wih, woh = _dot(wi_f, h), _dot(wo_f, h)
        ok = (ci > 0) & okh & (wih > 0) & (refl | (trans & (woh < 0)))
        d, g, alphas = self.d_g1(h, wi_f if need_f else None, wo_f, uv, n, wih, woh)
        fr = self.fresnel(s, wih, wi_f)
        jac = np.where(refl, 1.0, self.jacobian_t(wih, woh, eta_i, eta_t))
        f = pdf = None
        if need_f:
            with np.errstate(divide="ignore", invalid="ignore"):
                r = fr * d * g / (4.0 * ci * co)
                t = wih * eta_i * eta_i * (1.0 - fr) * d * g * jac / (ci * np.abs(co) * eta_t * eta_t)
            r = np.where(ok & refl & np.isfinite(r), r, 0.0)
            t = np.where(ok & trans & np.isfinite(t), t, 0.0)
            ka = self.ka.value if self.ka.constant else self.ka.eval(uv_or_zeros(uv, n))
            f = r[:, None] + t[:, None] * np.broadcast_to(np.asarray(ka, dtype=np.float64), (n, 3))
        if need_pdf:
            w = self.normal_factor(wi_f, h, wih, alphas)  # D·w: the density of ω_h (cos θ_h, or visible)
            with np.errstate(divide="ignore", invalid="ignore"):
                p = np.where(refl, fr * d * w / (4.0 * np.abs(woh)), (1.0 - fr) * d * w * jac)
            pdf = np.where(ok & np.isfinite(p), p, 0.0)
        return f, pdf

    def eval(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None = None) -> np.ndarray:
        """f(ω_i, ω_o) (N, 3), without the cosine: f_r on ω_i's side, f_t on the other."""
        return self._terms(wi, wo, uv, True, False)[0]

    def pdf(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None = None) -> np.ndarray:
        """Solid-angle density (N,) of :meth:`sample` over the whole sphere."""
        return self._terms(wi, wo, uv, False, True)[1]

    def eval_pdf(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """f and p together (one half vector, one D, one F)."""
        return self._terms(wi, wo, uv, True, True)

    def sample(self, wi: np.ndarray, u: np.ndarray, uv: np.ndarray | None = None) -> BSDFSample:
        """ω_h ∝ D cos θ_h (or a visible normal), then reflect (probability F) or refract about it (see the module
        docstring)."""
        n = len(wi)
        s, _, _ = self._media(wi)
        flip = np.stack([np.ones(n), np.ones(n), s], axis=1)
        wi_f = wi * flip
        with np.errstate(invalid="ignore", divide="ignore"):
            h = self.sample_normals(wi_f, u, uv)
        wih = _dot(wi_f, h)
        fr, cos_t, eta = self.refraction(s * wih, wi_f)
        refl = u[:, 2] < fr
        wo_r = 2.0 * wih[:, None] * h - wi_f
        wo_t = -eta[:, None] * wi_f + (eta * wih - cos_t)[:, None] * h
        wo_f = np.where(refl[:, None], wo_r, wo_t)
        ok = (wih > 0) & (wi_f[:, 2] > 0) & np.where(refl, wo_f[:, 2] > 0, wo_f[:, 2] < 0)
        if not self.default_options:  # a failed normal (grazing ω_i, ξ1 = 1 of an unbounded warp): a finite ω_o
            wo_f = np.where(np.isfinite(wo_f), wo_f, np.array([0.0, 0.0, -1.0]))
        wo = wo_f * flip
        f, pdf = self.eval_pdf(wi, wo, uv)
        pdf = np.where(ok, pdf, 0.0)
        return BSDFSample(wo, abs_cos_weight(f, wo, pdf), pdf)
