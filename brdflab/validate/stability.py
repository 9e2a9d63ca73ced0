"""Stiff and extreme cases: eval, pdf and sample must give no NaN, no infinity and no negative value.

Cases: α ∈ {10⁻⁴, 10⁻³, 0.5, 1}; θ up to 89.9°; ω_i = ω_o; ω_i = n; ω_o tangent (z = 0); random pairs;
index ratios near 1 (1.0001) and large (10); R0 ∈ {0, 1}. Everything is computed in float64; the
formulas that needed care are noted in :data:`NOTES` and shown in the report.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from brdflab.bsdf.roughconductor import RoughConductor
from brdflab.bsdf.roughsubstrate import RoughSubstrate
from brdflab.math import warps

NOTES = [
    "tan²θ is computed as (1 − cos²θ)/cos²θ from the clamped cosine (never tan of an angle), so D stays "
    "finite at grazing angles and exactly 0 beyond the horizon.",
    "exp(−tan²θ/α²)/(πα²cos⁴θ) is evaluated with over/underflow suppressed and non-finite results mapped to 0: "
    "at α = 10⁻⁴ the peak value is 3·10⁷ (fine in float64, it would lose the tails in float32).",
    "The Beckmann warp forms cos θ_h = 1/√(1 + tan²θ_h) with tan²θ_h = −α² log1p(−ξ), accurate for tiny α.",
    "G1 uses b = 1/(α tan θ_v) with tan θ_v = √(1 − cos²)/|cos|; θ_v = 0 gives b = ∞ → G1 = 1 without NaN.",
    "The Fresnel cosine is clamped to [0, 1]; total internal reflection and η_ext = η_int are handled explicitly.",
    "Sample weights are f·cos/pdf only where pdf > 0 and cos θ_o > 0; anything non-finite is set to 0.",
]


@dataclass
class StabilityRow:
    """One extreme case and what it produced."""

    material: str
    case: str
    n: int
    nan: int
    inf: int
    negative: int

    @property
    def passed(self) -> bool:
        """No NaN, no infinity, no negative value."""
        return self.nan == 0 and self.inf == 0 and self.negative == 0


def _dirs(theta_deg: np.ndarray, phi: np.ndarray) -> np.ndarray:
    t = np.radians(theta_deg)
    return np.stack([np.sin(t) * np.cos(phi), np.sin(t) * np.sin(phi), np.cos(t)], axis=1)


def _cases(rng: np.random.Generator) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    n = 2000
    th = np.concatenate([np.linspace(0, 89.9, n // 2), np.full(n // 2, 89.9)])
    a = _dirs(th, rng.uniform(0, 2 * np.pi, n))
    b = _dirs(rng.uniform(0, 89.9, n), rng.uniform(0, 2 * np.pi, n))
    normal = np.tile([0.0, 0.0, 1.0], (n, 1))
    tangent = _dirs(np.full(n, 90.0), rng.uniform(0, 2 * np.pi, n))
    grazing = _dirs(np.full(n, 89.9), np.zeros(n))
    below = _dirs(rng.uniform(90.1, 180, n), rng.uniform(0, 2 * np.pi, n))
    return {
        "random pairs up to 89.9°": (a, b),
        "ω_i = ω_o": (a, a.copy()),
        "ω_i = n": (normal, b),
        "ω_i = ω_o = n": (normal, normal.copy()),
        "ω_o tangent (z = 0)": (b, tangent),
        "ω_i grazing 89.9°, ω_o mirror": (grazing, grazing * [-1, -1, 1]),
        "ω_i = −ω_o": (a, -a),
        "ω_o below the surface": (b, below),
        "uniform sphere pairs": (warps.square_to_uniform_sphere(rng.random((n, 2))),
                                 warps.square_to_uniform_sphere(rng.random((n, 2)))),
    }


def materials() -> dict[str, object]:
    """The material configurations exercised (extreme α, R0, and index ratios)."""
    out = {}
    for a in (1e-4, 1e-3, 0.5, 1.0):
        out[f"roughconductor α={a:g} R0=1"] = RoughConductor(1.0, a)
        out[f"roughconductor α={a:g} R0=0"] = RoughConductor(0.0, a)
        out[f"roughsubstrate α={a:g}"] = RoughSubstrate(0.5, a)
    out["roughsubstrate η=1.0001/1"] = RoughSubstrate(0.5, 0.1, 1.0001, 1.0)
    out["roughsubstrate η=1/1 (equal)"] = RoughSubstrate(0.5, 0.1, 1.0, 1.0)
    out["roughsubstrate η=10/1"] = RoughSubstrate(0.5, 0.1, 10.0, 1.0)
    out["roughsubstrate η=1/10 (inverted)"] = RoughSubstrate(0.5, 0.1, 1.0, 10.0)
    return out


def _count(x: np.ndarray) -> tuple[int, int, int]:
    return int(np.isnan(x).sum()), int(np.isinf(x).sum()), int((x < 0).sum())


def run(seed: int = 0) -> list[StabilityRow]:
    """Evaluate every material on every case; one row per (material, case)."""
    rng = np.random.default_rng(seed)
    cases = _cases(rng)
    rows = []
    for mname, bsdf in materials().items():
        for cname, (wi, wo) in cases.items():
            f = bsdf.eval(wi, wo)
            p = bsdf.pdf(wi, wo)
            s = bsdf.sample(wi, rng.random((len(wi), 3)))
            vals = np.concatenate([f.ravel(), p, s.weight.ravel(), s.pdf])
            nan, inf, neg = _count(vals)
            nan += int(np.isnan(s.wo).sum())
            rows.append(StabilityRow(mname, cname, len(vals), nan, inf, neg))
    return rows
