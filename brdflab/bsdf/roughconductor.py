"""``roughconductor``: microfacet conductor, Beckmann or GGX, Schlick or exact conductor Fresnel (spec §10.5; PBR §8.4).

==================  ==========================================  ============  =====================================
parameter           tag                                         default       meaning
==================  ==========================================  ============  =====================================
``R0``              color, or child ``texture name="R0"``       0.5           reflectance at normal incidence
                                                                              (Schlick; unused with ``eta``)
``alpha``           float, or child ``texture name="alpha"``    0.1           roughness α (> 0; a texture's
                                                                              luminance is used); sets α_u and α_v
``alpha_u``         float                                       ``alpha``     α along the shading frame's x axis
``alpha_v``         float                                       ``alpha``     α along the shading frame's y axis
``distribution``    string: ``beckmann`` or ``ggx``             ``beckmann``  the microfacet distribution D
``sample_visible``  boolean                                     true for      sample visible normals (Heitz 2018)
                                                                ggx           instead of D cos θ_h
``eta``, ``k``      color                                       (none)        complex index η + ik of the metal
                                                                              (relative to the outside; k: 0)
``material``        string: ``Au``, ``Ag``, ``Cu``, ``Al``      (none)        η and k of a metal
                                                                              (:mod:`brdflab.bsdf.conductors`)
==================  ==========================================  ============  =====================================

Evaluation (Torrance–Sparrow, PBR eq. 8.18 without the extra cos θ_h, as the course references require):

    f(ω_i, ω_o) = D(ω_h) · F(ω_h·ω_i) · G1(ω_i, ω_h) G1(ω_o, ω_h) / (4 cos θ_i cos θ_o),

ω_h = normalize(ω_i + ω_o), zero unless cos θ_i, cos θ_o > 0; D and G1 in :mod:`brdflab.bsdf.microfacet`
(Beckmann with the course's rational G1, GGX with its exact G1; anisotropic with α_u along the frame's x axis);
F = F_Schlick(·; R0), or with ``eta``/``material`` the exact conductor Fresnel (:func:`~brdflab.bsdf.fresnel.
fresnel_conductor`, PBR-3 eq. 8.6). The defaults (Beckmann, one α, no visible-normal sampling, Schlick) are
the course's model and run its original code path, bit for bit.

Sampling: ω_h ∝ D cos θ_h (the Beckmann warp, or :func:`~brdflab.bsdf.microfacet.sample_normals`), or with
``sample_visible`` from the visible normals (:func:`~brdflab.bsdf.microfacet.sample_visible_normals`); then
ω_o = reflect(ω_i, ω_h), so p(ω_o) = D(ω_h) cos θ_h / (4 |ω_o·ω_h|) (PBR eq. 8.13), or with visible normals
p(ω_o) = G1(ω_i) max(0, ω_i·ω_h) D(ω_h)/cos θ_i · 1/(4 |ω_o·ω_h|) with the exact G1 (for Beckmann, the erf
form: it is the sampler's density; f keeps the rational G1). weight = f cos θ_o / p. Samples whose ω_o lies
below the surface keep their direction and density but get weight 0; samples from microfacets facing away
from ω_i (ω_i·ω_h ≤ 0) fail (pdf 0): those directions cannot be produced consistently.

The tangent of anisotropic α: the local frame's x axis (α_u) follows the mesh's uv parameterisation. A
material whose α_u and α_v may differ (:attr:`RoughConductor.anisotropic`) is shaded, on a mesh with uvs (OBJ
``vt``; the bundled shapes have them), in the frame s = normalize(dp/du − n (n·dp/du)), t = n × s, with dp/du
of the hit's triangle (PBR-3 §3.6.2, :mod:`brdflab.scene.tangents`) and n the shading normal (Gram–Schmidt,
:mod:`brdflab.math.frame`). The fallback, where a mesh has no uvs, a triangle's uvs are degenerate or dp/du is
parallel to n: the frame built from the shading normal alone (Duff et al. 2017), whose s is a fixed function of
the normal (continuous over a flat or gently curved surface whose normals keep the sign of n_z), not the
texture's u direction. Isotropic materials always use that frame (their values do not depend on it; so the
course's scenes render to the same bits).
"""

from __future__ import annotations

import numpy as np

from brdflab.bsdf import microfacet as mf
from brdflab.bsdf.base import BSDF, BSDFSample, cos_weight, uv_or_zeros
from brdflab.bsdf.conductors import MATERIALS, metal_eta_k
from brdflab.bsdf.fresnel import fresnel_conductor, fresnel_schlick
from brdflab.bsdf.microfacet import beckmann_d, half_vector, reflect, reflection_pdf, smith_g1
from brdflab.bsdf.microfacet_options import (  # noqa: F401 (alpha_values: re-exported)
    KNOWN_OPTIONS,
    MicrofacetOptions,
    alpha_values,
    check_alpha,
    option_properties,
)
from brdflab.errors import clean
from brdflab.kernels import twin
from brdflab.scene.properties import PropertyList
from brdflab.texture import Texture, as_texture


class RoughConductor(MicrofacetOptions, BSDF):
    """Rough conductor: Beckmann or GGX, isotropic or anisotropic, Schlick or (η, k) Fresnel (module docstring).

    Parameters
    ----------
    R0
        Reflectance at normal incidence (Schlick): a number, an RGB triple or a texture.
    alpha
        Roughness (> 0): a number or a texture (its luminance is used); α_u and α_v unless given.
    distribution
        ``"beckmann"`` (the course's) or ``"ggx"``.
    alpha_u, alpha_v
        Anisotropic roughness along the local x and y axes (default: ``alpha``).
    sample_visible
        Sample visible normals (default: True for GGX, False for Beckmann).
    eta, k
        Complex index of refraction η + ik (colours) for the exact conductor Fresnel term, instead of R0.
    material
        A metal's name (``"Au"``, ``"Ag"``, ``"Cu"``, ``"Al"``): its η and k.

    Examples
    --------
    >>> import numpy as np
    >>> from brdflab import RoughConductor
    >>> m = RoughConductor(R0=0.9, alpha=0.1)
    >>> wi = np.array([[0.0, 0.0, 1.0]])
    >>> s = m.sample(wi, np.full((1, 3), 0.5))
    >>> bool(np.allclose(s.weight, m.eval(wi, s.wo) * s.wo[:, 2:] / s.pdf[:, None]))
    True
    >>> g = RoughConductor(distribution="ggx", alpha_u=0.2, alpha_v=0.45, eta=(0.2, 0.92, 1.1), k=(3.9, 2.45, 2.14))
    >>> s = g.sample(np.array([[0.6, 0.0, 0.8]]), np.full((1, 3), 0.3))
    >>> bool(np.allclose(s.pdf, g.pdf(np.array([[0.6, 0.0, 0.8]]), s.wo)))
    True
    """

    #: Instances differing only in constants are evaluated as one batch (:mod:`brdflab.bsdf.family`).
    batchable = True
    type_name = "roughconductor"
    #: Compiled twin in :mod:`brdflab.kernels.bsdf` (own body only: subclasses stay on NumPy).
    kernel = "roughconductor"
    texture_slots = ("R0", "alpha")
    #: What ``fit`` adjusts by default (the optional anisotropy and η/k are alternatives to R0 and alpha).
    fit_parameters = ("R0", "alpha")
    KNOWN = {"R0": "color", "alpha": "float", **KNOWN_OPTIONS, "eta": "color", "k": "color", "material": "string"}

    def __init__(self, R0: Texture | np.ndarray | float = 0.5, alpha: Texture | float = 0.1,  # noqa: N803
                 distribution: str = mf.BECKMANN, alpha_u: float | None = None, alpha_v: float | None = None,
                 sample_visible: bool | None = None, eta=None, k=None, material: str | None = None) -> None:
        self.R0 = as_texture(R0)
        self.alpha = as_texture(alpha)
        self.set_options(distribution, alpha_u, alpha_v, sample_visible)
        if material is not None:
            if eta is not None or k is not None:
                raise ValueError("give either material or eta/k, not both")
            if material not in MATERIALS:
                raise ValueError(f"unknown material {material!r}; known: {', '.join(MATERIALS)}")
            eta, k = metal_eta_k(material)
        if eta is None and k is not None:
            raise ValueError("k needs eta")
        self.material = material
        self.eta = None if eta is None else np.broadcast_to(np.asarray(eta, np.float64), (3,)).copy()
        self.k = None if eta is None else np.broadcast_to(np.asarray(0.0 if k is None else k, np.float64),
                                                          (3,)).copy()
        if self.eta is not None and not (np.all(np.isfinite(self.eta)) and np.all(self.eta > 0)
                                         and np.all(np.isfinite(self.k)) and np.all(self.k >= 0)):
            raise ValueError(f"eta must be finite and > 0 and k finite and >= 0, got {self.eta}, {self.k}")

    @classmethod
    def from_properties(cls, props: PropertyList) -> RoughConductor:
        """Build from a ``<bsdf type="roughconductor">`` property list."""
        props.check_known(cls.KNOWN)
        options = option_properties(props)
        material = props.get_string("material") if "material" in props else None
        if material is not None and material not in MATERIALS:
            raise props.error("material", f"'material' must be one of {', '.join(MATERIALS)}, "
                              f"got '{clean(material, 30)}'")
        if material is not None and ("eta" in props or "k" in props):
            raise props.error("material", "give either 'material' or 'eta'/'k', not both")
        if "k" in props and "eta" not in props:
            raise props.error("k", "'k' needs 'eta' (the real part of the index)")
        if ("eta" in props or material is not None) and "R0" in props:
            raise props.error("R0", "'R0' (Schlick) and 'eta'/'k'/'material' are alternatives: give one")
        eta = k = None
        if "eta" in props:
            eta = props.nonnegative_color("eta")
            if np.any(eta <= 0):
                raise props.error("eta", f"'eta' must have components > 0, got {eta.tolist()}")
            k = props.nonnegative_color("k", np.zeros(3))
        return cls(props.reflectance("R0", np.full(3, 0.5)), check_alpha(props), eta=eta, k=k, material=material,
                   **options)

    def scalar_parameters(self) -> tuple:
        """The non-texture parameters (members of a material family share them)."""
        return (*self.option_parameters(),
                None if self.eta is None else tuple(self.eta), None if self.k is None else tuple(self.k))

    @property
    def course_model(self) -> bool:
        """True for the course's model (Beckmann, one α, D cos θ_h sampling, Schlick): its original code path."""
        return (self.distribution == mf.BECKMANN and self.alpha_u is None and self.alpha_v is None
                and not self.sample_visible and self.eta is None)

    def _fresnel(self, hi: np.ndarray, uv: np.ndarray | None, n: int, s: np.ndarray) -> np.ndarray:
        c = np.clip(hi, 0.0, 1.0)
        if self.eta is None:
            r0 = self.R0.value if self.R0.constant else self.R0.eval(uv_or_zeros(uv, n))
            return fresnel_schlick(c, r0, s)
        return fresnel_conductor(c, self.eta, self.k) * s[:, None]

    def _terms(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None, need_f: bool,
               need_pdf: bool) -> tuple[np.ndarray | None, np.ndarray | None]:
        """f and/or p of the same directions, sharing ω_h, D(ω_h) and ω_i·ω_h."""
        n = len(wi)
        iso = self.isotropic_beckmann
        if iso:
            a = alpha_values(self.alpha, uv, n)
        else:
            ax, ay = self.alphas(uv, n)
        ci = wi[:, 2]
        wh, okh = half_vector(wi, wo)
        hi = wh[:, 0] * wi[:, 0] + wh[:, 1] * wi[:, 1] + wh[:, 2] * wi[:, 2]
        d = beckmann_d(wh[:, 2], a) if iso else mf.ndf(self.distribution, wh, ax, ay)
        f = pdf = None
        if need_f:
            co = wo[:, 2]
            ok = (ci > 0) & (co > 0) & okh
            if iso:
                g = smith_g1(wi, wh, a, hi) * smith_g1(wo, wh, a)
            else:
                g = mf.g1(self.distribution, wi, wh, ax, ay, hi) * mf.g1(self.distribution, wo, wh, ax, ay)
            with np.errstate(divide="ignore", invalid="ignore"):
                s = np.where(ok, d * g / (4.0 * ci * co), 0.0)
            s = np.where(np.isfinite(s), s, 0.0)
            f = self._fresnel(hi, uv, n, s)
        if need_pdf:
            ok = (ci > 0) & okh & (hi > 0)
            if self.sample_visible:
                p = mf.visible_pdf(self.distribution, wi, wh, wo, *((a, a) if iso else (ax, ay)), d, hi)
            else:
                p = reflection_pdf(wh, wo, None, d)
            pdf = np.where(ok, p, 0.0)
        return f, pdf

    @twin("bsdf", "eval_bsdf")
    def eval(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None = None) -> np.ndarray:
        """f(ω_i, ω_o) (N, 3), without the cosine."""
        return self._terms(wi, wo, uv, True, False)[0]

    @twin("bsdf", "pdf_bsdf")
    def pdf(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None = None) -> np.ndarray:
        """p(ω_o) (module docstring), 0 for cos θ_i ≤ 0 or ω_i·ω_h ≤ 0."""
        return self._terms(wi, wo, uv, False, True)[1]

    @twin("bsdf", "eval_pdf_bsdf")
    def eval_pdf(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """f and p together (one half vector and one D(ω_h))."""
        return self._terms(wi, wo, uv, True, True)

    @twin("bsdf", "sample_bsdf")
    def sample(self, wi: np.ndarray, u: np.ndarray, uv: np.ndarray | None = None) -> BSDFSample:
        """Sample ω_h (∝ D cos θ_h, or the visible normals) and reflect ω_i about it.

        f and p are then evaluated from (ω_i, ω_o) exactly as :meth:`eval` and :meth:`pdf` do, so the
        weight is eval·cos/pdf and the pdf equals :meth:`pdf` to the last bit. A microfacet facing away
        from ω_i (ω_i·ω_h < 0) gives an ω_o whose half vector is −ω_h, below the surface: D = 0 there, so
        such samples fail (pdf 0).
        """
        with np.errstate(invalid="ignore"):
            wo = reflect(wi, self.sample_normals(wi, u, uv))
        wo = np.where(np.isfinite(wo), wo, np.array([0.0, 0.0, -1.0]))  # ξ1 = 1 of an unbounded warp: fails
        f, pdf = self.eval_pdf(wi, wo, uv)
        return BSDFSample(wo, cos_weight(f, wo, pdf), pdf)
