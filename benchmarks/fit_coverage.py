"""Coverage of ``fit``'s standard errors (issue 45): synthetic data from a known anisotropic GGX conductor with
the η/k of gold, 5 % log-normal noise (an independent stream per trial), fitted with ``free =
alpha_u,alpha_v,eta,k``; counts how often each fitted value lies within 1.96 reported standard errors of the
truth (95 % if the errors are right) and prints the η–k correlations.

    python benchmarks/fit_coverage.py [--trials 40] [--stride 6,8,15] [--sigma 0.05]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import brdflab as bl
from brdflab.fitting_data import noisy

TRUTH = dict(distribution="ggx", alpha_u=0.15, alpha_v=0.3, material="Au")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=40)
    ap.add_argument("--stride", default="6,8,15")
    ap.add_argument("--sigma", type=float, default=0.05)
    a = ap.parse_args()
    stride = tuple(int(x) for x in a.stride.split(","))
    gold = bl.RoughConductor(**TRUTH)
    truth = {"alpha_u": gold.alpha_u, "alpha_v": gold.alpha_v, "eta": gold.eta, "k": gold.k}
    zs, rhos, t0 = [], [], time.time()
    for trial in range(a.trials):
        res = bl.fit(noisy(gold, a.sigma, seed=1000 + trial), fixed={"distribution": "ggx"},
                     free="alpha_u,alpha_v,eta,k", stride=stride)
        zs.append(np.concatenate([np.ravel((np.asarray(res.params[k]) - v) / np.asarray(res.uncertainty[k]))
                                  for k, v in truth.items()]))
        m, lab = np.asarray(res.correlation["matrix"]), res.correlation["labels"]
        rhos.append([m[lab.index(f"eta[{c}]"), lab.index(f"k[{c}]")] for c in "rgb"])
    z = np.abs(np.array(zs))
    names = ["alpha_u", "alpha_v", *(f"{p}[{c}]" for p in ("eta", "k") for c in "rgb")]
    print(f"{a.trials} trials, stride {stride}, σ = {a.sigma}: {time.time() - t0:.0f} s")
    for j, n in enumerate(names):
        print(f"  {n:8s} within 1.96 SE: {np.mean(z[:, j] < 1.96):.3f}   rms z = {np.sqrt(np.mean(z[:, j] ** 2)):.2f}")
    print(f"  all values within 1.96 SE: {np.mean(z < 1.96):.3f} (expected 0.95)")
    print(f"  ρ(η, k) per channel (mean): {np.round(np.mean(rhos, axis=0), 3).tolist()}")


if __name__ == "__main__":
    main()
