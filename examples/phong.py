"""``phong``: a normalised Phong lobe about the mirror direction, sampled exactly — an example brdflab plugin.

==============  ==================  ===============  ======================================================
parameter       tag                 default          meaning
==============  ==================  ===============  ======================================================
``ks``          color               0.8, 0.8, 0.8    albedo at normal incidence (per channel, ≤ 1)
``exponent``    float               20               Phong exponent n > 0 (larger: sharper lobe)
==============  ==================  ===============  ======================================================

Evaluation (the "modified Phong" BRDF normalised for energy, Lafortune & Willems 1994, eq. 9 and §4):

    f(ω_i, ω_o) = k_s (n + 2)/(2π) · max(0, cos α)^n,     cos α = ω_o · m(ω_i),  m(ω_i) = (−x_i, −y_i, z_i),

zero unless cos θ_i > 0 and cos θ_o > 0. cos α is symmetric in ω_i and ω_o, so f is reciprocal.

Sampling: ω_o about m with density p(ω_o) = (n + 1)/(2π) · max(0, cos α)^n over the whole sphere (the
lobe's cosine power; ∫ p dω = 1), by inverting its CDF: cos α = ξ1^(1/(n+1)), φ = 2π ξ2, rotated into the
frame of m (Duff et al. 2017, "Building an orthonormal basis, revisited", listing 3). Directions below
the surface keep their density and get weight 0. The weight is f cos θ_o / p = k_s (n + 2)/(n + 1) cos θ_o,
so ρ(0) = k_s exactly.

Load it with ``--plugin examples/phong.py`` (a plugin file's BSDF classes are registered when it is loaded; from
Python, ``bl.load_plugin("examples/phong.py")`` does the same, or import the class and call
``bl.register_bsdf(Phong)`` as the tutorial does); it declares a sweep over the exponent for the battery. Its
twin ``phong_broken`` has a warp bug (the lobe is sampled about the normal instead of the mirror direction,
the pdf left right): the chi-square test must reject it for every θ_i > 0.
"""

from __future__ import annotations

import numpy as np

from brdflab import BSDF, BSDFSample


def _basis(m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing the unit vectors ``m`` (N, 3) to orthonormal frames (Duff et al. 2017)."""
    sign = np.where(m[:, 2] >= 0, 1.0, -1.0)
    a = -1.0 / (sign + m[:, 2])
    b = m[:, 0] * m[:, 1] * a
    t = np.stack([1.0 + sign * m[:, 0] ** 2 * a, sign * b, -sign * m[:, 0]], axis=1)
    s = np.stack([b, sign + m[:, 1] ** 2 * a, -m[:, 1]], axis=1)
    return t, s


class Phong(BSDF):
    """Normalised Phong lobe about the mirror direction (see the module docstring)."""

    type_name = "phong"
    #: Grid the validation battery sweeps (a BSDF without ``alpha`` is otherwise swept over θ only).
    sweep = {"exponent": [5.0, 20.0, 100.0]}

    def __init__(self, ks=(0.8, 0.8, 0.8), exponent: float = 20.0) -> None:
        self.ks = np.broadcast_to(np.asarray(ks, dtype=np.float64), (3,)).copy()
        self.exponent = float(exponent)
        if not self.exponent > 0:
            raise ValueError(f"exponent must be > 0, got {exponent}")

    @staticmethod
    def _mirror(wi: np.ndarray) -> np.ndarray:
        return wi * np.array([-1.0, -1.0, 1.0])

    def _cos_alpha(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        return np.clip(np.sum(self._mirror(wi) * wo, axis=1), 0.0, 1.0)

    def eval(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None = None) -> np.ndarray:
        """f(ω_i, ω_o) (N, 3), without the cosine."""
        n = self.exponent
        up = (wi[:, 2] > 0) & (wo[:, 2] > 0)
        lobe = np.where(up, (n + 2) / (2 * np.pi) * self._cos_alpha(wi, wo) ** n, 0.0)
        return lobe[:, None] * self.ks

    def pdf(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None = None) -> np.ndarray:
        """p(ω_o) = (n + 1)/(2π) cos^n α on the whole sphere; 0 for cos θ_i ≤ 0."""
        n = self.exponent
        return np.where(wi[:, 2] > 0, (n + 1) / (2 * np.pi) * self._cos_alpha(wi, wo) ** n, 0.0)

    def _lobe_axis(self, wi: np.ndarray) -> np.ndarray:
        return self._mirror(wi)

    def sample(self, wi: np.ndarray, u: np.ndarray, uv: np.ndarray | None = None) -> BSDFSample:
        """cos α = ξ1^(1/(n+1)), φ = 2πξ2 about the mirror direction; weight = f cos θ_o / p."""
        cos_a = u[:, 0] ** (1.0 / (self.exponent + 1.0))
        sin_a = np.sqrt(np.maximum(0.0, 1.0 - cos_a * cos_a))
        phi = 2.0 * np.pi * u[:, 1]
        axis = self._lobe_axis(wi)
        t, s = _basis(axis)
        wo = (sin_a * np.cos(phi))[:, None] * t + (sin_a * np.sin(phi))[:, None] * s + cos_a[:, None] * axis
        wo /= np.linalg.norm(wo, axis=1, keepdims=True)
        pdf = self.pdf(wi, wo)
        f = self.eval(wi, wo)
        ok = (pdf > 0) & (wo[:, 2] > 0)
        weight = np.where(ok[:, None], f * (np.maximum(wo[:, 2], 0.0) / np.where(ok, pdf, 1.0))[:, None], 0.0)
        return BSDFSample(wo, weight, pdf)


class PhongBroken(Phong):
    """The deliberately broken twin: samples the lobe about the normal, while :meth:`pdf` (unchanged) is right."""

    type_name = "phong_broken"

    def _lobe_axis(self, wi: np.ndarray) -> np.ndarray:
        return np.broadcast_to([0.0, 0.0, 1.0], wi.shape).copy()  # BUG: forgot to rotate to the mirror direction
