"""The render loop: sample passes × tiles on worker processes, merged deterministically.

Work is split into *passes* (a number of samples per pixel) and, within a pass, into square *tiles*.
Each (pass, tile) unit draws all its random numbers from its own ``numpy.random.Generator`` (SFC64,
30 % faster than the default PCG64 for the ~6 uniforms per sample) seeded with ``SeedSequence([seed, pass,
tile])`` and splats into a private tile film; the main process adds the tile
films into the image in unit order. The image is therefore bit-identical for any number of workers.

Workers are **forked processes** (they inherit the loaded scene and its Embree BVH copy-on-write; a unit
returns only its small tile film and its ray counters). Threads were measured first: a unit of 16 k
samples makes ~800 NumPy calls of ~10 µs, and with the GIL held between (and during some of) them two
threads reached only 1.3–1.6× one; two forked workers reach 1.7–1.9× one (bench scenes). Off Linux the
pool falls back to threads.

On two cores the main process's CPU time is taken from the workers, so it is kept small: a forked worker
gets :data:`TASK_UNITS` consecutive units per task (one message per task; with one unit per task the
futures and pipes took 9 % of the two cores), and writes their tile films into a shared-memory slot of the
task (mapped before the workers fork) instead of pickling them through a pipe. Cornell box, 2 workers:
main-process CPU 0.92 s per render with one unit per task, 0.35 s with 8, 0.21 s with shared slots. At
most :data:`IN_FLIGHT` tasks per worker are queued, so a stop request (Ctrl-C, ``time_limit``) takes
effect within about one task (8 units, ~40 ms on the bench scenes).

Units hold about :data:`UNIT_SAMPLES` camera samples: small enough that a batch's ~20 live float64 columns
stay in the 2 MiB per-core L2 cache (measured on the Cornell box, one worker: 65 k samples 1.71 M
samples/s, 16 k 1.97 M, 4 k 1.60 M, where the per-call overhead takes over).

Pass sizes are 1, 1, 2, 4, … (doubling up to ``max_pass``), then ``max_pass`` each, so every power of
two up to the final count is a pass boundary: a progressive run of 256 spp yields the 1, 2, 4, …, 128
spp images as checkpoints (:func:`render` ``on_pass``), each with its elapsed time.
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
import time
import types
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Executor, ProcessPoolExecutor, ThreadPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from contextlib import nullcontext
from dataclasses import dataclass, field

import numpy as np

from brdflab.alloc import tune_allocator
from brdflab.errors import BrdflabError, clean
from brdflab.film import Film
from brdflab.limits import WORKER_BYTES, check_memory, check_spp, check_work
from brdflab.scene.geometry import RayStats

#: Target number of camera samples per work unit (a batch's temporaries stay in the L2 cache).
UNIT_SAMPLES = 1 << 14
#: Tasks queued per worker ahead of the one being merged.
IN_FLIGHT = 3
#: Units per task sent to a forked worker (fewer messages for the main process to handle).
TASK_UNITS = 8
#: Samples per pixel of a pass when no intermediate images are asked for: a 16 k-sample unit then covers
#: 16 × 16 pixels, whose tile film (22 × 22 with the filter's border) is a third of a 16-spp unit's (38 × 38):
#: less to splat, transfer and merge per sample (Cornell box, 2 workers, 64 spp: 4.94 → 4.75 s).
BATCH_PASS = 64
#: Most worker processes accepted (each costs memory, see :func:`render_memory`).
MAX_WORKERS = 256
#: Workers are forked processes on Linux; elsewhere threads (macOS system libraries are not fork-safe).
FORK_WORKERS = sys.platform.startswith("linux")


def iter_passes(spp: int, max_pass: int = 16, checkpoints: tuple[int, ...] = (),
                progressive: bool = True) -> Iterator[int]:
    """Sizes of the sample passes, lazily; they sum to ``spp``.

    Progressive: 1, 1, 2, 4, … up to ``max_pass``, then ``max_pass`` (every power of two is a boundary).
    Otherwise ``max_pass`` each (fewer, larger units: the splat is cheapest per sample there). Every value
    in ``checkpoints`` (≤ spp) is also made a pass boundary. Nothing is built ahead: a sample count of
    2^63 costs nothing until its passes are rendered (a ``stop`` or ``time_limit`` ends it).
    """
    stops = iter(sorted({c for c in checkpoints if 0 < c < spp}))
    nxt = next(stops, None)
    done = 0
    while done < spp:
        size = (1 if done == 0 else min(done, max_pass)) if progressive else max_pass
        size = min(size, spp - done)
        while nxt is not None and nxt <= done:
            nxt = next(stops, None)
        if nxt is not None:
            size = min(size, nxt - done)
        yield size
        done += size


def pass_schedule(spp: int, max_pass: int = 16, checkpoints: tuple[int, ...] = (),
                  progressive: bool = True) -> list[int]:
    """:func:`iter_passes` as a list (for small sample counts)."""
    return list(iter_passes(spp, max_pass, checkpoints, progressive))


def tiles_for(width: int, height: int, pass_spp: int) -> list[tuple[int, int, int, int]]:
    """Square tiles (x0, y0, w, h) sized so each unit holds about :data:`UNIT_SAMPLES` samples."""
    side = int(np.clip(math.sqrt(UNIT_SAMPLES / pass_spp), 16, 256)) // 8 * 8
    return [(x, y, min(side, width - x), min(side, height - y))
            for y in range(0, height, side) for x in range(0, width, side)]


def render_memory(width: int, height: int, filt, workers: int, max_tile: tuple[int, int]) -> int:
    """Estimated bytes a render needs besides the scene: the image film and the pass film (4 float64
    planes with the filter's border), the final image and its temporaries, the shared result slots of
    the workers and :data:`~brdflab.limits.WORKER_BYTES` per worker."""
    b = int(np.ceil(filt.radius)) + 1
    films = 2 * 4 * 8 * (width + 2 * b) * (height + 2 * b)
    image = (3 * 4 + 3 * 8 * 2) * width * height
    slots = IN_FLIGHT * workers * TASK_UNITS * 4 * 8 * (max_tile[0] + 2 * b) * (max_tile[1] + 2 * b)
    return films + image + (slots + workers * WORKER_BYTES if workers > 1 else 0)


def max_tile_size(width: int, height: int) -> tuple[int, int]:
    """(w, h) of the largest tile of any pass: that of a 1-spp pass (tiles shrink as passes grow)."""
    first = tiles_for(width, height, 1)[0]
    return first[2], first[3]


@dataclass
class RenderStats:
    """What a render did and how long it took."""

    spp: int = 0
    seconds: float = 0.0
    samples: int = 0
    rays: int = 0
    ray_seconds: float = 0.0
    dropped: int = 0
    workers: int = 1
    checkpoints: list[tuple[int, float]] = field(default_factory=list)
    per_worker: dict = field(default_factory=dict)
    """On a cluster: worker address → :class:`brdflab.cluster.WorkerStats`."""

    @property
    def samples_per_second(self) -> float:
        """Camera samples per wall-clock second."""
        return self.samples / self.seconds if self.seconds > 0 else 0.0

    @property
    def rays_per_second(self) -> float:
        """Ray queries (camera, shadow, BSDF) per wall-clock second."""
        return self.rays / self.seconds if self.seconds > 0 else 0.0

    @property
    def embree_share(self) -> float:
        """Share of worker time spent inside embreex ray queries."""
        busy = self.seconds * self.workers
        return min(1.0, self.ray_seconds / busy) if busy > 0 else 0.0

    def summary(self) -> str:
        """One line: wall time, samples/s, rays/s, share of time in ray queries."""
        s = (f"{self.spp} spp in {self.seconds:.2f} s: {self.samples_per_second / 1e6:.2f} M samples/s, "
             f"{self.rays_per_second / 1e6:.2f} M rays/s, {100 * self.embree_share:.0f}% of time in ray "
             f"queries ({self.workers} worker{'s' if self.workers > 1 else ''})")
        if self.dropped:
            s += f"; {self.dropped} non-finite or negative samples dropped"
        return s


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
    jitter = rng.random((2, n))
    sx = jitter[0]
    sx += px
    sx += x0
    sy = jitter[1]
    sy += py
    sy += y0
    o, d, tmax = cam.generate_rays(sx, sy)
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
PR_SET_PDEATHSIG = 1


def _die_with_parent() -> None:
    """Ask Linux to SIGKILL this process when its parent dies (``prctl(PR_SET_PDEATHSIG)``)."""
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    except (OSError, AttributeError):
        pass


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
    _die_with_parent()
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

    def finish(self, image: np.ndarray, stats: RenderStats) -> None:
        """Called with the image and stats when the render ends (nothing to do here)."""


def render(
    scene,
    spp: int | None = None,
    seed: int | None = None,
    workers: int | None = None,
    progress: Callable[[float, RenderStats], None] | None = None,
    on_pass: Callable[[int, float, Film], None] | None = None,
    stop: threading.Event | None = None,
    time_limit: float | None = None,
    checkpoints: tuple[int, ...] = (),
    progressive: bool | None = None,
    cluster=None,
) -> tuple[np.ndarray, RenderStats]:
    """Render ``scene``.

    Parameters
    ----------
    scene
        A loaded :class:`brdflab.scene.loader.Scene`.
    spp, seed
        Samples per pixel and seed (default: the scene's sampler).
    workers
        Worker processes (default: the number of CPU cores; see the module docstring).
    progress
        Called after every unit with (fraction done, running stats).
    on_pass
        Called at every pass boundary with (spp so far, elapsed seconds, the film).
    stop
        When set (e.g. by Ctrl-C), rendering stops within one work unit; the image holds the completed
        passes only.
    time_limit
        Stop at the last pass boundary that fits in this many seconds.
    checkpoints
        Sample counts that must be pass boundaries (so ``on_pass`` sees them).
    progressive
        Passes of 1, 1, 2, 4, … samples (a checkpoint at every power of two). Default: only when
        ``on_pass``, ``checkpoints`` or ``time_limit`` ask for intermediate images; otherwise passes of
        :data:`BATCH_PASS` samples per pixel. The pass sizes are part of the random-number layout: an image is
        reproducible for the same scene, seed, sample count and schedule.
    cluster
        Run the units on a Dask cluster instead of local workers: an address (``"tcp://host:8786"``,
        ``"local:4"``) or a :class:`brdflab.cluster.Cluster`. The image is bit-identical to a local render.
        A lost scheduler raises :class:`brdflab.cluster.ClusterError` carrying the completed passes.

    Returns
    -------
    (image, stats)
        The (H, W, 3) float32 image and the :class:`RenderStats`; ``stats.spp`` is the number of samples
        per pixel actually taken (smaller than requested when stopped early).
    """
    tune_allocator()
    spp = scene.spp if spp is None else spp
    seed = scene.seed if seed is None else seed
    if not 0 <= seed < 2**64:
        raise BrdflabError(f"the seed must be an integer in [0, 2^64), got {clean(seed, 30)}")
    spp = check_spp(spp)
    if cluster is None and workers is not None and not 1 <= workers <= MAX_WORKERS:
        raise BrdflabError(f"workers must be between 1 and {MAX_WORKERS}, got {workers}")
    executor = ForkPool(workers) if cluster is None else _cluster_executor(cluster)
    workers = executor.workers
    cam = scene.camera
    if progressive is None:
        progressive = on_pass is not None or bool(checkpoints) or time_limit is not None
    sizes = iter_passes(spp, max_pass=16 if progressive else BATCH_PASS, checkpoints=checkpoints,
                        progressive=progressive)
    pass_sizes: list[int] = []

    def size_of(p: int) -> int:
        """Size of pass ``p`` (0 past the last), drawn from the lazy schedule as needed."""
        while len(pass_sizes) <= p:
            s = next(sizes, None)
            if s is None:
                return 0
            pass_sizes.append(s)
        return pass_sizes[p]

    local = workers if cluster is None else 1  # a cluster's workers use their own machines' memory
    check_memory(render_memory(cam.width, cam.height, scene.filter, local, max_tile_size(cam.width, cam.height)),
                 f"a {cam.width}×{cam.height} render with {local} worker{'s' if local > 1 else ''}")
    check_work(spp * cam.width * cam.height, workers, f"a {cam.width}×{cam.height} render at {spp:,} spp with "
               f"{workers} worker{'s' if workers > 1 else ''}", time_limit)
    film = Film(cam.width, cam.height, scene.filter)

    def unit_stream() -> Iterator[tuple]:
        p = 0
        while size := size_of(p):
            tiles = tiles_for(cam.width, cam.height, size)
            for t, tile in enumerate(tiles):
                yield p, t, tile, size, t == len(tiles) - 1
            p += 1

    total = spp * cam.width * cam.height
    stats = RenderStats(workers=workers)
    geo = scene.geometry
    geo.stats.reset()
    t0 = time.perf_counter()
    done_spp = 0
    done_samples = 0
    halt = threading.Event()
    worker_rays, worker_seconds = 0, 0.0
    pass_film = Film(cam.width, cam.height, scene.filter)
    # The executor consumes the lazy unit stream a few tasks ahead; the loop below walks a copy of it
    # (itertools.tee keeps only the units in between) to know which unit each result belongs to.
    ahead, behind = itertools.tee(unit_stream())
    results = executor.results(scene, (u[:4] for u in ahead), seed, halt)
    for (tile_film, n, dropped, rays, secs), unit in zip(results, behind, strict=False):
        if stop is not None and stop.is_set():
            halt.set()  # keep only the completed passes; running units finish and are discarded
            break
        pass_film.add(tile_film)
        done_samples += n
        worker_rays += rays
        worker_seconds += secs
        stats.dropped += dropped
        stats.seconds = time.perf_counter() - t0
        stats.samples = done_samples
        stats.rays, stats.ray_seconds = geo.stats.rays + worker_rays, geo.stats.seconds + worker_seconds
        p, _, _, size, last = unit
        ended = False
        if last:
            film.data += pass_film.data
            pass_film.data[:] = 0.0
            done_spp += size
            stats.spp = done_spp
            stats.checkpoints.append((done_spp, stats.seconds))
            if on_pass is not None:
                on_pass(done_spp, stats.seconds, film)
            nxt = size_of(p + 1)
            over_time = (time_limit is not None and nxt
                         and stats.seconds + stats.seconds / done_spp * nxt > time_limit)
            if (stop is not None and stop.is_set()) or over_time:
                halt.set()
                ended = True
        if progress is not None:  # after the pass bookkeeping: the line shows the passes completed so far
            progress(done_samples / total, stats)
        if ended:
            break
    results.close()  # ends the workers now (queued units are cancelled)
    stats.seconds = time.perf_counter() - t0
    stats.rays, stats.ray_seconds = geo.stats.rays + worker_rays, geo.stats.seconds + worker_seconds
    stats.samples = done_spp * cam.width * cam.height
    image = film.image()
    executor.finish(image, stats)
    return image, stats


def _cluster_executor(cluster):
    """A :class:`brdflab.cluster.Cluster` for an address (closed when the render ends) or as given."""
    from brdflab.cluster import Cluster

    return cluster if isinstance(cluster, Cluster) else Cluster(cluster, close_after_render=True)


class _CallableModule(types.ModuleType):
    """``brdflab.render`` is both this module and the public function :func:`brdflab.api.render`: importing a
    submodule binds its name in the package, so the module itself forwards calls to the API function."""

    def __call__(self, *args, **kwargs):
        from brdflab.api import render as api_render

        return api_render(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule
