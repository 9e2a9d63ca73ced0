"""``--cluster ADDRESS`` for the commands that can run on a Dask cluster (see :mod:`brdflab.cluster`)."""

from __future__ import annotations

import argparse
import logging
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager

from brdflab.errors import BrdflabError


def add_cluster_options(p: argparse.ArgumentParser, scene_transfer: bool = False) -> None:
    """Add ``--cluster`` (and, for commands that ship scenes, ``--scene-transfer``) to ``p``."""
    p.add_argument("--cluster", metavar="ADDRESS",
                   help="run on a Dask cluster: tcp://HOST:PORT of a running scheduler, or local / local:N for a "
                   "LocalCluster of N single-threaded worker processes (default: $BRDFLAB_CLUSTER; none: this "
                   "machine's worker pool). Results are identical to a local run")
    if scene_transfer:
        p.add_argument("--scene-transfer", choices=("ship", "path"), default="ship",
                       help="how the scene reaches cluster workers: ship the loaded scene once per worker "
                       "(default), or path: each worker loads the file from a shared file system")


def _address(args: argparse.Namespace) -> str | None:
    from brdflab.cluster import cluster_address

    if args.cluster is not None and getattr(args, "workers", None) is not None:
        raise BrdflabError("--workers sets the local worker pool; with --cluster the cluster's workers are used")
    if args.cluster is None and getattr(args, "workers", None) is not None:
        return None  # an explicit local pool wins over $BRDFLAB_CLUSTER
    return cluster_address(args.cluster)


def _quiet_dask() -> None:
    """Dask logs worker restarts and reconnection attempts (with tracebacks); brdflab reports what matters
    in one line. Its configuration gives some loggers their own level, so each is set."""
    import distributed  # noqa: F401 - configures the loggers

    for name in ["distributed", *logging.root.manager.loggerDict]:
        if name == "distributed" or name.startswith("distributed."):
            logging.getLogger(name).setLevel(logging.CRITICAL + 1)


@contextmanager
def cluster_from_args(args: argparse.Namespace, quiet: bool = False) -> Iterator:
    """The :class:`brdflab.cluster.Cluster` the arguments ask for (None for a local run), closed on exit."""
    address = _address(args)
    if address is None:
        yield None
        return
    from brdflab.cluster import Cluster

    if not getattr(args, "debug", False):
        _quiet_dask()
    t0 = time.perf_counter()
    cl = Cluster(address, scene_transfer=getattr(args, "scene_transfer", "ship"))
    try:
        if not quiet:
            print(f"{cl.describe()} (ready in {time.perf_counter() - t0:.1f} s)", file=sys.stderr)
        yield cl
    finally:
        cl.close()
