"""Scale-out on a Dask cluster: renders, studies and sweeps with results identical to a local run.

Where the work runs is given by an *address* (``--cluster`` on the command line, or the environment
variable ``BRDFLAB_CLUSTER``):

``tcp://HOST:PORT`` (or ``HOST:PORT``)
    A running Dask scheduler (``dask scheduler`` plus ``dask worker tcp://HOST:PORT --nthreads 1`` on
    each machine; the workers need the same brdflab installed, which is checked).
``local`` / ``local:N``
    A ``distributed.LocalCluster`` of N single-threaded worker processes on this machine (default N: the
    number of cores), bound to 127.0.0.1, without a dashboard; brdflab starts it and always shuts it down.

Renders
-------
:func:`brdflab.renderer.render` hands its (pass, tile) units to an *executor* — the built-in fork pool or a
:class:`Cluster`; both yield the units' tile films in unit order, and the render loop adds them in that
fixed order, so the image is **bit-identical** to ``--workers N`` for any cluster size and any
scheduling (every unit draws its random numbers from its own ``SeedSequence([seed, pass, tile])``).

A Dask task carries :data:`TASK_UNITS` consecutive units and returns their tile films as one float64
array (the per-unit counters beside it). At most :data:`WINDOW` tasks per worker thread are submitted
ahead of the unit being merged: a stop (Ctrl-C, ``time_limit``) cancels at most that many, and results
never pile up in the workers' memory. Per-task overhead on this machine (2 cores shared by the
scheduler, the client and the workers) is a few milliseconds, against ~150 ms of work in an 8-unit
Cornell-box task; see the README's "Scale-out" section for the measurements.

The scene reaches the workers in one of two ways (``scene_transfer``):

``"ship"`` (default)
    The loaded scene object is pickled once (its Embree BVH left out; its triangle tables rebuilt from
    the meshes on the worker), scattered once to every worker, and rebuilt once per worker process,
    cached by the SHA-256 of its bytes. Works for any scene — loaded with overrides, with plugin
    materials (classes from plugin files travel by value), or changed in memory — and needs no shared
    file system.
``"path"``
    Each worker loads the scene file itself (same absolute path: a shared file system), with the
    client's integrator, image size and emitter selection (built-in materials, or plugins importable on
    the workers); the worker checks that its XML file and geometry hash
    to the client's, so a stale copy fails loudly instead of rendering a different image. Nothing but
    the path travels: for very large meshes on a cluster with a shared file system. (Image and texture
    files are not compared, and changes made to the scene in memory do not reach the workers.)

Every worker also checks that its brdflab source hashes to the client's (:func:`code_digest`): images
are identical only between identical renderers.

Faults: a worker that dies mid-render loses its tasks, which the scheduler reruns elsewhere (same units,
same seeds: same image). A lost scheduler ends the render with a :class:`ClusterError` that carries the
image of the completed passes (the CLI writes it as ``<stem>_partial_<N>spp``). On a stop or an error
the outstanding tasks are cancelled.

Studies and sweeps
------------------
:func:`map_jobs` runs ``fn(job)`` over independent job descriptors, locally or on a cluster, and returns
the results in job order. Each job carries its own seed, so results do not depend on placement.
"""

from __future__ import annotations

import atexit
import hashlib
import itertools
import logging
import os
import re
import threading
import time
import uuid
import weakref
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

import numpy as np

from brdflab.cluster_tasks import (  # noqa: F401 (re-exported: the module's former contents)
    _SCENES,
    _SCENES_LOCK,
    SCENE_CACHE,
    SceneRef,
    WorkerStats,
    _attach_embree,
    _ignore_sigint,
    _ignore_sigint_plugin,
    _path_fingerprint,
    _rebuild_geometry,
    _render_task,
    _ship_plugin_modules,
    _worker_name,
    _worker_scene,
    code_digest,
    register_user_bsdfs,
    scene_bytes,
    user_bsdf_classes,
)
from brdflab.errors import BrdflabError, ascii_int
from brdflab.kernels import engine

#: Environment variable holding the default cluster address.
ENV = "BRDFLAB_CLUSTER"
#: (pass, tile) units per Dask task (~0.5 M camera samples, ~150 ms on the Cornell box; see the module doc).
TASK_UNITS = 8
#: Tasks submitted per worker thread ahead of the unit being merged.
WINDOW = 4
#: How the scene reaches the workers.
SCENE_TRANSFERS = ("ship", "path")
#: Seconds to wait for a scheduler to answer, and for its first worker to join.
CONNECT_TIMEOUT = 10.0
WORKER_WAIT = 60.0
_SCHEMES = ("tcp",)


class ClusterError(BrdflabError):
    """The cluster failed: scheduler unreachable or lost, or a task repeatedly killed its workers.

    For a render, ``image`` and ``stats`` hold the completed passes (``stats.spp`` of them; ``image`` is
    None when no pass completed).
    """

    def __init__(self, message: str, image: np.ndarray | None = None, stats=None) -> None:
        super().__init__(message)
        self.image = image
        self.stats = stats


def parse_address(text: str) -> tuple[str, int | str]:
    """Parse a cluster address: ``("local", N)`` or ``("remote", "tcp://host:port")``.

    Raises
    ------
    BrdflabError
        For anything else, with the accepted forms.
    """
    from brdflab.limits import max_local_workers

    t = text.strip()
    shown = t[:60].encode("unicode_escape").decode("ascii")
    if t == "local" or t.startswith("local:"):
        n = t[6:]
        if not n:
            return "local", os.cpu_count() or 1
        if ascii_int(n) is not None and 1 <= int(n) < 10**9:
            limit = max_local_workers()
            if int(n) > limit:
                raise BrdflabError(f"cluster address '{shown}': at most {limit} local workers (4 per core; raise "
                                   "it with BRDFLAB_MAX_LOCAL_WORKERS=<N>)")
            return "local", int(n)
    else:
        scheme, sep, rest = t.rpartition("://")
        if (sep and scheme not in _SCHEMES) or (sep and "://" in scheme):
            raise BrdflabError(f"cluster address: expected tcp://HOST:PORT, got '{shown}' (brdflab connects only "
                               "over tcp: other Dask transports need a configuration it does not pass)")
        m = re.fullmatch(r"([A-Za-z0-9_.\-]+|\[[0-9A-Fa-f:]+\]):([0-9]{1,5})", rest)
        if m and 1 <= int(m.group(2)) <= 65535:
            return "remote", "tcp://" + rest
    raise BrdflabError(f"cluster address: expected tcp://HOST:PORT (port 1–65535), local or local:N (N ≥ 1), "
                       f"got '{shown}'")


def cluster_address(option: str | None) -> str | None:
    """The cluster to use: ``option`` if given, else ``$BRDFLAB_CLUSTER``; None (local fork pool) when
    neither is set or the value is ``none``."""
    value = option if option is not None else os.environ.get(ENV)
    if value is None or value.strip().lower() in ("", "none", "off"):
        return None
    parse_address(value)
    return value.strip()


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= 160 else text[:157] + "..."


class Cluster:
    """A connection to a Dask cluster: the render executor and :meth:`map` for studies and sweeps.

    Parameters
    ----------
    address
        ``"tcp://host:port"``, ``"local"`` / ``"local:N"`` (see :func:`parse_address`), or a Dask cluster
        object (``LocalCluster``, ``dask_jobqueue.SLURMCluster`` …) or ``distributed.Client``.
    scene_transfer
        ``"ship"`` (default) or ``"path"``: how renders get their scene to the workers (module doc).
    task_units
        (pass, tile) units per task.
    wait
        Seconds to wait for the first worker to join.
    timeout
        Seconds to wait for the scheduler to answer.
    close_after_render
        Close after the first render (:func:`brdflab.renderer.render` given an address does this).

    Use it as a context manager (a LocalCluster brdflab started is shut down on exit, and at interpreter
    exit at the latest)::

        with Cluster("local:2") as cl:
            image, stats = render(scene, spp=64, cluster=cl)
    """

    def __init__(self, address, scene_transfer: str = "ship", task_units: int = TASK_UNITS,
                 wait: float = WORKER_WAIT, timeout: float = CONNECT_TIMEOUT, close_after_render: bool = False) -> None:
        from distributed import Client, LocalCluster

        if scene_transfer not in SCENE_TRANSFERS:
            raise BrdflabError(f"scene transfer: expected one of {', '.join(SCENE_TRANSFERS)}, got '{scene_transfer}'")
        self.scene_transfer = scene_transfer
        self.close_after_render = close_after_render
        self.task_units = max(1, int(task_units))
        self._local = None
        self._own_client = True
        self.worker_stats: dict[str, WorkerStats] = {}
        self.failure: ClusterError | None = None
        if isinstance(address, str):
            kind, arg = parse_address(address)
            self.address = address
            if kind == "local":
                self._local = LocalCluster(n_workers=arg, threads_per_worker=1, processes=True, host="127.0.0.1",
                                           dashboard_address=None, silence_logs=logging.CRITICAL)
                self.client = Client(self._local, set_as_default=False)
                self.client.register_plugin(_ignore_sigint_plugin())
            else:
                try:
                    self.client = Client(arg, timeout=timeout, set_as_default=False)
                except Exception as exc:  # noqa: BLE001 - Dask's errors for an unreachable/odd scheduler vary
                    raise ClusterError(f"cannot reach the Dask scheduler at {arg}: {_one_line(exc)}") from None
        elif isinstance(address, Client):
            self.client, self._own_client = address, False
            self.address = address.scheduler.address
        else:
            self.client = Client(address, set_as_default=False)
            self.address = getattr(address, "scheduler_address", repr(address))
        self._finalizer = weakref.finalize(self, _shutdown, self.client if self._own_client else None, self._local)
        atexit.register(self._finalizer)
        try:
            self.client.wait_for_workers(1, timeout=wait)
        except TimeoutError:
            self.close()
            raise ClusterError(f"no Dask worker joined the scheduler at {self.address} within {wait:g} s") from None

    # -- lifetime
    def __enter__(self) -> Cluster:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Disconnect; shut down the LocalCluster if this object started it."""
        self._finalizer()

    @property
    def workers(self) -> int:
        """Worker threads in the cluster now."""
        try:
            return max(1, sum(self.client.nthreads().values()))
        except (OSError, TimeoutError):
            return 1

    def describe(self) -> str:
        """One line: the address and the workers."""
        nt = self.client.nthreads()
        kind = "LocalCluster" if self._local is not None else "scheduler"
        return (f"cluster: {kind} {self.client.scheduler.address}, {len(nt)} worker{'s' if len(nt) != 1 else ''}, "
                f"{sum(nt.values())} thread{'s' if sum(nt.values()) != 1 else ''}")

    # -- the render executor
    def _scene_ref(self, scene) -> tuple[SceneRef, object]:
        if self.scene_transfer == "path":
            path = str(Path(scene.path).resolve())
            ref = SceneRef(_path_fingerprint(scene), code_digest(), path, scene.integrator_type,
                           (scene.camera.width, scene.camera.height), scene.emitter_pmf, scene.emitter_cdf)
            return ref, None
        blob = scene_bytes(scene)
        ref = SceneRef(hashlib.sha256(blob).hexdigest(), code_digest())
        return ref, self.client.scatter(blob, broadcast=True, hash=False)

    def results(self, scene, units: Iterable[tuple], seed: int, halt: threading.Event) -> Iterator[tuple]:
        """Yield (tile film, samples, dropped, rays, Embree seconds) per unit, in unit order, until ``halt``
        (the executor interface of :func:`brdflab.renderer.render`). A lost scheduler ends the iteration
        and is recorded in :attr:`failure`; other task errors are raised."""
        from distributed.client import FutureCancelledError

        from brdflab.film import Film

        self.worker_stats, self.failure = {}, None
        cam = scene.camera
        border = Film(1, 1, scene.filter).border
        tag = uuid.uuid4().hex[:8]
        try:
            ref, blob = self._scene_ref(scene)
        except (OSError, TimeoutError) as exc:
            self.failure = ClusterError(f"lost the Dask cluster at {self.address}: {_one_line(exc)}")
            return
        k = self.task_units
        unit_iter = iter(units)  # a lazy stream (huge sample counts build no list)
        batches = iter(lambda: list(itertools.islice(unit_iter, k)), [])
        pending: deque = deque()
        state = {"next": 0, "window": WINDOW * self.workers, "checked": time.monotonic()}
        eng = engine()  # the workers compute with the client's engine (BRDFLAB_ENGINE / --engine)

        def top_up() -> None:
            now = time.monotonic()
            if now - state["checked"] > 1.0:  # workers may join or leave during a long render
                state["window"], state["checked"] = WINDOW * self.workers, now
            while len(pending) < state["window"]:
                b = next(batches, None)
                if b is None:
                    return
                key = f"brdflab-render-{tag}-{state['next']}"
                state["next"] += 1
                pending.append((b, self.client.submit(_render_task, ref, blob, b, seed, eng, key=key, pure=False)))

        try:
            top_up()
            while pending and not halt.is_set():
                b, fut = pending.popleft()
                try:
                    meta, data, worker, busy = fut.result()
                except (FutureCancelledError, OSError, TimeoutError) as exc:
                    self.failure = ClusterError(self._lost_message(exc))
                    return
                except Exception as exc:
                    if type(exc).__name__ == "KilledWorker":
                        self.failure = ClusterError(f"a render task killed {_one_line(exc)}")
                        return
                    raise
                fut.release()
                ws = self.worker_stats.setdefault(worker, WorkerStats())
                ws.tasks += 1
                ws.busy_seconds += busy
                off = 0
                for u, (n, dropped, rays, secs) in zip(b, meta, strict=True):
                    x0, y0, w, h = u[2]
                    shape = (4, h + 2 * border, w + 2 * border)
                    size = shape[0] * shape[1] * shape[2]
                    film = Film(cam.width, cam.height, scene.filter, x0, y0, w, h, data[off:off + size].reshape(shape))
                    off += size
                    ws.samples += n
                    ws.ray_seconds += secs
                    yield film, n, dropped, rays, secs
                top_up()
        finally:
            left = [f for _, f in pending]
            if left:
                try:
                    self.client.cancel(left, force=True)
                except Exception:  # noqa: BLE001 - the scheduler may be gone; nothing left to cancel then
                    pass
            if blob is not None:
                blob.release()
            if self.close_after_render:
                self.close()

    def _lost_message(self, exc: BaseException) -> str:
        reason = getattr(exc, "reason", "")
        if reason == "scheduler-connection-lost" or isinstance(exc, OSError | TimeoutError):
            return f"lost the connection to the Dask scheduler at {self.address}"
        return f"a render task was cancelled by the cluster ({reason or _one_line(exc)})"

    def finish(self, image: np.ndarray, stats) -> None:
        """After a render: raise the recorded failure with the completed passes attached."""
        stats.per_worker = dict(self.worker_stats)
        if self.failure is not None:
            err, self.failure = self.failure, None
            err.image, err.stats = (image if stats.spp > 0 else None), stats
            raise err

    def summary(self) -> list[str]:
        """Per-worker lines of the last render: tasks, samples/s while busy, Embree share."""
        lines = []
        for addr, ws in sorted(self.worker_stats.items()):
            rate = ws.samples / ws.busy_seconds if ws.busy_seconds > 0 else 0.0
            lines.append(f"  {addr}: {ws.tasks} tasks, {ws.samples / 1e6:.2f} M samples, {rate / 1e6:.2f} M samples/s "
                         f"while busy, {100 * ws.embree_share:.0f}% in ray queries")
        return lines

    # -- studies and sweeps
    def imap(self, fn: Callable, jobs: Iterable) -> Iterator:
        """Yield ``fn(job)`` for every job, in job order, computed on the cluster (``fn`` must be
        importable by the workers: a module-level function). Closing the iterator cancels the rest."""
        from distributed.client import FutureCancelledError

        self._check_code()
        tag = uuid.uuid4().hex[:8]
        futures = [self.client.submit(fn, job, key=f"brdflab-job-{tag}-{i}", pure=False) for i, job in enumerate(jobs)]
        done = 0
        try:
            for fut in futures:
                try:
                    result = fut.result()
                except (FutureCancelledError, OSError, TimeoutError) as exc:
                    raise ClusterError(self._lost_message(exc)) from None
                fut.release()
                done += 1
                yield result
        finally:
            if done < len(futures):
                try:
                    self.client.cancel(futures[done:], force=True)
                except Exception:  # noqa: BLE001 - nothing to cancel on a lost scheduler
                    pass

    def _check_code(self) -> None:
        """Every worker must run the client's brdflab (jobs compute on the workers' code)."""
        if getattr(self, "_code_checked", False):
            return
        for addr, digest in self.client.run(code_digest).items():
            if digest != code_digest():
                raise BrdflabError(f"worker {addr} runs a different brdflab than the client (source digest "
                                   f"{digest[:12]} ≠ {code_digest()[:12]}); install the same version on every worker")
        self._code_checked = True

    def map(self, fn: Callable, jobs: Iterable) -> list:
        """``[fn(job) for job in jobs]`` on the cluster, in job order."""
        return list(self.imap(fn, jobs))


def _shutdown(client, local) -> None:
    """Close the client (if ours) and the LocalCluster (if started by brdflab)."""
    for obj in (client, local):
        if obj is not None:
            try:
                obj.close(timeout=5) if obj is client else obj.close()
            except Exception:  # noqa: BLE001 - best effort at shutdown; the processes exit with the parent
                pass


def open_cluster(cluster) -> tuple[Cluster | None, bool]:
    """(a :class:`Cluster`, whether the caller must close it) for an address, a Cluster or None."""
    if cluster is None or isinstance(cluster, Cluster):
        return cluster, False
    return Cluster(cluster), True


def iter_jobs(fn: Callable, jobs: Iterable, cluster=None) -> Iterator:
    """Yield ``fn(job)`` for every job in job order: on ``cluster`` (an address or a :class:`Cluster`) when
    given, else in this process.

    ``fn`` must be a module-level function and each job a picklable descriptor carrying its own seed, so
    the results do not depend on where or in which order the jobs run.
    """
    cl, owned = open_cluster(cluster)
    if cl is None:
        for job in jobs:
            yield fn(job)
        return
    try:
        yield from cl.imap(fn, jobs)
    finally:
        if owned:
            cl.close()


def map_jobs(fn: Callable, jobs: Iterable, cluster=None) -> list:
    """``[fn(job) for job in jobs]`` in job order, on ``cluster`` when given (see :func:`iter_jobs`).

    Examples
    --------
    >>> from brdflab.cluster import map_jobs
    >>> map_jobs(abs, [-1, 2, -3])
    [1, 2, 3]
    """
    return list(iter_jobs(fn, jobs, cluster))
