"""brdflab on a SLURM cluster with dask-jobqueue (``pip install dask-jobqueue``).

Run this on the login node: it starts a Dask scheduler there, submits batch jobs whose Dask workers join
it, and renders on them. Every job runs ``JOB["processes"]`` single-threaded worker processes (brdflab's
NumPy batches hold the GIL between calls: processes, not threads). The workers need the same brdflab in
the same environment (``python`` below); the scene is shipped to them, no shared file system needed.

    python docs/slurm_cluster.py scenes/cbox/cbox_spheres.xml 4096 --jobs 8 --queue short --account lab

``make_cluster`` is tested (it builds the job script without submitting anything).
"""

from __future__ import annotations

import argparse
import sys

#: One SLURM job: 8 single-threaded worker processes on 8 cores.
JOB = {"cores": 8, "processes": 8, "memory": "16GB", "walltime": "02:00:00"}


def make_cluster(queue: str | None = None, account: str | None = None, host: str | None = None,
                 dashboard_address: str | None = ":8787", **overrides):
    """A ``dask_jobqueue.SLURMCluster`` for brdflab workers (no job is submitted until ``scale``)."""
    from dask_jobqueue import SLURMCluster

    scheduler = {"dashboard_address": dashboard_address, "dashboard": bool(dashboard_address)}
    if host:
        scheduler["host"] = host
    options = dict(JOB, queue=queue, account=account, python=sys.executable, scheduler_options=scheduler)
    options.update(overrides)
    return SLURMCluster(**options)


def main() -> None:
    from brdflab.cluster import Cluster
    from brdflab.imageio import write_exr
    from brdflab.renderer import render
    from brdflab.scene.loader import load_scene

    ap = argparse.ArgumentParser()
    ap.add_argument("scene")
    ap.add_argument("spp", type=int)
    ap.add_argument("--jobs", type=int, default=4)
    ap.add_argument("--queue")
    ap.add_argument("--account")
    args = ap.parse_args()
    slurm = make_cluster(args.queue, args.account)
    slurm.scale(jobs=args.jobs)
    print(slurm.job_script())
    scene = load_scene(args.scene)
    with Cluster(slurm, wait=600) as cl:  # wait for the first job to start
        image, stats = render(scene, spp=args.spp, cluster=cl)
        print(stats.summary())
        print("\n".join(cl.summary()))
    slurm.close()
    write_exr(args.scene.rsplit(".", 1)[0] + f"_{args.spp}spp.exr", image)


if __name__ == "__main__":
    main()
