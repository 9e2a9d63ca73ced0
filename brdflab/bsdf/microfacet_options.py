"""The microfacet options the rough materials share (issue 45): ``distribution``, ``alpha_u``/``alpha_v``,
``sample_visible`` — of ``roughconductor``, ``roughdielectric`` and ``roughsubstrate``'s coat.

=================  ========================================  ============  ======================================
parameter          tag                                       default       meaning
=================  ========================================  ============  ======================================
``alpha``          float, or child ``texture name="alpha"``  0.1           roughness α (> 0); sets α_u and α_v
``alpha_u``        float                                     ``alpha``     α along the shading frame's x axis
``alpha_v``        float                                     ``alpha``     α along the shading frame's y axis
``distribution``   string: ``beckmann`` or ``ggx``           ``beckmann``  the microfacet distribution D
``sample_visible`` boolean                                   true for ggx  sample visible normals (Heitz 2018)
=================  ========================================  ============  ======================================

The formulas are in :mod:`brdflab.bsdf.microfacet`. The defaults (Beckmann, one α, normals ∝ D cos θ_h) are the
course's model: :attr:`MicrofacetOptions.isotropic_beckmann` materials run the course's functions
(:func:`~brdflab.bsdf.microfacet.beckmann_d`, :func:`~brdflab.bsdf.microfacet.smith_g1`,
:func:`~brdflab.math.warps.square_to_beckmann`), bit for bit as before.
"""

from __future__ import annotations

import numpy as np

from brdflab.bsdf import microfacet as mf
from brdflab.bsdf.base import uv_or_zeros
from brdflab.errors import clean
from brdflab.math import warps
from brdflab.scene.properties import PropertyList
from brdflab.texture import Texture

#: The options' parameter kinds (added to a material's ``KNOWN``).
KNOWN_OPTIONS = {"alpha_u": "float", "alpha_v": "float", "distribution": "string", "sample_visible": "boolean"}


def alpha_values(tex: Texture, uv: np.ndarray | None, n: int) -> np.ndarray | float:
    """Roughness per query: the constant, or the luminance of a texture at ``uv``."""
    if tex.constant:
        return tex.luminance()  # the weights sum to 1, so a grey value is kept exactly
    return tex.luminance(uv_or_zeros(uv, n))


def check_alpha(props: PropertyList) -> float:
    """Read ``alpha`` and require a finite value > 0."""
    return props.positive_float("alpha", 0.1)


def option_properties(props: PropertyList) -> dict:
    """The options of a property list as constructor keywords (``distribution``, ``alpha_u``, ``alpha_v``,
    ``sample_visible``), with the scene's file and line in the error of a bad value."""
    dist = props.get_string("distribution", mf.BECKMANN)
    if dist not in mf.DISTRIBUTIONS:
        raise props.error("distribution", f"'distribution' must be one of {', '.join(mf.DISTRIBUTIONS)}, "
                          f"got '{clean(dist, 30)}'")
    au = props.positive_float("alpha_u", 1.0) if "alpha_u" in props else None
    av = props.positive_float("alpha_v", 1.0) if "alpha_v" in props else None
    vis = props.get_bool("sample_visible") if "sample_visible" in props else None
    return dict(distribution=dist, alpha_u=au, alpha_v=av, sample_visible=vis)


class MicrofacetOptions:
    """Mix-in of the options (module docstring); the material has an ``alpha`` texture."""

    alpha: Texture

    def set_options(self, distribution: str = mf.BECKMANN, alpha_u: float | None = None,
                    alpha_v: float | None = None, sample_visible: bool | None = None) -> None:
        """Check and store the options (``ValueError`` on a bad one)."""
        if distribution not in mf.DISTRIBUTIONS:
            raise ValueError(f"distribution must be one of {', '.join(mf.DISTRIBUTIONS)}, got {distribution!r}")
        self.distribution = distribution
        for name, v in (("alpha_u", alpha_u), ("alpha_v", alpha_v)):
            if v is not None and not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a finite number > 0, got {v}")
        self.alpha_u = None if alpha_u is None else float(alpha_u)
        self.alpha_v = None if alpha_v is None else float(alpha_v)
        self.sample_visible = (distribution == mf.GGX) if sample_visible is None else bool(sample_visible)

    def option_parameters(self) -> tuple:
        """(distribution, α_u, α_v, sample_visible): part of :meth:`scalar_parameters` (no family mixes them)."""
        return (self.distribution, self.alpha_u, self.alpha_v, self.sample_visible)

    @property
    def anisotropic(self) -> bool:
        """True when α_u and α_v may differ (one of them given, and not both equal): the shading frame then
        follows the uv tangent (module docstring)."""
        au, av = self.alpha_u, self.alpha_v
        if au is None and av is None:
            return False
        if au is None or av is None:
            if not self.alpha.constant:
                return True
            a = float(self.alpha.luminance())
            au, av = (a if au is None else au), (a if av is None else av)
        return au != av

    @property
    def isotropic_beckmann(self) -> bool:
        """Beckmann with one α: the course's D and G1 functions serve it."""
        return self.distribution == mf.BECKMANN and self.alpha_u is None and self.alpha_v is None

    @property
    def default_options(self) -> bool:
        """Beckmann, one α, normals ∝ D cos θ_h: the course's microfacet model and its original code path."""
        return self.isotropic_beckmann and not self.sample_visible

    @property
    def alpha_value(self) -> float:
        """The (mean) roughness, for reports (√(α_u α_v) when anisotropic)."""
        if self.alpha_u is not None or self.alpha_v is not None:
            a = float(np.mean(self.alpha.mean()))
            return float(np.sqrt((self.alpha_u or a) * (self.alpha_v or a)))
        return float(np.mean(self.alpha.mean()))

    def alphas(self, uv: np.ndarray | None, n: int) -> tuple:
        """(α_u, α_v) per query (constants or (n,) arrays)."""
        a = alpha_values(self.alpha, uv, n) if self.alpha_u is None or self.alpha_v is None else None
        return (a if self.alpha_u is None else self.alpha_u), (a if self.alpha_v is None else self.alpha_v)

    def normals_for(self, wi: np.ndarray, u: np.ndarray, ax, ay) -> np.ndarray:
        """Microfacet normals for ``wi`` (z > 0) with roughness (α_u, α_v): visible normals or ∝ D cos θ_h; for
        the default options the course's Beckmann warp (``ax`` = α)."""
        if self.default_options:
            return warps.square_to_beckmann(u[:, :2], ax)
        if self.sample_visible:
            return mf.sample_visible_normals(self.distribution, wi, u, ax, ay)
        return mf.sample_normals(self.distribution, u, ax, ay)

    def sample_normals(self, wi: np.ndarray, u: np.ndarray, uv: np.ndarray | None = None) -> np.ndarray:
        """The microfacet normals the sampler scatters ω_i about (``wi`` in the frame where z > 0)."""
        n = len(wi)
        if self.default_options:
            return self.normals_for(wi, u, alpha_values(self.alpha, uv, n), None)
        return self.normals_for(wi, u, *self.alphas(uv, n))

    def d_g1(self, wh: np.ndarray, v1: np.ndarray, v2: np.ndarray, uv: np.ndarray | None, n: int,
             v1h: np.ndarray | None = None, v2h: np.ndarray | None = None) -> tuple:
        """(D(ω_h), G1(v1, ω_h) G1(v2, ω_h) or None without ``v1``, (α_u, α_v)) for f: the course's functions for
        isotropic Beckmann (the α twice), :func:`~brdflab.bsdf.microfacet.ndf`/``g1`` otherwise."""
        if self.isotropic_beckmann:
            a = alpha_values(self.alpha, uv, n)
            d = mf.beckmann_d(wh[:, 2], a)
            g = None if v1 is None else mf.smith_g1(v1, wh, a, v1h) * mf.smith_g1(v2, wh, a, v2h)
            return d, g, (a, a)
        ax, ay = self.alphas(uv, n)
        d = mf.ndf(self.distribution, wh, ax, ay)
        g = None if v1 is None else (mf.g1(self.distribution, v1, wh, ax, ay, v1h)
                                     * mf.g1(self.distribution, v2, wh, ax, ay, v2h))
        return d, g, (ax, ay)

    def normal_factor(self, wi: np.ndarray, wh: np.ndarray, wih: np.ndarray, alphas: tuple) -> np.ndarray:
        """w with D(ω_h)·w the density of the sampled normal ω_h: w = cos θ_h, or with visible normals
        w = G1(ω_i) max(0, ω_i·ω_h) / cos θ_i with the exact G1 = 1/(1 + Λ(ω_i)) (Heitz 2018, eq. 1)."""
        if not self.sample_visible:
            return wh[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.maximum(wih, 0.0) / ((1.0 + mf.smith_lambda(self.distribution, wi, *alphas)) * wi[:, 2])
