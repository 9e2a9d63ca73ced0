"""Calibration of ``check``'s direct/indirect fit d ≈ a·D + b·I on unbiased path-traced renders, from the fit's
inputs that ``benchmarks/check_power.py --where --cache DIR`` keeps (``DIR/where_<scene>_<trial>_<W>x<H>.npz``).

Every definite statement (:func:`brdflab.stats.findings.depth_finding`: ``direct``, ``indirect``, ``mixed``,
``all``) of such a render is false. Reported: their rate with its exact (Clopper–Pearson) 95 % interval; the
p-values of a and b (uniform under the null: Kolmogorov–Smirnov, and the fractions below 1 %, 5 %, 10 %); and the
rule's *nominal* rate on the same designs: each trial's own cells refitted with the observations replaced by
its residuals under a = b = 0 (i.e. d itself) times random signs (Rademacher; ``--flips`` per trial). Sign flips
keep every cell's variance and tails but make the cells exactly independent and symmetric, the assumptions of
the fit's t-tests: the measured rate above that is what the real cells add (correlation, skew), at that rate
it is the rule's own.

Usage: python benchmarks/depth_fit_null.py DIR [--flips 20] [--t-test]  (``--t-test``: HC3 and Student's t, the
p-values before the wild bootstrap, :mod:`brdflab.stats.wild_bootstrap`)
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

import numpy as np
from scipy import stats

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from check_power import clopper_pearson  # noqa: E402

from brdflab.stats import attribution as A  # noqa: E402


def trial_fit(z, wild: int = A.WILD_DRAWS) -> tuple[A.Fit | None, str | None, int]:
    """The whole-image fit and statement of one cached trial, as ``check_power.where_statement`` makes them
    (``wild`` 0: the p-values of HC3 and Student's t instead of the wild bootstrap)."""
    d = z["d"]
    sign = -1 if d.mean() < 0 else 1
    fit = A.fit_cells(d, [z["direct"], z["indirect"]], ["D", "I"], z["material"] >= 0, A.CELL, wild=wild)
    return fit, A.depth_finding(fit, sign)[1], sign


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("cache", type=Path)
    ap.add_argument("--flips", type=int, default=20)
    ap.add_argument("--t-test", action="store_true", help="HC3 t-test p-values instead of the wild bootstrap's")
    args = ap.parse_args()
    files = sorted(args.cache.glob("where_*.npz"), key=lambda p: int(re.findall(r"_(\d+)_\d+x\d+", p.name)[0]))
    if not files:
        print(f"no where_*.npz in {args.cache}: run check_power.py --where --cache {args.cache}")
        return 2
    rng = np.random.default_rng(20261204)
    pvals, kinds, nominal = [], [], []
    for f in files:
        z = dict(np.load(f))
        wild = 0 if args.t_test else A.WILD_DRAWS
        fit, kind, sign = trial_fit(z, wild)
        if fit is None:
            continue
        pvals.append(fit.p)
        kinds.append(kind)
        lit = z["material"] >= 0
        for _ in range(args.flips):  # the same design, d's cells with random signs (pixels of a cell share one)
            cells = rng.choice([-1.0, 1.0], size=((lit.shape[0] + A.CELL - 1) // A.CELL,
                                                   (lit.shape[1] + A.CELL - 1) // A.CELL))
            flip = np.kron(cells, np.ones((A.CELL, A.CELL)))[: lit.shape[0], : lit.shape[1]]
            z2 = dict(z, d=z["d"] * flip)
            nominal.append(trial_fit(z2, wild)[1] is not None)
    p, n = np.array(pvals), len(kinds)
    k = sum(x is not None for x in kinds)
    lo, hi = clopper_pearson(k, n)
    print(f"{n} unbiased renders ({files[0].name.split('_')[1]}): definite statements {k}/{n} = {100 * k / n:.1f} % "
          f"(95 % CI {100 * lo:.1f} … {100 * hi:.1f} %); kinds {dict((str(x), kinds.count(x)) for x in set(kinds))}")
    m = int(np.sum(nominal))
    lo, hi = clopper_pearson(m, len(nominal))
    print(f"the rule on the same designs with sign-flipped cells (its nominal rate): {m}/{len(nominal)} = "
          f"{100 * m / len(nominal):.2f} % (95 % CI {100 * lo:.2f} … {100 * hi:.2f} %)")
    print(f"binomial test of the measured count against that rate: p = "
          f"{stats.binomtest(k, n, m / len(nominal), alternative='greater').pvalue:.3g}")
    for j, name in enumerate(("a (D)", "b (I)")):
        q = p[:, j]
        print(f"p-values of {name}: KS p = {stats.kstest(q, 'uniform').pvalue:.3f}; below 1 % {np.mean(q < .01):.3f}, "
              f"5 % {np.mean(q < .05):.3f}, 10 % {np.mean(q < .1):.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
