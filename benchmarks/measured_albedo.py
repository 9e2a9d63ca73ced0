"""The directional albedo of a noisy measured table, as `brdflab plot` computes it: the adaptive (cos θ_o, φ_o) rule
that chased the noise against the fixed-order half-vector rule at the table's resolution (brdflab.viz.reflectance),
alternating in one process.

    python benchmarks/measured_albedo.py [--rounds 2] [--noise 0.05]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from brdflab.bsdf.measured import Measured, tabulate
from brdflab.bsdf.roughconductor import RoughConductor
from brdflab.viz import reflectance
from brdflab.viz.views import ALBEDO_THETAS


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--noise", type=float, default=0.05, help="multiplicative Gaussian noise of the table")
    a = ap.parse_args()
    rng = np.random.default_rng(1)
    t = tabulate(RoughConductor(0.9, 0.1))
    m = Measured(table=(t * (1 + a.noise * rng.standard_normal(t.shape))).clip(0))
    rules = {"adaptive": lambda th: reflectance._adaptive(m, th, False),
             "fixed": lambda th: reflectance.measured_albedo(m, th)}
    res: dict[str, list] = {k: [] for k in rules}
    for r in range(a.rounds):
        for name, fn in rules.items():
            t0 = time.perf_counter()
            vals = np.array([fn(th) for th in ALBEDO_THETAS])
            res[name].append((time.perf_counter() - t0, vals))
            print(f"round {r} {name:8s} {res[name][-1][0]:7.2f} s for {len(ALBEDO_THETAS)} angles; "
                  f"load {os.getloadavg()[0]:.1f}", flush=True)
    diff = np.abs(res["adaptive"][0][1] - res["fixed"][0][1]).max()
    print(f"max |adaptive - fixed| = {diff:.2e}; speed-up per round:",
          ", ".join(f"{x[0] / y[0]:.0f}x" for x, y in zip(res["adaptive"], res["fixed"], strict=True)))


if __name__ == "__main__":
    main()
