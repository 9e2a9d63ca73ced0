"""Scaling of brdflab: render speed and load time against triangle count, and speed-up of 2 workers over 1.

Usage (brdflab's environment active)::

    python benchmarks/scaling.py [--spp 16] [--runs 3]

* Triangles: displaced spheres of about 10 k, 30 k, 100 k, 300 k and 1 M triangles under a point light
  (800×600, ``direct_ems``), each loaded (OBJ parse + BVH build) and rendered in a fresh process.
* Workers: every bench case of ``brdflab bench`` with 1 and with 2 workers (forked processes).

Each measurement is the median of ``--runs`` renders. Writes ``docs/scaling.png`` (two panels) and
``benchmarks/results/scaling.json`` and prints Markdown tables for the README.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from brdflab.benchmarking import CASES, COURSE_CASES, mesh1m_scene, mesh_scene  # noqa: E402

#: (n_theta, n_phi) of the tessellated spheres: about 2·n_theta·n_phi triangles.
SIZES = [(50, 100), (87, 174), (158, 316), (274, 548), (500, 1004)]


def measure(scene: Path, integrator: str, spp: int, runs: int, workers: int, case: str) -> dict:
    """Run ``brdflab.benchmarking --one`` in a fresh process; return its record with medians."""
    cmd = [sys.executable, "-m", "brdflab.benchmarking", "--one", str(scene), integrator, str(spp), str(runs),
           str(workers), case]
    out = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, check=True)
    rec = json.loads(out.stdout.strip().splitlines()[-1])
    rec["median_samples_per_s"] = statistics.median(r["samples_per_s"] for r in rec["runs"])
    rec["median_embree_share"] = statistics.median(r["embree_share"] for r in rec["runs"])
    return rec


def main(argv: list[str] | None = None) -> int:
    """Measure, plot and print."""
    ap = argparse.ArgumentParser(description="brdflab scaling with triangles and workers")
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "scaling.png")
    a = ap.parse_args(argv)
    cache = ROOT / ".bench-cache"
    tri_rows = []
    for nt, npf in SIZES:
        scene = mesh1m_scene(cache) if (nt, npf) == SIZES[-1] else mesh_scene(cache, nt, npf, f"mesh_{nt}x{npf}")
        rec = measure(scene, "direct_ems", a.spp, a.runs, 0, scene.stem)
        tri_rows.append({"triangles": rec["triangles"], "load_seconds": rec["load_seconds"],
                         "samples_per_s": rec["median_samples_per_s"], "embree_share": rec["median_embree_share"],
                         "peak_rss_bytes": rec["peak_rss_bytes"], "bytes_per_triangle": rec["bytes_per_triangle"]})
        print(f"{rec['triangles']:>9,} triangles  load+BVH {rec['load_seconds']:5.2f} s  "
              f"{rec['median_samples_per_s'] / 1e6:5.2f} M samples/s  Embree {100 * rec['median_embree_share']:3.0f}%",
              flush=True)
    worker_rows = []
    for case, (rel, integrators) in CASES.items():
        if rel == "<generated>" or case in COURSE_CASES:
            continue
        for integ in integrators:
            one = measure(ROOT / rel, integ, a.spp, a.runs, 1, case)["median_samples_per_s"]
            two = measure(ROOT / rel, integ, a.spp, a.runs, 2, case)["median_samples_per_s"]
            worker_rows.append({"case": case, "integrator": integ, "one": one, "two": two, "speedup": two / one})
            print(f"{case:13s} {integ:12s} 1 worker {one / 1e6:5.2f} M/s  2 workers {two / 1e6:5.2f} M/s  "
                  f"×{two / one:.2f}", flush=True)
    _plot(tri_rows, worker_rows, a.out, a.spp)
    doc = {"date": time.strftime("%Y-%m-%d %H:%M"), "spp": a.spp, "runs": a.runs, "triangles": tri_rows,
           "workers": worker_rows}
    res = ROOT / "benchmarks" / "results" / "scaling.json"
    res.parent.mkdir(parents=True, exist_ok=True)
    res.write_text(json.dumps(doc, indent=2))
    print("\n| triangles | load + BVH | samples/s (2 workers) | Embree share | bytes/triangle |")
    print("|---|---|---|---|---|")
    for r in tri_rows:
        print(f"| {r['triangles']:,} | {r['load_seconds']:.2f} s | {r['samples_per_s'] / 1e6:.2f} M | "
              f"{100 * r['embree_share']:.0f} % | {r['bytes_per_triangle']:.0f} |")
    print("\n| case | integrator | 1 worker | 2 workers | speed-up |")
    print("|---|---|---|---|---|")
    for r in worker_rows:
        print(f"| {r['case']} | {r['integrator']} | {r['one'] / 1e6:.2f} M | {r['two'] / 1e6:.2f} M | "
              f"{r['speedup']:.2f}× |")
    print(f"\nwrote {a.out} and {res}")
    return 0


def _plot(tri_rows: list[dict], worker_rows: list[dict], out: Path, spp: int) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4))
    tris = [r["triangles"] for r in tri_rows]
    ax1.plot(tris, [r["samples_per_s"] / 1e6 for r in tri_rows], "o-", label="render, M samples/s")
    ax1.set_xscale("log")
    ax1.set_xlabel("triangles")
    ax1.set_ylabel("M samples/s (direct_ems, 2 workers)")
    ax1.set_ylim(bottom=0)
    axt = ax1.twinx()
    axt.plot(tris, [r["load_seconds"] for r in tri_rows], "s--", color="tab:red", label="load + BVH, s")
    axt.set_ylabel("load + BVH build (s)", color="tab:red")
    axt.set_ylim(bottom=0)
    ax1.set_title(f"Triangle count (displaced sphere, 800×600, {spp} spp)")
    labels = [f"{r['case'].split('_')[0]}\n{r['integrator'].removeprefix('direct_')}" for r in worker_rows]
    x = range(len(worker_rows))
    ax2.bar([i - 0.2 for i in x], [r["one"] / 1e6 for r in worker_rows], 0.4, label="1 worker")
    ax2.bar([i + 0.2 for i in x], [r["two"] / 1e6 for r in worker_rows], 0.4, label="2 workers")
    for i, r in enumerate(worker_rows):
        ax2.text(i + 0.2, r["two"] / 1e6, f"×{r['speedup']:.2f}", ha="center", va="bottom", fontsize=7)
    ax2.set_xticks(list(x), labels, fontsize=7)
    ax2.set_ylabel("M samples/s")
    ax2.set_ylim(0, 1.25 * max(r["two"] for r in worker_rows) / 1e6)
    ax2.set_title("Workers (forked processes)")
    ax2.legend(fontsize=8)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)


if __name__ == "__main__":
    sys.exit(main())
