"""Negative controls of the transmission and delta judges: deliberately broken glass that the checks must reject.

=====================================  ==========================================================  ===================
class                                  the bug (a student's, spec §10.4 and Walter et al. 2007)    rejected by
=====================================  ==========================================================  ===================
:class:`InvertedEtaDielectric`         Snell's law with η = η_t/η_i (directions and weights)       :mod:`.delta`
:class:`WrongCosineDielectric`         Fresnel of cos θ_t instead of cos θ_i (lobe frequencies)    :mod:`.delta`
:class:`NoJacobianRoughDielectric`     pdf without dω_h/dω_o = η_t²|ω_o·ω_h|/(η_i ω_i·ω_h +        chi-square
                                       η_t ω_o·ω_h)² of the transmitted half vector
:class:`InvertedEtaRoughDielectric`    refraction about ω_h with η inverted (sampling only)        chi-square
:class:`VndfWithoutG1RoughDielectric`  GGX visible-normal pdf without G1(ω_i) (issue 45)            chi-square
:class:`SwappedAlphaRoughDielectric`   anisotropic GGX, α_u/α_v swapped in the sampler only        chi-square
:class:`MacroCosineRoughDielectric`    Fresnel of the macro-normal cos θ_i instead of ω_i·ω_h, in  reciprocity
                                       eval, pdf and sampling alike (so sample and pdf agree)      (consistency)
=====================================  ==========================================================  ===================

:func:`run_controls` runs the first six the way the battery does and returns their results (each must fail);
the last one is a test of the consistency check (tests/test_transmission_judges.py).
"""

from __future__ import annotations

import numpy as np

from brdflab.bsdf import microfacet as mf
from brdflab.bsdf.dielectric import Dielectric
from brdflab.bsdf.fresnel import dielectric_refraction, fresnel_dielectric
from brdflab.bsdf.roughdielectric import RoughDielectric
from brdflab.judges.material.entries import SwappedAlphaSampler


def _inverted(f: np.ndarray, cos_i: np.ndarray, eta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    bad = 1.0 / eta
    ct = np.sqrt(np.maximum(0.0, 1.0 - bad * bad * (1.0 - cos_i * cos_i)))
    return f, ct, bad


class InvertedEtaDielectric(Dielectric):
    """Refracts with η_t/η_i instead of η_i/η_t (and weighs by its square)."""

    type_name = "dielectric with η inverted"

    def fresnel(self, cos_i):
        """Correct F, but the inverted η and the cos θ_t it gives."""
        f, _, eta = super().fresnel(cos_i)
        return _inverted(f, cos_i, eta)


class WrongCosineDielectric(Dielectric):
    """Fresnel evaluated at cos θ_t (same media order) instead of cos θ_i."""

    type_name = "dielectric with Fresnel of cos θ_t"

    def fresnel(self, cos_i):
        """F(cos θ_t) with the correct refraction."""
        _, ct, eta = super().fresnel(cos_i)
        f = fresnel_dielectric(np.where(cos_i >= 0, ct, -ct), self.ext_ior, self.int_ior)
        return np.where(ct > 0, f, 1.0), ct, eta


class NoJacobianRoughDielectric(RoughDielectric):
    """The transmitted density without the half-vector Jacobian (the density of ω_h used for ω_o)."""

    type_name = "roughdielectric without transmission Jacobian"

    def jacobian_t(self, wih, woh, eta_i, eta_t):
        """1 instead of η_t²|ω_o·ω_h|/(η_i ω_i·ω_h + η_t ω_o·ω_h)²."""
        return np.ones_like(wih)


class InvertedEtaRoughDielectric(RoughDielectric):
    """Samples refract about ω_h with η_t/η_i; eval and pdf are right."""

    type_name = "roughdielectric with η inverted"

    def refraction(self, c, wi_f=None):
        """Correct F, the inverted η."""
        f, _, eta = super().refraction(c, wi_f)
        return _inverted(f, np.abs(c), eta)


class VndfWithoutG1RoughDielectric(RoughDielectric):
    """GGX with visible normals whose pdf omits G1(ω_i) (reflection and transmission): it does not integrate to 1."""

    type_name = "roughdielectric, visible-normal pdf without G1(ω_i)"

    def __init__(self, alpha=0.3, intIOR=1.5, extIOR=1.0, **kw):  # noqa: N803
        super().__init__(alpha, intIOR, extIOR, **{"distribution": "ggx", "sample_visible": True, **kw})

    def _terms(self, wi, wo, uv, need_f, need_pdf):
        f, pdf = super()._terms(wi, wo, uv, need_f, need_pdf)
        if need_pdf:  # Λ depends on z² only: the same from either side
            pdf = pdf * (1.0 + mf.smith_lambda(self.distribution, wi, *self.alphas(uv, len(wi))))
        return f, pdf


class SwappedAlphaRoughDielectric(SwappedAlphaSampler, RoughDielectric):
    """Anisotropic GGX (α_u = 0.1, α_v = 0.4) whose sampler swaps α_u and α_v; eval and pdf are right."""

    type_name = "roughdielectric, α_u/α_v swapped in the sampler"

    def __init__(self, alpha=0.3, intIOR=1.5, extIOR=1.0, **kw):  # noqa: N803
        super().__init__(alpha, intIOR, extIOR, **{"distribution": "ggx", "alpha_u": 0.1, "alpha_v": 0.4, **kw})


class MacroCosineRoughDielectric(RoughDielectric):
    """F(cos θ_i) of the macro normal everywhere (consistent between sample and pdf, so chi-square passes)."""

    type_name = "roughdielectric with Fresnel of cos θ_i"

    def fresnel(self, s, wih, wi_f):
        """F of the macro-normal cosine."""
        return fresnel_dielectric(s * wi_f[:, 2], self.ext_ior, self.int_ior)

    def refraction(self, c, wi_f=None):
        """The sampling's F from the macro cosine too (Snell about ω_h stays right)."""
        _, ct, eta = dielectric_refraction(c, self.ext_ior, self.int_ior)
        s = np.where(c >= 0, 1.0, -1.0)
        return fresnel_dielectric(s * wi_f[:, 2], self.ext_ior, self.int_ior), ct, eta


def run_controls(n: int, threshold: float, progress=None) -> list:
    """The six controls of the battery (delta: θ_i = 60°, 150°; chi-square: α = 0.3, θ_i = 30°, 150°, or 60°,
    120° for the pdf without G1(ω_i)); each result must fail (``passed`` False)."""
    from brdflab.judges.core.seeding import test_seed
    from brdflab.judges.material import chi2 as c2
    from brdflab.judges.material.delta import delta_test

    out = []
    for cls in (InvertedEtaDielectric, WrongCosineDielectric):
        for t in (60.0, 150.0):
            out.append(delta_test(cls(1.5, 1.0), theta=t, samples=min(n, 100_000), name=cls.type_name,
                                  params={"intIOR": 1.5, "theta": t}, threshold=threshold,
                                  seed=test_seed("neg-delta", cls.type_name, t)))
    # Without G1(ω_i) the pdf is off by 1 + Λ(ω_i), < 1 % at 30° from the normal (α = 0.3): 60° from either side.
    for cls, thetas in ((NoJacobianRoughDielectric, (30.0, 150.0)), (InvertedEtaRoughDielectric, (30.0, 150.0)),
                        (VndfWithoutG1RoughDielectric, (60.0, 120.0)), (SwappedAlphaRoughDielectric, (30.0, 150.0))):
        for t in thetas:
            seed = test_seed("neg-rough", cls.type_name, t)
            out.append(c2.bsdf_test(cls.type_name, cls(0.3, 1.5, 1.0), t, n, seed=seed,
                                    params={"alpha": 0.3, "theta": t}, threshold=threshold))
    if progress:
        for r in out:
            progress(f"{'REJECTED (good)' if not r.passed else 'NOT REJECTED (bad)'}  negative control {r.name} "
                     f"θ={r.params['theta']:g}: p = {r.p_value:.3g}" + (f" ({r.fault})" if r.fault else ""))
    return out
