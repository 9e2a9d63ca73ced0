"""Consistency checks of a BSDF: sample weight = eval·cos/pdf, ∫ pdf ≤ 1, reciprocity, non-negativity.

* **Weight**: for N samples, |w − f cos θ_o / p| ≤ 10⁻⁵ · max(|f cos θ_o / p|, 10⁻³⁰) in float64.
* **Pdf mass**: ∫ p dω over the sphere by the adaptive quadrature of :mod:`brdflab.validate.chi2`;
  it must be ≤ 1 + 10⁻³ and equal the fraction of non-failed samples within Monte Carlo error.
* **Reciprocity**: f(ω_i, ω_o) = f(ω_o, ω_i) for random pairs (relative 10⁻⁹).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from brdflab.math import warps
from brdflab.validate.chi2 import incident, integrate_bins, theta_edges_from_pilot, to_angles


@dataclass
class ConsistencyResult:
    """Outcome of the consistency checks for one BSDF and incident angle."""

    name: str
    theta: float
    max_weight_error: float
    pdf_integral: float
    valid_fraction: float
    max_reciprocity_error: float
    negative_or_nonfinite: int

    @property
    def passed(self) -> bool:
        """All checks within tolerance."""
        se = np.sqrt(max(self.valid_fraction * (1 - self.valid_fraction), 1e-12) / 200_000)
        return (self.max_weight_error <= 1e-5 and self.pdf_integral <= 1 + 1e-3
                and abs(self.pdf_integral - self.valid_fraction) <= max(5 * se, 2e-3)
                and self.max_reciprocity_error <= 1e-9 and self.negative_or_nonfinite == 0)


def check_bsdf(name: str, bsdf, theta_deg: float, n: int = 200_000, seed: int = 0) -> ConsistencyResult:
    """Run the consistency checks for ``bsdf`` at incident angle ``theta_deg``."""
    rng = np.random.default_rng(seed)
    wi1 = incident(theta_deg)
    wi = np.ascontiguousarray(np.broadcast_to(wi1, (n, 3)))
    s = bsdf.sample(wi, rng.random((n, 3)))
    f = bsdf.eval(wi, s.wo)
    ok = s.pdf > 0
    expect = np.zeros_like(s.weight)
    expect[ok] = f[ok] * (np.maximum(s.wo[ok, 2], 0.0) / s.pdf[ok])[:, None]
    err = np.abs(s.weight - expect) / np.maximum(np.abs(expect), 1e-30)
    err[(np.abs(s.weight - expect) == 0)] = 0.0
    bad = int((~np.isfinite(s.weight)).sum() + (s.weight < 0).sum() + (~np.isfinite(s.pdf)).sum() + (s.pdf < 0).sum())

    axis = np.array([-wi1[0], -wi1[1], wi1[2]])
    th, _ = to_angles(s.wo[ok][:50_000], axis)
    edges = theta_edges_from_pilot(th, 20)
    integral = float(integrate_bins(lambda w: bsdf.pdf(np.ascontiguousarray(np.broadcast_to(wi1, (len(w), 3))), w),
                                    axis, edges, 40, n).sum())

    a = warps.square_to_uniform_sphere(rng.random((20_000, 2)))
    b = warps.square_to_uniform_sphere(rng.random((20_000, 2)))
    fab, fba = bsdf.eval(a, b), bsdf.eval(b, a)
    rec = np.abs(fab - fba) / np.maximum(np.maximum(np.abs(fab), np.abs(fba)), 1e-300)
    rec[(fab == fba)] = 0.0
    bad += int((~np.isfinite(fab)).sum() + (fab < 0).sum())
    return ConsistencyResult(name, theta_deg, float(err.max()), integral, float(ok.mean()), float(rec.max()), bad)
