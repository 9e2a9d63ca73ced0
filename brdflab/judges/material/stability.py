"""Stiff and extreme cases: eval, pdf and sample must give no NaN, no infinity and no negative value.

Cases: α ∈ {10⁻⁴, 10⁻³, 0.5, 1}; θ up to 89.9°; ω_i = ω_o; ω_i = n; ω_o tangent (z = 0); random pairs;
index ratios near 1 (1.0001) and large (10); R0 ∈ {0, 1}. Everything is computed in float64; the
formulas that needed care are noted in :data:`NOTES` and shown in the report.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from brdflab.bsdf.roughconductor import RoughConductor
from brdflab.bsdf.roughsubstrate import RoughSubstrate
from brdflab.judges.core.results import CaseList
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
    fault: str | None = None

    @property
    def passed(self) -> bool:
        """No NaN, no infinity, no negative value, and the BSDF neither raised nor returned wrong shapes."""
        return self.fault is None and self.nan == 0 and self.inf == 0 and self.negative == 0

    @property
    def message(self) -> str:
        """One-line verdict."""
        what = self.fault or f"{self.nan} NaN, {self.inf} inf, {self.negative} negative of {self.n} values"
        return f"{'PASS' if self.passed else 'FAIL'} stability {self.material} / {self.case}: {what}"


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
        out[f"roughconductor ggx α={a:g} η,k"] = RoughConductor(distribution="ggx", alpha=a, material="Au")
        out[f"roughconductor beckmann visible α_u={a:g} α_v=0.3"] = RoughConductor(
            1.0, distribution="beckmann", sample_visible=True, alpha_u=a, alpha_v=0.3)
        out[f"roughconductor ggx α_u=0.3 α_v={a:g} (normals ∝ D cos)"] = RoughConductor(
            1.0, distribution="ggx", sample_visible=False, alpha_u=0.3, alpha_v=a)
    out["roughsubstrate η=1.0001/1"] = RoughSubstrate(0.5, 0.1, 1.0001, 1.0)
    out["roughsubstrate η=1/1 (equal)"] = RoughSubstrate(0.5, 0.1, 1.0, 1.0)
    out["roughsubstrate η=10/1"] = RoughSubstrate(0.5, 0.1, 10.0, 1.0)
    out["roughsubstrate η=1/10 (inverted)"] = RoughSubstrate(0.5, 0.1, 1.0, 10.0)
    _transmissive(out)
    return out


def _transmissive(out: dict[str, object]) -> None:
    """The delta and transmissive materials (issue 44) at extreme α and index ratios."""
    from brdflab.bsdf.dielectric import Dielectric
    from brdflab.bsdf.mirror import Mirror
    from brdflab.bsdf.roughdielectric import RoughDielectric

    out["mirror"] = Mirror()
    for a in (1e-4, 1e-3, 0.5, 1.0):
        out[f"roughdielectric α={a:g}"] = RoughDielectric(a)
    for label, (i, e) in {"η=1.0001/1": (1.0001, 1.0), "η=1/1 (equal)": (1.0, 1.0), "η=10/1": (10.0, 1.0),
                          "η=1/10 (inverted)": (1.0, 10.0)}.items():
        out[f"dielectric {label}"] = Dielectric(i, e)
        out[f"roughdielectric {label}"] = RoughDielectric(0.1, i, e)


def _count(x: np.ndarray) -> tuple[int, int, int]:
    return int(np.isnan(x).sum()), int(np.isinf(x).sum()), int((x < 0).sum())


def _row(mname: str, cname: str, bsdf, wi: np.ndarray, wo: np.ndarray, u: np.ndarray) -> StabilityRow:
    """Evaluate one case; exceptions and wrong shapes become a failed row naming the method."""
    from brdflab.judges.core.guard import CheckedBSDF, PluginFault

    n = len(wi)
    shapes = {"eval": (n, 3), "pdf": (n,), "sample.wo": (n, 3), "sample.weight": (n, 3), "sample.pdf": (n,)}
    proxy = CheckedBSDF(bsdf, mname)
    try:
        f = proxy._call("eval", wi, wo, None)
        p = proxy._call("pdf", wi, wo, None)
        s = proxy._call("sample", wi, u, None)
        swo, sw, sp = s[:3] if isinstance(s, tuple) and len(s) == 4 else s  # delta (4th field) may be None
        out = {"eval": f, "pdf": p, "sample.wo": swo, "sample.weight": sw, "sample.pdf": sp}
        out = {k: np.asarray(v, dtype=np.float64) for k, v in out.items()}
    except PluginFault as fault:
        return StabilityRow(mname, cname, 0, 0, 0, 0, fault=str(fault))
    except (TypeError, ValueError) as exc:
        return StabilityRow(mname, cname, 0, 0, 0, 0, fault=f"{mname}.sample returned {exc}")
    for k, v in out.items():
        if v.shape != shapes[k]:
            what = f"{mname}.{k} has shape {v.shape}, expected {shapes[k]}"
            return StabilityRow(mname, cname, 0, 0, 0, 0, fault=what)
    vals = np.concatenate([out["eval"].ravel(), out["pdf"], out["sample.weight"].ravel(), out["sample.pdf"]])
    nan, inf, neg = _count(vals)
    nan += int(np.isnan(out["sample.wo"]).sum())
    return StabilityRow(mname, cname, len(vals), nan, inf, neg)


def run(seed: int = 0, bsdfs: dict[str, object] | None = None) -> list[StabilityRow]:
    """Evaluate every material (default: :func:`materials`) on every case; one row per (material, case)."""
    rng = np.random.default_rng(seed)
    cases = _cases(rng)
    rows = []
    for mname, bsdf in (materials() if bsdfs is None else bsdfs).items():
        for cname, (wi, wo) in cases.items():
            rows.append(_row(mname, cname, bsdf, wi, wo, rng.random((len(wi), 3))))
    return rows


@dataclass
class StabilityResult(CaseList):
    """Stability rows of one BSDF (or of the built-ins), iterable over its :class:`StabilityRow`s."""

    name: str
    seed: int | None
    cases_attr: ClassVar[str] = "rows"
    rows: list[StabilityRow]


    @property
    def message(self) -> str:
        """A summary line, then the failed cases."""
        bad = [r for r in self.rows if not r.passed]
        head = (f"{'PASS' if not bad else 'FAIL'} stability {self.name}: {len(self.rows)} extreme cases, "
                f"{len(bad)} failed")
        return "\n".join([head, *(r.message for r in bad)])



def stability_test(bsdf=None, name: str | None = None, seed: int | None = None) -> StabilityResult:
    """Extreme and degenerate directions: no NaN, infinity, negative value, exception or wrong shape.

    Parameters
    ----------
    bsdf
        Any :class:`brdflab.BSDF`; None: the built-in materials at extreme parameters (:func:`materials`).
    name
        For messages (default: its type name).
    seed
        Default: derived from the BSDF's type (0 for the built-ins).

    Returns
    -------
    StabilityResult
        Iterable over one :class:`StabilityRow` per (material, case); ``passed`` when all pass.

    Examples
    --------
    >>> import brdflab as bl
    >>> res = bl.stability_test(bl.Diffuse(albedo=0.5))
    >>> len(res), res.passed
    (9, True)
    """
    from brdflab.judges.core.guard import describe
    from brdflab.judges.core.seeding import bsdf_identity, test_seed

    if bsdf is None:
        return StabilityResult("built-in materials", seed or 0, run(seed or 0))
    name = name or describe(bsdf)
    if seed is None:
        seed = test_seed("stability", bsdf_identity(bsdf), name)
    return StabilityResult(name, seed, run(seed % 2**32, {name: bsdf}))
