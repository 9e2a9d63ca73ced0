"""What runs on a Dask worker: the scene shipped once per worker process (pickled without its Embree BVH, rebuilt and
cached by SHA-256, or loaded from a shared path and fingerprinted), users' BSDF classes sent along, the code digest
a worker must share with the client, and the render task itself (a batch of (pass, tile) units, the same function
the local fork pool runs). The client side is :mod:`brdflab.cluster`.
"""

from __future__ import annotations

import functools
import hashlib
import io
import os
import pickle
import signal
import threading
import time
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from brdflab.errors import BrdflabError

#: Scenes kept per worker process (by content hash).
SCENE_CACHE = 4


@functools.lru_cache(maxsize=1)
def code_digest() -> str:
    """SHA-256 of brdflab's Python sources (workers must run the same renderer as the client)."""
    root = Path(__file__).resolve().parent
    h = hashlib.sha256()
    for p in sorted(root.rglob("*.py")):
        h.update(str(p.relative_to(root)).encode())
        h.update(p.read_bytes())
    return h.hexdigest()


# -- scenes on workers -----------------------------------------------------------------------------------
def _rebuild_geometry(meshes, state):
    """Unpickle a Geometry: rebuilt from its meshes (same constructor, same arrays), or from its state."""
    from brdflab.scene.geometry import Geometry

    if meshes is not None:
        return Geometry(meshes)
    g = Geometry.__new__(Geometry)
    g.__dict__.update(state)
    _attach_embree(g)
    return g


def _attach_embree(g) -> None:
    """Build the Embree scene of a Geometry whose arrays are set (as its constructor does)."""
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh

    from brdflab.scene.geometry import RayStats

    g.stats = RayStats()
    g._scene = rtcs.EmbreeScene()
    if len(g.faces):
        TriangleMesh(g._scene, g.positions.astype(np.float32), g.faces.astype(np.int32))
        g._scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32), query="OCCLUDED")


def scene_bytes(scene) -> bytes:
    """The scene pickled for shipping: no Embree handles or ray counters; the triangle tables are
    rebuilt from the meshes on the worker when the geometry is exactly their concatenation."""
    import cloudpickle

    from brdflab.scene.geometry import Geometry, RayStats

    _ship_plugin_modules()
    meshes = [m.mesh for m in getattr(scene, "meshes", [])]

    class Pickler(cloudpickle.Pickler):
        def reducer_override(self, obj):
            if isinstance(obj, Geometry):
                same = (len(meshes) and len(obj.positions) == sum(len(m.positions) for m in meshes)
                        and np.array_equal(obj.positions, np.concatenate([m.positions for m in meshes])))
                if same:
                    return _rebuild_geometry, (meshes, None)
                state = {k: v for k, v in obj.__dict__.items() if k not in ("_scene", "stats")}
                return _rebuild_geometry, (None, state)
            if isinstance(obj, RayStats):
                return RayStats, ()
            return super().reducer_override(obj)

    buf = io.BytesIO()
    Pickler(buf, protocol=5).dump(scene)
    return buf.getvalue()


def _ship_plugin_modules() -> None:
    """Plugins loaded from a .py file live in a module no worker can import: pickle their classes by value."""
    import sys

    import cloudpickle

    for name, module in list(sys.modules.items()):
        if name.startswith("brdflab_plugin_") and module is not None:
            cloudpickle.register_pickle_by_value(module)


def user_bsdf_classes() -> bytes:
    """The user BSDF classes registered in this process, pickled for jobs that may run on cluster workers
    (see :func:`register_user_bsdfs`); classes from plugin files travel by value."""
    import cloudpickle

    from brdflab import plugins

    _ship_plugin_modules()
    return cloudpickle.dumps([plugins.bsdf_class(n) for n in plugins.bsdf_names() if not plugins.is_builtin(n)])


def register_user_bsdfs(blob: bytes) -> None:
    """In a job: register the client's user BSDF classes (from :func:`user_bsdf_classes`) not yet known here."""
    from brdflab import plugins

    for cls in pickle.loads(blob):
        known = cls.type_name in plugins.bsdf_names()
        if not known or plugins.bsdf_class(cls.type_name) is not cls:
            plugins.register_bsdf(cls, origin="a plugin of the cluster client")


def _path_fingerprint(scene) -> str:
    """What a worker must match in ``path`` mode: the scene file as loaded, the image size and the triangle
    geometry (image and texture files are not compared)."""
    h = hashlib.sha256(f"{scene.source_digest} {scene.camera.width} {scene.camera.height}".encode())
    h.update(np.ascontiguousarray(scene.geometry.positions, np.float64).tobytes())
    h.update(np.ascontiguousarray(scene.geometry.faces, np.int64).tobytes())
    return h.hexdigest()


@dataclass(frozen=True)
class SceneRef:
    """How a worker finds the scene of a task (the bytes themselves travel as a scattered future)."""

    digest: str
    code: str
    path: str | None = None
    """Path mode: the scene file, its integrator and the client's emitter selection."""
    integrator: str | None = None
    size: tuple[int, int] | None = None
    emitter_pmf: np.ndarray | None = None
    emitter_cdf: np.ndarray | None = None


_SCENES: OrderedDict = OrderedDict()


_SCENES_LOCK = threading.Lock()


def _worker_scene(ref: SceneRef, blob: bytes | None):
    """The task's scene in this worker process: built once per content hash, then cached."""
    with _SCENES_LOCK:
        scene = _SCENES.get(ref.digest)
        if scene is not None:
            _SCENES.move_to_end(ref.digest)
            return scene
        where = _worker_name()
        if ref.code != code_digest():
            raise BrdflabError(f"worker {where} runs a different brdflab than the client (source digest "
                               f"{code_digest()[:12]} ≠ {ref.code[:12]}); install the same version on every worker")
        if blob is not None:
            scene = pickle.loads(blob)
        else:
            from brdflab.scene.loader import load_scene

            try:
                scene = load_scene(ref.path, ref.integrator, width=ref.size[0], height=ref.size[1])
            except BrdflabError as exc:
                raise BrdflabError(f"worker {where}: {exc}") from None
            scene.emitter_pmf, scene.emitter_cdf = ref.emitter_pmf, ref.emitter_cdf
            if _path_fingerprint(scene) != ref.digest:
                raise BrdflabError(f"worker {where}: the scene at {ref.path} differs from the client's (another "
                                   "file on this machine?); use scene transfer 'ship'")
        _SCENES[ref.digest] = scene
        while len(_SCENES) > SCENE_CACHE:
            _SCENES.popitem(last=False)
        return scene


def _worker_name() -> str:
    try:
        from distributed import get_worker

        return get_worker().address
    except (ImportError, ValueError):
        return f"pid {os.getpid()}"


def _render_task(ref: SceneRef, blob: bytes | None, batch: list[tuple], seed: int, engine: str = "numba"):
    """A Dask task: render ``batch`` units with the client's ``engine`` (:mod:`brdflab.kernels`); return
    (per-unit (samples, dropped, rays, Embree s), the tile films concatenated, the worker's address, busy
    seconds)."""
    from brdflab.kernels import use_engine

    with use_engine(engine):
        return _render_batch(ref, blob, batch, seed)


def _render_batch(ref: SceneRef, blob: bytes | None, batch: list[tuple], seed: int):
    from brdflab.alloc import tune_allocator
    from brdflab.workers import _render_unit

    t0 = time.perf_counter()
    tune_allocator()
    scene = _worker_scene(ref, blob)
    st = scene.geometry.stats
    meta, films = [], []
    for u in batch:
        st.reset()
        film, n, dropped = _render_unit(scene, *u, seed)
        films.append(film.data.ravel())
        meta.append((n, dropped, st.rays, st.seconds))
    return meta, np.concatenate(films), _worker_name(), time.perf_counter() - t0


@dataclass
class WorkerStats:
    """What one worker did in a render."""

    tasks: int = 0
    samples: int = 0
    busy_seconds: float = 0.0
    ray_seconds: float = 0.0

    @property
    def embree_share(self) -> float:
        """Share of the worker's task time spent inside embreex ray queries."""
        return min(1.0, self.ray_seconds / self.busy_seconds) if self.busy_seconds > 0 else 0.0


def _ignore_sigint() -> None:
    """In a LocalCluster worker: leave Ctrl-C (sent to the whole terminal process group) to brdflab."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)


def _ignore_sigint_plugin():
    """A worker plugin applying :func:`_ignore_sigint` to every worker, also to those restarted later."""
    from distributed.diagnostics.plugin import WorkerPlugin

    class IgnoreSigint(WorkerPlugin):
        name = "brdflab-ignore-sigint"
        idempotent = True

        def setup(self, worker) -> None:
            _ignore_sigint()

    return IgnoreSigint()
