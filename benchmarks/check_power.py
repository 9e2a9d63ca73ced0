"""False-alarm rate and power of ``brdflab check`` on a Cornell box at 64 spp, over many seeds.

For each of N trials (independent seeds throughout): brdflab's estimate is the default check effort
(4 runs × 32 spp of direct_ems); the user renders are 64 spp by direct_ems (another seed) and by
direct_mis (another unbiased integrator). From the direct_ems render three biased images are made:
3 % too dark everywhere, the red wall alone 10 % too dark, and a bright patch (+15 % on a square of
1/8 the image height on the back wall). Reported: false alarms of the unbiased renders with their exact
(Clopper–Pearson) 95 % interval, the detection rate of each bias, the smallest detectable bias and the
cost per check.

Usage: python benchmarks/check_power.py [--trials 50] [--scale 0.25] [--scene PATH] [--json OUT]

The scene is the course's Cornell box (../shared/scenes/assignment-3/cbox/cbox_mats.xml) when present,
else the bundled scenes/cbox/cbox_diffuse.xml. ``--scale`` shrinks the camera resolution (the default
0.25 gives 200 × 150 for the course scene, so 50 trials take ~15 min on a shared 2-core machine);
per-block power does not depend on the image size, the image-mean test gains with more pixels.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np
from scipy import stats

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from brdflab.scene.loader import load_scene  # noqa: E402
from brdflab.stats.check import Estimate, check_images, run_check  # noqa: E402
from brdflab.stats.jobs import RenderJob, run_job, run_seed  # noqa: E402

COURSE = ROOT.parent / "shared" / "scenes" / "assignment-3" / "cbox" / "cbox_mats.xml"
BUNDLED = ROOT / "scenes" / "cbox" / "cbox_diffuse.xml"


def clopper_pearson(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """Exact binomial interval of a rate k/n."""
    a = 1 - level
    lo = 0.0 if k == 0 else stats.beta.ppf(a / 2, k, n - k + 1)
    hi = 1.0 if k == n else stats.beta.ppf(1 - a / 2, k + 1, n - k)
    return float(lo), float(hi)


def biased_variants(img: np.ndarray, est: np.ndarray) -> dict[str, np.ndarray]:
    """The three biased images made from an unbiased render."""
    h, w = img.shape[:2]
    wall = (est[..., 0] > 3 * est[..., 1]) & (est[..., 0] > 0.02)  # the red wall (R ≫ G)
    out = {"3% darker everywhere": 0.97 * img}
    x = img.copy()
    x[wall] *= 0.9
    out["red wall 10% darker"] = x
    x = img.copy()
    s = max(h // 8, 4)
    y0, x0 = int(0.45 * h) - s // 2, w // 2 - s // 2
    x[y0:y0 + s, x0:x0 + s] *= 1.15
    out["bright patch +15%"] = x
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--trials", type=int, default=50)
    ap.add_argument("--scale", type=float, default=0.25)
    ap.add_argument("--scene", type=Path)
    ap.add_argument("--spp", type=int, default=64, help="user renders' spp (default 64)")
    ap.add_argument("--workers", type=int)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    scene = args.scene or (COURSE if COURSE.exists() else BUNDLED)
    cam = load_scene(scene).camera
    res = (max(16, round(cam.width * args.scale)), max(16, round(cam.height * args.scale)))
    print(f"scene {scene}, {res[0]}×{res[1]}, user renders {args.spp} spp, brdflab 4 × 32 spp direct_ems, "
          f"{args.trials} trials", flush=True)
    unbiased = {"direct_ems, another seed": 0, "direct_mis": 0}
    detected: dict[str, int] = {}
    mdb, mdbb, secs = [], [], []
    for t in range(args.trials):
        user = {"direct_ems, another seed": run_job(RenderJob(scene, "direct_ems", args.spp, run_seed(t, 0, "report"),
                                                               res, args.workers))[0],
                "direct_mis": run_job(RenderJob(scene, "direct_mis", args.spp, run_seed(t, 1, "report"), res,
                                                args.workers))[0]}
        t0 = time.perf_counter()
        first = run_check([user["direct_ems, another seed"]], scene, "direct_ems", 32, 4, seed=1000 + t,
                          workers=args.workers, resolution=res, user_spp=args.spp)
        secs.append(time.perf_counter() - t0)
        est = first.estimate
        estimate = Estimate.from_runs(list(first.runs), run_spp=32)  # the same runs for every variant
        line = [f"trial {t:3d}:"]
        for name, img in user.items():
            r = first if name.startswith("direct_ems") else check_images([img], estimate, user_spp=args.spp)
            unbiased[name] += not r.consistent
            line.append(f"{name} {'ALARM' if not r.consistent else 'ok'} (p {r.p_value:.2g})")
        mdb.append(first.min_detectable_bias)
        mdbb.append(first.min_detectable_block_bias)
        for name, img in biased_variants(user["direct_ems, another seed"], est).items():
            r = check_images([img], estimate, user_spp=args.spp)
            detected[name] = detected.get(name, 0) + (not r.consistent)
            line.append(f"{name} {'flagged' if not r.consistent else 'MISSED'}")
        print("  ".join(line), flush=True)
    n = args.trials
    summary = {"scene": str(scene), "resolution": res, "trials": n, "user_spp": args.spp,
               "brdflab_runs": "4 × 32 spp direct_ems", "false_alarms": {}, "power": {},
               "median_check_seconds": statistics.median(secs),
               "median_min_detectable_bias": statistics.median(mdb),
               "median_min_detectable_block_bias": statistics.median(mdbb)}
    print("\nfalse alarms (unbiased renders, family-wise α = 1 %):")
    for name, k in unbiased.items():
        lo, hi = clopper_pearson(k, n)
        summary["false_alarms"][name] = {"count": k, "rate": k / n, "ci95": [lo, hi]}
        print(f"  {name:28s} {k}/{n} = {100 * k / n:.1f} %  (95 % CI {100 * lo:.1f} … {100 * hi:.1f} %)")
    k_all = sum(unbiased.values())
    lo, hi = clopper_pearson(k_all, 2 * n)
    summary["false_alarms"]["all"] = {"count": k_all, "rate": k_all / (2 * n), "ci95": [lo, hi]}
    print(f"  {'all':28s} {k_all}/{2 * n} = {100 * k_all / (2 * n):.1f} %  (95 % CI {100 * lo:.1f} … {100 * hi:.1f} %)")
    print("power (biased images flagged):")
    for name, k in detected.items():
        lo, hi = clopper_pearson(k, n)
        summary["power"][name] = {"count": k, "rate": k / n, "ci95": [lo, hi]}
        print(f"  {name:28s} {k}/{n} = {100 * k / n:.0f} %  (95 % CI {100 * lo:.0f} … {100 * hi:.0f} %)")
    print(f"smallest detectable bias (80 % power, median over trials): image mean "
          f"{100 * summary['median_min_detectable_bias']:.2f} %, one block "
          f"{100 * summary['median_min_detectable_block_bias']:.1f} %")
    print(f"median check time (4 × 32 spp + tests): {summary['median_check_seconds']:.1f} s at {res[0]}×{res[1]} "
          "(shared machine)")
    if args.json:
        args.json.write_text(json.dumps(summary, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
