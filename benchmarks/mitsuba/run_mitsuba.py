"""Render one Mitsuba 3 scene and print its timing as one JSON line (run with the Mitsuba venv's python).

Usage::

    python run_mitsuba.py SCENE.xml --spp N --variant scalar_rgb [--exr OUT.exr]

The scene is loaded and rendered once at 1 spp untimed (for ``llvm_*`` variants this compiles the
kernels, reported as ``cold_seconds``); then ``mi.render`` at ``--spp`` is timed until the image is in a
NumPy array. samples/s = width · height · spp / render seconds, as brdflab reports it.
"""

from __future__ import annotations

import argparse
import json
import time

import mitsuba as mi
import numpy as np


def main() -> None:
    """Render and print the JSON record."""
    ap = argparse.ArgumentParser()
    ap.add_argument("scene")
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--variant", default="scalar_rgb")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--exr", default=None)
    a = ap.parse_args()
    mi.set_variant(a.variant)
    t0 = time.perf_counter()
    scene = mi.load_file(a.scene)
    load_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    np.asarray(mi.render(scene, spp=1, seed=a.seed + 1))
    cold_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    img = np.asarray(mi.render(scene, spp=a.spp, seed=a.seed))
    seconds = time.perf_counter() - t0
    h, w = img.shape[:2]
    if a.exr:
        mi.Bitmap(img[..., :3]).write(a.exr)
    print(json.dumps({"variant": a.variant, "spp": a.spp, "width": w, "height": h, "seconds": seconds,
                      "samples_per_s": w * h * a.spp / seconds, "load_seconds": load_s, "cold_seconds": cold_s,
                      "mean": float(img[..., :3].mean()), "mitsuba": mi.__version__}))


if __name__ == "__main__":
    main()
