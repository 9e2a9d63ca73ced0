"""The work of a render unit and the local worker pool: one (pass, tile) unit rendered into its own tile film with its
own random stream (``_render_unit``, also what a Dask worker runs), the tiling of an image into units, and the fork
pool that runs units on this machine's cores (workers die with their parent, results in unit order, a bounded
number in flight). The render loop — passes, progress, time limit, the merge — is :mod:`brdflab.renderer`.
"""

from __future__ import annotations

import functools
import itertools
import math
import mmap
import multiprocessing
import os
import signal
import sys
import threading
from collections import deque
from collections.abc import Iterable, Iterator
from concurrent.futures import Executor, ProcessPoolExecutor, ThreadPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from contextlib import nullcontext

import numpy as np

from brdflab.errors import BrdflabError, clean
from brdflab.film import Film
from brdflab.processes import die_with_parent
from brdflab.scene.geometry import RayStats

#: Target number of camera samples per work unit (see :mod:`brdflab.renderer`: per-unit costs against cache).
UNIT_SAMPLES = 1 << 16


#: Tasks queued per worker ahead of the one being merged.
IN_FLIGHT = 3


#: Units per task sent to a forked worker (fewer messages for the main process to handle: 131 k samples).
TASK_UNITS = 2


#: Workers are forked processes on Linux; elsewhere threads (macOS system libraries are not fork-safe).
FORK_WORKERS = sys.platform.startswith("linux")


#: Tiles per pass that small images still get (so that every worker has units), where 16-pixel tiles allow.
MIN_TILES = 8


def tiles_for(width: int, height: int, pass_spp: int) -> list[tuple[int, int, int, int]]:
    """Square tiles (x0, y0, w, h) sized so each unit holds about :data:`UNIT_SAMPLES` samples, and a pass
    has at least :data:`MIN_TILES` tiles where tiles of 16 pixels allow (the layout depends on the image and
    the pass only, never on the number of workers)."""
    side = min(math.sqrt(UNIT_SAMPLES / pass_spp), math.sqrt(width * height / MIN_TILES))
    side = int(np.clip(side, 16, 256)) // 8 * 8
    return [(x, y, min(side, width - x), min(side, height - y))
            for y in range(0, height, side) for x in range(0, width, side)]


def max_tile_size(width: int, height: int) -> tuple[int, int]:
    """(w, h) of the largest tile of any pass: that of a 1-spp pass (tiles shrink as passes grow)."""
    first = tiles_for(width, height, 1)[0]
    return first[2], first[3]


def _render_unit(scene, pass_index: int, tile_index: int, tile: tuple[int, int, int, int], spp: int,
                 seed: int) -> tuple[Film, int, int]:
    """Render one (pass, tile) unit into a tile film; returns (film, samples, dropped samples)."""
    # Non-finite or negative samples are counted and dropped below (and reported in the summary); NumPy's
    # floating-point warnings about them would only reach the user unlocated.
    with np.errstate(all="ignore"):
        return _render_unit_inner(scene, pass_index, tile_index, tile, spp, seed)


def _render_unit_inner(scene, pass_index: int, tile_index: int, tile: tuple[int, int, int, int], spp: int,
                       seed: int) -> tuple[Film, int, int]:
    x0, y0, w, h = tile
    cam = scene.camera
    rng = np.random.Generator(np.random.SFC64(np.random.SeedSequence([seed, pass_index, tile_index])))
    n = w * h * spp
    px, py = _pixel_offsets(w, h, spp)
    sx, sy, o, d, tmax = cam.unit_rays(rng.random((2, n)), px, py, x0, y0)
    L = scene.integrator.li(scene, o, d, tmax, rng)
    film = Film(cam.width, cam.height, scene.filter, x0, y0, w, h)
    # Two reductions over the whole batch find the (rare) non-finite or negative samples; only then
    # is the per-sample mask built.
    dropped = 0
    if not (np.isfinite(L.sum()) and L.min() >= 0):
        good = np.all(np.isfinite(L), axis=1) & np.all(L >= 0, axis=1)
        dropped = int(n - good.sum())
        sx, sy, L = sx[good], sy[good], L[good]
    film.splat(sx, sy, L)
    return film, n, dropped


@functools.lru_cache(maxsize=16)
def _pixel_offsets(w: int, h: int, spp: int) -> tuple[np.ndarray, np.ndarray]:
    """Column and row (float64, read-only) of each sample of a w × h tile with ``spp`` samples per
    pixel, pixel-major (the integer divisions are done once per tile shape)."""
    pix = np.repeat(np.arange(w * h), spp)
    px, py = (pix % w).astype(np.float64), (pix // w).astype(np.float64)
    px.flags.writeable = py.flags.writeable = False
    return px, py


#: The scene of the render in progress, inherited by forked workers (see :func:`_process_units`).
_FORK_SCENE = None


#: Shared-memory result slots of the forked workers, one per task in flight (see :func:`_results`).
_FORK_SLOTS: np.ndarray | None = None


_FORK_LOCK = threading.Lock()


#: Process id of the process that forked the workers (checked by the workers: see :func:`_worker_init`).
_PARENT_PID = 0


#: Process pools of renders in progress, so that :func:`kill_workers` can end their processes at once.
_ACTIVE_POOLS: set = set()


def _worker_init() -> None:
    """In a forked worker: die with the parent, leave SIGINT/SIGTERM/SIGHUP to it, count rays afresh.

    The parent handles the signals (it stops the render and writes the completed passes) and ends the
    workers itself; a terminal's SIGHUP or a ``kill`` of the process group must not kill a worker in the
    middle of a task. If the parent dies in any way (even SIGKILL), the kernel kills the workers
    (``PR_SET_PDEATHSIG``); the parent-pid check covers a parent that died before the prctl call and
    systems without prctl (see :func:`_process_units`).
    """
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, signal.SIG_IGN)
    die_with_parent()
    if os.getppid() != _PARENT_PID:
        os._exit(1)
    _FORK_SCENE.geometry.stats = RayStats()  # a fresh lock: the parent's may have been held at fork


def kill_workers() -> None:
    """SIGKILL the worker processes of every render in progress (a second Ctrl-C/SIGTERM: exit at once)."""
    for pool in list(_ACTIVE_POOLS):
        for proc in list((getattr(pool, "_processes", None) or {}).values()):
            try:
                os.kill(proc.pid, signal.SIGKILL)
            except (OSError, AttributeError):
                pass


def _process_units(batch: list[tuple], slot: int) -> list[tuple[int, int, int, int, float]]:
    """Units in a forked worker. Their tile films go, one after the other, into the shared result slot
    ``slot``; returns per unit (offset in the slot, samples, dropped, rays, seconds in Embree)."""
    if os.getppid() != _PARENT_PID:  # the parent is gone: nobody will read the result
        os._exit(1)
    scene = _FORK_SCENE
    st = scene.geometry.stats
    buf = _FORK_SLOTS[slot]
    out, off = [], 0
    for u in batch:
        st.reset()
        film, n, dropped = _render_unit(scene, *u)
        size = film.data.size
        buf[off:off + size] = film.data.ravel()
        out.append((off, n, dropped, st.rays, st.seconds))
        off += size
    return out


def _executor(workers: int) -> tuple[Executor | None, bool]:
    """(pool, is a process pool): forked processes where available, else threads; None for one worker."""
    if workers <= 1:
        return None, False
    if FORK_WORKERS and "fork" in multiprocessing.get_all_start_methods():
        return ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("fork"),
                                   initializer=_worker_init), True
    return ThreadPoolExecutor(workers), False


def _results(scene, units: Iterable[tuple], seed: int, workers: int, halt: threading.Event) -> Iterator[tuple]:
    """Yield (tile film, samples, dropped, rays, Embree seconds) per unit, in unit order, until ``halt``.

    ``units`` (an iterable of (pass, tile, (x0, y0, w, h), spp)) is consumed lazily, a few tasks ahead of the
    merge. Rays and seconds are those counted in worker processes (0 for in-process units, which count in
    ``scene.geometry.stats`` directly).
    """
    cam = scene.camera
    units = iter(units)
    max_tile = max_tile_size(cam.width, cam.height)
    pool, forked = _executor(workers)
    if pool is None:
        for u in units:
            if halt.is_set():
                return
            film, n, dropped = _render_unit(scene, *u, seed)
            yield film, n, dropped, 0, 0.0
        return
    global _FORK_SCENE, _FORK_SLOTS, _PARENT_PID
    border = Film(1, 1, scene.filter).border
    with _FORK_LOCK if forked else nullcontext():
        free: deque = deque()
        if forked:
            _FORK_SCENE = scene
            _PARENT_PID = os.getpid()
            # Tile films come back through shared memory (mapped before the workers fork), not pickled
            # through a pipe: that took a third of the main process's CPU time.
            slot_len = TASK_UNITS * 4 * (max_tile[1] + 2 * border) * (max_tile[0] + 2 * border)
            n_slots = IN_FLIGHT * workers
            _FORK_SLOTS = np.frombuffer(mmap.mmap(-1, n_slots * slot_len * 8), np.float64).reshape(n_slots, slot_len)
            free.extend(range(n_slots))
        _ACTIVE_POOLS.add(pool)
        try:
            pending: deque = deque()
            k = TASK_UNITS if forked else 1

            def submit() -> None:
                b = list(itertools.islice(units, k))
                if not b:
                    return
                if forked:
                    slot = free.popleft()
                    pending.append((b, slot, pool.submit(_process_units, [(*u, seed) for u in b], slot)))
                else:
                    pending.append((b, None, pool.submit(_render_unit, scene, *b[0], seed)))

            for _ in range(IN_FLIGHT * workers):
                submit()
            while pending and not halt.is_set():
                b, slot, fut = pending.popleft()
                try:
                    res = fut.result()
                except SystemExit as exc:  # sys.exit() in a worker's task (a plugin outside its checks)
                    raise BrdflabError(f"a render worker called sys.exit({clean(exc.code, 30)}); no image "
                                       "written") from None
                except BrokenProcessPool:
                    raise BrdflabError("a render worker process died unexpectedly (killed by the system, "
                                       "perhaps out of memory); no image written") from None
                if forked:
                    for u, (off, n, dropped, rays, secs) in zip(b, res, strict=True):
                        x0, y0, w, h = u[2]
                        shape = (4, h + 2 * border, w + 2 * border)
                        data = _FORK_SLOTS[slot, off:off + shape[0] * shape[1] * shape[2]].reshape(shape)
                        # The consumer adds the tile before asking for the next one; the slot is reused
                        # only after the whole task has been consumed.
                        film = Film(cam.width, cam.height, scene.filter, x0, y0, w, h, data)
                        yield film, n, dropped, rays, secs
                    free.append(slot)
                else:
                    yield (*res, 0, 0.0)
                submit()
        except GeneratorExit:  # the caller stopped early (stop request, time limit): running tasks finish
            raise
        except BaseException:
            # An error or a KeyboardInterrupt: the queued and running units are of no use; end the
            # workers now instead of waiting for their tasks.
            if forked:
                kill_workers()
            raise
        finally:
            try:
                pool.shutdown(wait=True, cancel_futures=True)
            finally:
                _ACTIVE_POOLS.discard(pool)
                _FORK_SCENE = _FORK_SLOTS = None


class ForkPool:
    """The built-in executor: forked worker processes on this machine (threads off Linux; in-process for
    one worker). :class:`brdflab.cluster.Cluster` implements the same interface on a Dask cluster."""

    def __init__(self, workers: int | None = None) -> None:
        self.workers = workers or os.cpu_count() or 1

    def results(self, scene, units: Iterable[tuple], seed: int, halt: threading.Event) -> Iterator[tuple]:
        """Yield (tile film, samples, dropped, rays, Embree seconds) per unit, in unit order, until ``halt``."""
        return _results(scene, units, seed, self.workers, halt)

    def finish(self, image: np.ndarray, stats) -> None:
        """Called with the image and stats when the render ends (nothing to do here)."""
