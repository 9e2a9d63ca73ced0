"""The compiled engine stage by stage: each kernel against the NumPy code it mirrors, on one render unit.

Usage (brdflab's environment)::

    python benchmarks/kernel_stages.py [SCENE.xml …] [--rounds 60]

One 16 k-sample unit in the middle of each scene's image is traced once; then the stages that have a compiled
twin (:mod:`brdflab.kernels`) are timed with both engines, alternately, by thread CPU time (robust on a shared
machine), median of ``--rounds``: the shading points of the camera hits (``trace_camera`` without its Embree
call), one light sample per point, the BSDF ``eval`` and ``eval_pdf`` at those directions, and the splat of
the unit's samples into a 32 × 32 tile film; and two whole integrator steps with their ray queries answered
in advance (nothing occluded, the BSDF rays' hits traced once): the light term (``light_term``: light
sample, BSDF eval, contributions and shadow rays) and ``direct_mats``' BSDF rays (sample, rays, emission
found). Embree's share is what neither engine changes.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from brdflab import kernels  # noqa: E402
from brdflab.alloc import tune_allocator  # noqa: E402
from brdflab.api import load_scene  # noqa: E402
from brdflab.film import Film  # noqa: E402
from brdflab.integrator import direct_mats  # noqa: E402
from brdflab.integrator.common import (  # noqa: E402
    eval_bsdfs,
    light_dims,
    light_term,
    point_uniforms,
    sample_lights,
    trace_camera,
)


def stages(path: Path) -> dict:
    """The stage callables of one unit of the scene ``path`` (Embree traced once, beforehand)."""
    scene = load_scene(path)
    cam = scene.camera
    rng = np.random.default_rng(0)
    n = 16384
    sx = rng.random(n) * 16 + cam.width // 2
    sy = rng.random(n) * 16 + cam.height // 2
    o, d, tmax = cam.generate_rays(sx, sy)
    rh = scene.geometry.trace(o, d, tmax)
    g = scene.geometry
    _, sp = trace_camera(scene, o, d, tmax)
    u = point_uniforms(rng, n, sp, light_dims(scene))
    ub = point_uniforms(rng, n, sp, 3)
    traced, real_trace = [], g.trace
    g.trace = lambda *a: traced.append(real_trace(*a)) or traced[-1]
    direct_mats.bsdf_rays(scene, sp, ub)
    # Time only what happens around the Embree calls: their answers are given (camera rays come with a tmax,
    # the BSDF rays without).
    g.trace = lambda o_, d_, t_=None: rh if t_ is not None else traced[0]
    g.occluded_f32 = lambda o_, d_, t_: np.zeros(len(o_), bool)
    wo = sp.local(sample_lights(scene, sp, u).wi)
    values = rng.random((n, 3))

    def splat():
        Film(cam.width, cam.height, scene.filter, x0=cam.width // 2 - 8, y0=cam.height // 2 - 8, w=32,
             h=32).splat(sx, sy, values)

    return {"shading points": lambda: trace_camera(scene, o, d, tmax),
            "light sample": lambda: sample_lights(scene, sp, u),
            "BSDF eval": lambda: eval_bsdfs(scene, sp, wo), "BSDF eval_pdf": lambda: eval_bsdfs(scene, sp, wo, True),
            "splat": splat, "light term": lambda: light_term(scene, sp, u),
            "BSDF rays": lambda: direct_mats.bsdf_rays(scene, sp, ub)}


def main(argv: list[str] | None = None) -> int:
    """Print one line per (scene, stage): NumPy and compiled milliseconds and their ratio."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenes", nargs="*", type=Path, default=[ROOT / "scenes/cbox/cbox_spheres.xml"])
    ap.add_argument("--rounds", type=int, default=60)
    a = ap.parse_args(argv)
    tune_allocator()
    print("| scene | stage | NumPy | compiled | ratio |\n|---|---|---|---|---|")
    for path in a.scenes:
        for name, fn in stages(path).items():
            t: dict[str, list[float]] = {"numpy": [], "numba": []}
            for r in range(a.rounds):
                for eng in ("numpy", "numba") if r % 2 else ("numba", "numpy"):
                    with kernels.use_engine(eng):
                        t0 = time.thread_time()
                        fn()
                        t[eng].append(time.thread_time() - t0)
            ref, fast = (1e3 * statistics.median(t[e]) for e in ("numpy", "numba"))
            print(f"| {path.stem} | {name} | {ref:.3f} ms | {fast:.3f} ms | {ref / fast:.2f}× |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
