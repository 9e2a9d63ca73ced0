"""False alarms of ``brdflab chi2 --samples FILE --against roughconductor`` at its smallest settings (issue 40).

Correct sample files of two methods — brdflab's own sampler and an independent visible-normal sampler
(``tests/vndf_sampler.py``) — with few samples per ω_i group (``--n``, the command's minimum is 50) at random α
and θ_i, written as float32 text (as a Nori build writes them: the pdf and weights computed in float32 and
printed with 9 digits), are judged one file at a time; every failure is a false alarm. Reported with its exact
(Clopper–Pearson) 95 % interval; the nominal level of one file (one group) is 1 %.

    python benchmarks/samples_false_alarms.py --files 200 --n 50 100 1000
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy import stats

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from brdflab.bsdf.roughconductor import RoughConductor  # noqa: E402
from brdflab.judges.samples.bsdf_checks import check_samples  # noqa: E402
from tests.vndf_sampler import sample_vndf  # noqa: E402


def one_file(path: Path, rng: np.random.Generator, n: int, method: str) -> tuple[float, float]:
    alpha = float(np.exp(rng.uniform(np.log(0.05), np.log(1.0))))
    theta = float(rng.uniform(0.0, 80.0))
    b = RoughConductor(R0=0.9, alpha=alpha)
    wi1 = np.array([np.sin(np.radians(theta)), 0.0, np.cos(np.radians(theta))])
    wi = np.tile(wi1, (n, 1))
    if method == "brdflab":
        s = b.sample(wi, rng.random((n, 3)))
        wo, pdf = s.wo, s.pdf
    else:
        wo, pdf, _ = sample_vndf(wi1, alpha, rng.random((n, 2)))
    f = b.eval(wi, wo)
    with np.errstate(divide="ignore", invalid="ignore"):
        w = np.where((pdf > 0)[:, None], f * (np.maximum(wo[:, 2], 0) / np.where(pdf > 0, pdf, 1))[:, None], 0.0)
    cols = np.column_stack([wi, wo, pdf, w]).astype(np.float32)  # a float32 pipeline
    np.savetxt(path, cols, fmt="%.9g")
    return alpha, theta


def clopper_pearson(x: int, n: int) -> tuple[float, float]:
    lo = stats.beta.ppf(0.025, x, n - x + 1) if x else 0.0
    hi = stats.beta.ppf(0.975, x + 1, n - x) if x < n else 1.0
    return float(lo), float(hi)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--files", type=int, default=200)
    ap.add_argument("--n", type=int, nargs="+", default=[50, 1000])
    ap.add_argument("--seed", type=int, default=3)
    a = ap.parse_args()
    tmp = Path(tempfile.mkdtemp())
    for n in a.n:
        for method in ("brdflab", "visible normals"):
            rng = np.random.default_rng([a.seed, n, len(method)])
            alarms, worst = 0, []
            for _ in range(a.files):
                alpha, theta = one_file(tmp / "s.txt", rng, n, method)
                res = check_samples(tmp / "s.txt", "roughconductor", alpha=alpha, params={"R0": 0.9})
                if not res.passed:
                    alarms += 1
                    worst.append(f"α {alpha:.3g} θ {theta:.0f}°: {res.messages()[1][:100]}")
            lo, hi = clopper_pearson(alarms, a.files)
            print(f"n = {n:5d} per file, {method:15s}: {alarms}/{a.files} false alarms = "
                  f"{100 * alarms / a.files:.1f} % (95 % CI {100 * lo:.1f}–{100 * hi:.1f} %)", flush=True)
            for w in worst[:3]:
                print("    " + w)


if __name__ == "__main__":
    main()
