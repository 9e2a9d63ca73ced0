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
effect within about one task (2 units of 65 k samples, ~0.1 s on the bench scenes).

Units hold about :data:`UNIT_SAMPLES` (65 536) camera samples; a 64-spp pass has tiles of 32 × 32 pixels.
Every unit pays fixed costs: the Python calls between its kernels (~150), and the scene's tables (light
triangles, BVH nodes, triangle records) reloaded into the cache after the unit's sample columns pushed them
out (the light-sample kernel takes 1.0 ms on 16 k points with the tables in cache, 1.8 ms without; this
machine's cache keeps about 2–4 MiB). Fewer, larger units won on every scene measured (2026-12-02, one
worker, 64 spp, alternating, 3–5 rounds, 16 × 16 against 32 × 32 pixel tiles): compiled engine veach_mats
1.05×, table_ems 1.06×, cbox_conductors_ems 1.07×, veach_mis 1.16×; NumPy engine veach_mis 1.07×, table_ems
1.09×. (With the NumPy engine only, on a machine with 2 MiB of L2 per core, 16 k had been best: 65 k 1.71 M
samples/s, 16 k 1.97 M.)

Pass sizes are 1, 1, 2, 4, … (doubling up to ``max_pass``), then ``max_pass`` each, so every power of
two up to the final count is a pass boundary: a progressive run of 256 spp yields the 1, 2, 4, …, 128
spp images as checkpoints (:func:`render` ``on_pass``), each with its elapsed time.
"""

from __future__ import annotations

import itertools
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

import numpy as np

from brdflab.alloc import tune_allocator
from brdflab.errors import BrdflabError, clean
from brdflab.film import Film
from brdflab.kernels import preload
from brdflab.limits import WORKER_BYTES, check_memory, check_spp, check_work
from brdflab.workers import (  # noqa: F401 (re-exported: the module's former contents)
    _ACTIVE_POOLS,
    _FORK_LOCK,
    _FORK_SCENE,
    _FORK_SLOTS,
    _PARENT_PID,
    FORK_WORKERS,
    IN_FLIGHT,
    TASK_UNITS,
    UNIT_SAMPLES,
    ForkPool,
    _executor,
    _pixel_offsets,
    _process_units,
    _render_unit,
    _render_unit_inner,
    _results,
    _worker_init,
    kill_workers,
    max_tile_size,
    tiles_for,
)

#: Samples per pixel of a pass when no intermediate images are asked for: a 16 k-sample unit then covers
#: 16 × 16 pixels, whose tile film (22 × 22 with the filter's border) is a third of a 16-spp unit's (38 × 38):
#: less to splat, transfer and merge per sample (Cornell box, 2 workers, 64 spp: 4.94 → 4.75 s).
BATCH_PASS = 64
#: Most worker processes accepted (each costs memory, see :func:`render_memory`).
MAX_WORKERS = 256
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


def render_memory(width: int, height: int, filt, workers: int, max_tile: tuple[int, int]) -> int:
    """Estimated bytes a render needs besides the scene: the image film and the pass film (4 float64
    planes with the filter's border), the final image and its temporaries, the shared result slots of
    the workers and :data:`~brdflab.limits.WORKER_BYTES` per worker."""
    b = int(np.ceil(filt.radius)) + 1
    films = 2 * 4 * 8 * (width + 2 * b) * (height + 2 * b)
    image = (3 * 4 + 3 * 8 * 2) * width * height
    slots = IN_FLIGHT * workers * TASK_UNITS * 4 * 8 * (max_tile[0] + 2 * b) * (max_tile[1] + 2 * b)
    return films + image + (slots + workers * WORKER_BYTES if workers > 1 else 0)


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
    preload()  # the compiled kernels, before the clock starts and before the fork pool forks (workers inherit them)
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
                         and stats.seconds + _seconds_per_spp(stats.checkpoints) * nxt > time_limit)
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


def _seconds_per_spp(checkpoints: list[tuple[int, float]]) -> float:
    """Seconds per sample per pixel at the rate of the passes after the first (the first holds one-off costs:
    workers starting, caches warming), from (spp, seconds) at each pass boundary; the first pass's own rate
    while it is the only one."""
    (s0, t0), (s1, t1) = checkpoints[0], checkpoints[-1]
    return (t1 - t0) / (s1 - s0) if s1 > s0 else t0 / max(s0, 1)


def _cluster_executor(cluster):
    """A :class:`brdflab.cluster.Cluster` for an address (closed when the render ends) or as given."""
    from brdflab.cluster import Cluster

    return cluster if isinstance(cluster, Cluster) else Cluster(cluster, close_after_render=True)


def render_image(scene, spp: int | None = None, seed: int | None = None, workers: int | None = None, *,
                 return_stats: bool = False, cluster=None, time_limit: float | None = None):
    """:func:`render` as the public API gives it (``bl.render``): the image as float32, and the stats only
    when asked for (documented in :func:`brdflab.api.render`)."""
    if time_limit is not None and not (isinstance(time_limit, int | float) and time_limit > 0):
        raise BrdflabError(f"time_limit must be a number of seconds > 0, got {clean(time_limit, 30)}")
    image, stats = render(scene, spp=spp, seed=seed, workers=workers, cluster=cluster, time_limit=time_limit)
    image = np.asarray(image, dtype=np.float32)
    return (image, stats) if return_stats else image
