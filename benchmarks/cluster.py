"""The Dask executor against the built-in fork pool, side by side in one run; per-task overhead.

Usage (brdflab's environment active)::

    python benchmarks/cluster.py [SCENE] [--spp 64] [--rounds 5] [--task-units 8,16,32,64]

* Starts ``dask scheduler`` and two ``dask worker --nthreads 1`` processes on 127.0.0.1 (random port, no
  dashboard), as a user would by hand, and stops them at the end.
* Renders SCENE (default: the course Cornell box, ``../shared/scenes/assignment-3/cbox/cbox_conductors_ems.xml``)
  at ``--spp`` alternately with ``workers=2`` (fork pool) and on the cluster, ``--rounds`` times each, after
  one warm-up render of each (the workers import brdflab and build the scene once); reports median
  samples/s of both and their ratio, and checks that every cluster image is bit-identical to the fork
  pool's.
* Per-task overhead: (a) round trip of empty tasks (submit + run + gather, 2 workers); (b) in the renders,
  ``1 − Σ worker busy time / (wall time × workers)`` — the share of the workers' time not spent in tasks;
  (c) CPU time per render task of the client (receiving and merging tile films) and of the scheduler
  process; (d) bytes of tile films returned per task.
* ``--task-units`` also times one cluster render per batch size (units per task), alternating.
* Writes ``benchmarks/results/cluster.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import socket
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import psutil

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))

from brdflab.cluster import Cluster, scene_bytes  # noqa: E402
from brdflab.renderer import render  # noqa: E402
from brdflab.scene.loader import load_scene  # noqa: E402

DEFAULT_SCENE = ROOT.parent / "shared" / "scenes" / "assignment-3" / "cbox" / "cbox_conductors_ems.xml"


def _noop(x):
    return x


def start_cluster(n: int) -> tuple[str, list[subprocess.Popen]]:
    """``dask scheduler`` + n single-threaded ``dask worker`` processes on 127.0.0.1."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    addr = f"tcp://127.0.0.1:{port}"
    bindir = Path(sys.executable).parent
    quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL}
    procs = [subprocess.Popen([bindir / "dask", "scheduler", "--host", "127.0.0.1", "--port", str(port),
                               "--no-dashboard"], **quiet)]
    procs += [subprocess.Popen([bindir / "dask", "worker", addr, "--nthreads", "1", "--host", "127.0.0.1",
                                "--no-dashboard"], cwd=ROOT, **quiet) for _ in range(n)]
    return addr, procs


def task_round_trip(cl: Cluster, n: int = 400) -> float:
    """Seconds per empty task (submit, schedule, run, gather) with all tasks in flight."""
    client = cl.client
    client.gather(client.map(_noop, range(20), pure=False))
    t0 = time.perf_counter()
    client.gather(client.map(_noop, range(n), pure=False))
    return (time.perf_counter() - t0) / n


def idle_share(stats) -> float:
    busy = sum(w.busy_seconds for w in stats.per_worker.values())
    return 1.0 - busy / (stats.seconds * stats.workers) if stats.seconds > 0 else 0.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scene", nargs="?", type=Path, default=DEFAULT_SCENE)
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--task-units", default="", help="comma-separated batch sizes to compare (optional)")
    ap.add_argument("--json", type=Path, default=HERE / "results" / "cluster.json")
    args = ap.parse_args()
    if not args.scene.exists():
        sys.exit(f"scene {args.scene} not found")
    scene = load_scene(args.scene)
    blob = len(scene_bytes(scene))
    addr, procs = start_cluster(2)
    rec: dict = {"date": time.strftime("%Y-%m-%d %H:%M"), "scene": str(args.scene), "spp": args.spp,
                 "rounds": args.rounds, "machine": {"cpus": os.cpu_count(), "platform": platform.platform(),
                                                    "load_avg_start": os.getloadavg()},
                 "scene_bytes_shipped_per_worker": blob}
    try:
        with Cluster(addr, timeout=60) as cl:
            cl.client.wait_for_workers(2, timeout=120)
            rec["empty_task_seconds"] = statistics.median(task_round_trip(cl) for _ in range(3))
            ref, _ = render(scene, spp=args.spp, seed=0, workers=2)  # warm-up
            img, _ = render(scene, spp=args.spp, seed=0, cluster=cl)  # warm-up: ships and builds the scene
            assert np.array_equal(img, ref), "cluster image differs from the fork pool's"
            fork, dask, idle, tasks, embree, client_cpu, sched_cpu = [], [], [], 0, [], [], []
            sched = psutil.Process(procs[0].pid)
            for r in range(args.rounds):
                order = ("fork", "dask") if r % 2 == 0 else ("dask", "fork")
                for kind in order:
                    if kind == "fork":
                        img, st = render(scene, spp=args.spp, seed=0, workers=2)
                        fork.append(st.samples_per_second)
                    else:
                        c0, s0 = time.process_time(), sum(sched.cpu_times()[:2])
                        img, st = render(scene, spp=args.spp, seed=0, cluster=cl)
                        c1, s1 = time.process_time(), sum(sched.cpu_times()[:2])
                        dask.append(st.samples_per_second)
                        idle.append(idle_share(st))
                        tasks = sum(w.tasks for w in st.per_worker.values())
                        client_cpu.append((c1 - c0) / tasks)
                        sched_cpu.append((s1 - s0) / tasks)
                        embree.append({a: round(w.embree_share, 3) for a, w in st.per_worker.items()})
                    assert np.array_equal(img, ref), f"{kind} image differs"
                    print(f"round {r}: {kind:4s} {st.samples_per_second / 1e6:.3f} M samples/s "
                          f"({st.seconds:.2f} s)", flush=True)
            border = 3  # the Gaussian filter's border (⌈2⌉ + 1): a 16 × 16 tile's film is 22 × 22 × 4 float64
            rec["film_bytes_per_task"] = cl.task_units * 4 * (16 + 2 * border) ** 2 * 8
            rec["samples_per_task"] = cl.task_units * (1 << 14)
            rec.update(client_cpu_per_task=statistics.median(client_cpu),
                       scheduler_cpu_per_task=statistics.median(sched_cpu))
            rec.update(fork_samples_per_s=fork, dask_samples_per_s=dask, idle_share=idle, tasks_per_render=tasks,
                       embree_share_per_worker=embree, bit_identical=True,
                       median_fork=statistics.median(fork), median_dask=statistics.median(dask),
                       ratio=statistics.median(dask) / statistics.median(fork),
                       ratio_per_round=[d / f for d, f in zip(dask, fork, strict=True)])
            sizes = [int(t) for t in args.task_units.split(",") if t.strip()]
            if sizes:
                per = {k: [] for k in sizes}
                for r in range(max(1, args.rounds // 2)):
                    for k in sizes if r % 2 == 0 else reversed(sizes):
                        cl.task_units = k
                        _, st = render(scene, spp=args.spp, seed=0, cluster=cl)
                        per[k].append(st.samples_per_second)
                rec["task_units_samples_per_s"] = {k: statistics.median(v) for k, v in per.items()}
    finally:
        for p in procs:
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
    rec["machine"]["load_avg_end"] = os.getloadavg()
    print(f"empty task round trip: {1e3 * rec['empty_task_seconds']:.2f} ms; scene shipped per worker: "
          f"{blob / 2**20:.2f} MiB; {rec['tasks_per_render']} tasks per render")
    print(f"per render task: client CPU {1e3 * rec['client_cpu_per_task']:.2f} ms, scheduler CPU "
          f"{1e3 * rec['scheduler_cpu_per_task']:.2f} ms, {rec['film_bytes_per_task'] / 1024:.0f} KiB of tile films "
          f"for {rec['samples_per_task']:,} samples")
    print(f"fork pool (2 workers): {rec['median_fork'] / 1e6:.3f} M samples/s; dask (2 single-threaded workers): "
          f"{rec['median_dask'] / 1e6:.3f} M samples/s; ratio {rec['ratio']:.3f} (median of {args.rounds}, "
          f"alternating); workers idle {100 * statistics.median(rec['idle_share']):.1f} % of the render")
    if "task_units_samples_per_s" in rec:
        print("units per task → M samples/s: " + ", ".join(
            f"{k}: {v / 1e6:.3f}" for k, v in rec["task_units_samples_per_s"].items()))
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(rec, indent=2))
    print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
