"""False alarms of ``brdflab report``'s bias verdict, measured at small numbers of runs (issue 40).

For each scene, ``--pool`` independent runs of each unbiased integrator are rendered once (progressively: every
checkpoint of ``--spp``), each measured against a self-made reference (brdflab's ``direct_mis``, independent seeds,
as ``report`` makes it). Then, for K in ``--k``, the pool is cut into disjoint groups of K runs and each group gives
the report's test at every spp, as the report computes it (:func:`brdflab.pages.variance.aggregate` on a study of
those K runs). Every integrator is unbiased, so every rejection at the per-test level α is a false alarm; the
rate comes with its exact (Clopper–Pearson) 95 % interval. The old rule (the spread of the K run biases with
Welch–Satterthwaite df) is computed beside it on the same runs.

The "faster" verdict (a speed-up stated when its 95 % interval excludes 1) is measured the same way: two disjoint
groups of K runs of the *same* integrator (consecutive runs dealt alternately, as the report interleaves its
integrators' runs) are compared as if they were two estimators; any stated speed-up is a false one (nominal rate
5 %, two-sided).

    python benchmarks/bias_false_alarms.py ../shared/scenes/assignment-3/cbox/cbox_conductors_ems.xml \\
        --resolution 200x150 --pool 48 --k 2,3,4,8
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np
from scipy import stats

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from brdflab.pages import variance as V  # noqa: E402
from brdflab.stats.intervals import log_ratio_interval, welch_df  # noqa: E402
from brdflab.stats.jobs import RenderJob, run_seed  # noqa: E402


def pool_runs(scene: Path, integrators: list[str], spp: list[int], pool: int, resolution, seed: int):
    ref, _, ref_var, secs = V.make_reference(scene, 4 * max(spp), V.REF_RUNS, seed, resolution, 1)
    runs = {name: [] for name in integrators}
    for k in range(pool):  # run-major, as the report orders its jobs: a load drift slows every integrator alike
        for i, name in enumerate(integrators):
            job = RenderJob(scene, name, max(spp), run_seed(seed + 1, 10000 * i + k, "report"), resolution, 1)
            runs[name].append(V.measure_run(job, ref, tuple(spp), k).checkpoints)
    return runs, ref_var


def p_values(cps_group, spp: int, ref_var: float) -> tuple[float, float]:
    """(new rule, old rule) two-sided p-values of one group of runs at one spp."""
    cs = [next(c for c in cps if c.spp == spp) for cps in cps_group]
    k = len(cs)
    b = np.array([c.bias for c in cs])
    within = np.array([c.bias_var for c in cs])
    var_new = within.sum() / k**2 + (1 - 1 / k) * ref_var
    p_new = float(2 * stats.norm.sf(abs(b.mean()) / math.sqrt(var_new)))
    vb = b.var(ddof=1) / k
    var_old = vb + ref_var
    df = float(welch_df([vb, ref_var], [k - 1, np.inf]))
    t = b.mean() / math.sqrt(var_old)
    p_old = float(2 * (stats.t.sf(abs(t), df) if np.isfinite(df) else stats.norm.sf(abs(t))))
    return p_new, p_old


def clopper_pearson(x: int, n: int, level: float = 0.95) -> tuple[float, float]:
    a = (1 - level) / 2
    lo = stats.beta.ppf(a, x, n - x + 1) if x > 0 else 0.0
    hi = stats.beta.ppf(1 - a, x + 1, n - x) if x < n else 1.0
    return float(lo), float(hi)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenes", nargs="+", type=Path)
    ap.add_argument("--integrators", default="direct_ems,direct_mats,direct_mis")
    ap.add_argument("--spp", default="1,4,16")
    ap.add_argument("--pool", type=int, default=48)
    ap.add_argument("--k", default="2,3,4,8")
    ap.add_argument("--alpha", type=float, default=0.01)
    ap.add_argument("--resolution", default="200x150")
    ap.add_argument("--seed", type=int, default=7)
    a = ap.parse_args()
    spp = [int(s) for s in a.spp.split(",")]
    ks = [int(s) for s in a.k.split(",")]
    w, h = (int(v) for v in a.resolution.split("x"))
    print(f"false alarms of the report's bias test at α = {a.alpha} per test (every integrator is unbiased)")
    for scene in a.scenes:
        t0 = time.perf_counter()
        runs, ref_var = pool_runs(scene, a.integrators.split(","), spp, a.pool, (w, h), a.seed)
        print(f"\n{scene.name} at {w}×{h}, {a.pool} runs per integrator ({time.perf_counter() - t0:.0f} s)")
        for k in ks:
            new = old = n = 0
            for cps in runs.values():
                for g in range(len(cps) // k):
                    for s in spp:
                        pn, po = p_values(cps[g * k:(g + 1) * k], s, ref_var)
                        new += pn < a.alpha
                        old += po < a.alpha
                        n += 1
            lo, hi = clopper_pearson(new, n)
            olo, ohi = clopper_pearson(old, n)
            print(f"  K = {k}: {n} tests; within-run rule {new} alarms = {100 * new / n:.1f} % "
                  f"(95 % CI {100 * lo:.1f}–{100 * hi:.1f} %); old spread rule {old} = {100 * old / n:.1f} % "
                  f"({100 * olo:.1f}–{100 * ohi:.1f} %)")
            fast = m = 0
            for cps in runs.values():
                for g in range(len(cps) // (2 * k)):
                    block = cps[2 * g * k:(2 * g + 2) * k]  # consecutive runs, dealt alternately (as interleaved)
                    a_runs, b_runs = block[0::2], block[1::2]
                    for s in spp:
                        prod = [[c.relmse * c.seconds for c in (next(c for c in r if c.spp == s) for r in grp)]
                                for grp in (a_runs, b_runs)]
                        _, low, high = log_ratio_interval(prod[1], prod[0], 0.95)
                        fast += bool(np.isfinite(low) and (low > 1 or high < 1))
                        m += 1
            if m:
                flo, fhi = clopper_pearson(fast, m)
                print(f"         'faster' between two groups of one integrator: {fast} of {m} = {100 * fast / m:.1f} % "
                      f"(95 % CI {100 * flo:.1f}–{100 * fhi:.1f} %; nominal 5 %)")


if __name__ == "__main__":
    main()
