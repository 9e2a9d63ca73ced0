"""False-alarm rate of the chi-square test (and of the furnace agreement check) on correct samplers.

Runs each configuration with many independent seeds and reports the fraction rejected at the nominal
per-test level (default 0.01) with its binomial 95 % interval, and a Kolmogorov–Smirnov test of the p-values
against uniformity (a well-calibrated test gives uniform p-values). Configurations cover the lobe shapes the
binning must handle: a diffuse lobe, a Beckmann lobe near grazing, a very sharp lobe (α = 10⁻³), the
two-lobe substrate and the example Phong plugin (sharp, θ-only).

    python benchmarks/chi2_false_alarms.py --seeds 200 --samples 20000

Timings on a shared machine are not the point here; only rates are reported.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import time
from pathlib import Path

import numpy as np
from scipy import stats

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from brdflab.bsdf.diffuse import Diffuse  # noqa: E402
from brdflab.bsdf.roughconductor import RoughConductor  # noqa: E402
from brdflab.bsdf.roughsubstrate import RoughSubstrate  # noqa: E402
from brdflab.judges.material import chi2 as c2  # noqa: E402
from brdflab.judges.material import furnace  # noqa: E402


def _phong():
    spec = importlib.util.spec_from_file_location("example_phong", ROOT / "examples" / "phong.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.Phong


def configurations():
    """(label, BSDF, θ_i)."""
    phong = _phong()
    return [
        ("diffuse θ=30", Diffuse(0.5), 30.0),
        ("roughconductor α=0.3 θ=80", RoughConductor(0.5, 0.3), 80.0),
        ("roughconductor α=1e-3 θ=60", RoughConductor(0.5, 1e-3), 60.0),
        ("roughsubstrate α=0.05 θ=45", RoughSubstrate(0.5, 0.05), 45.0),
        ("phong n=100 θ=40 (plugin)", phong(exponent=100.0), 40.0),
    ]


def interval(k: int, n: int) -> tuple[float, float]:
    """Clopper–Pearson 95 % interval of a binomial proportion."""
    lo = stats.beta.ppf(0.025, k, n - k + 1) if k > 0 else 0.0
    hi = stats.beta.ppf(0.975, k + 1, n - k) if k < n else 1.0
    return float(lo), float(hi)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=200)
    ap.add_argument("--samples", type=int, default=20_000)
    ap.add_argument("--level", type=float, default=0.01)
    ap.add_argument("--furnace", action="store_true", help="also the furnace agreement check (4σ + 5e-4)")
    args = ap.parse_args()
    total_k = total_n = 0
    print(f"chi-square false alarms: {args.seeds} seeds × {args.samples} samples, nominal level {args.level}")
    for label, bsdf, theta in configurations():
        t0 = time.perf_counter()
        p = np.array([c2.bsdf_test(label, bsdf, theta, args.samples, seed=10_000 + s, threshold=args.level).p_value
                      for s in range(args.seeds)])
        k = int((p <= args.level).sum())
        total_k, total_n = total_k + k, total_n + len(p)
        lo, hi = interval(k, len(p))
        ks = stats.kstest(p, "uniform").pvalue
        print(f"  {label:32s} rejected {k:3d}/{len(p)} = {k / len(p):.3f} (95 % CI {lo:.3f}–{hi:.3f}); "
              f"rejected at 0.05: {(p <= 0.05).mean():.3f}; KS uniformity p = {ks:.2f} "
              f"[{time.perf_counter() - t0:.0f} s]")
    lo, hi = interval(total_k, total_n)
    print(f"  all: {total_k}/{total_n} = {total_k / total_n:.4f} (95 % CI {lo:.4f}–{hi:.4f}) vs nominal {args.level}")
    if args.furnace:
        print("furnace agreement false alarms (quadrature vs Monte Carlo within 4σ + 5e-4):")
        for label, bsdf, theta in configurations():
            bad = sum(not furnace.furnace_point(bsdf, theta=theta, samples=args.samples, seed=20_000 + s).agree
                      for s in range(args.seeds))
            print(f"  {label:32s} disagreements {bad}/{args.seeds}")


if __name__ == "__main__":
    main()
