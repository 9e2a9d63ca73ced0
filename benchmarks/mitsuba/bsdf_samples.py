"""Write Mitsuba 3's BSDF samples in brdflab's ``chi2 --samples`` format (held-out checks of ``--against``).

Run in the Mitsuba venv (``pip install mitsuba``), not in brdflab's::

    python benchmarks/mitsuba/bsdf_samples.py OUT.txt --alpha 0.1 [--visible 0|1] [--n 20000] [--bsdf roughplastic]

One line per call of ``BSDF::sample``: ``wi wo pdf`` in the local frame (z = normal), failed samples as
``wo = 0 0 0`` and pdf 0, for θ_i ∈ {0, 30, 60, 85}°. The weights are not written: Mitsuba's conductor
(``material="none"``, exact Smith G) and plastic differ from brdflab's ``roughconductor`` (Schlick Fresnel,
rational G1) and ``roughsubstrate``, so only the sampler (directions and pdf) is comparable. The files are
not committed: generate them where needed.
"""

from __future__ import annotations

import argparse

import mitsuba as mi
import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out")
    ap.add_argument("--alpha", type=float, required=True)
    ap.add_argument("--visible", type=int, default=1, help="sample_visible (1: VNDF, Mitsuba's default)")
    ap.add_argument("--n", type=int, default=20_000, help="samples per incident angle")
    ap.add_argument("--bsdf", default="roughconductor", choices=["roughconductor", "roughplastic"])
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    mi.set_variant("scalar_rgb")
    spec = {"type": a.bsdf, "distribution": "beckmann", "alpha": a.alpha, "sample_visible": bool(a.visible)}
    if a.bsdf == "roughconductor":
        spec["material"] = "none"
    bsdf = mi.load_dict(spec)
    ctx = mi.BSDFContext()
    rng = np.random.default_rng(a.seed)
    rows = []
    for theta in (0.0, 30.0, 60.0, 85.0):
        t = np.radians(theta)
        wi = np.array([np.sin(t), 0.0, np.cos(t)])
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(*wi)
        si.n = mi.Normal3f(0, 0, 1)
        si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
        u = rng.random((a.n, 3))
        for k in range(a.n):
            bs, w = bsdf.sample(ctx, si, float(u[k, 2]), mi.Point2f(float(u[k, 0]), float(u[k, 1])))
            wo = np.array([bs.wo.x, bs.wo.y, bs.wo.z], dtype=float)
            pdf = float(bs.pdf)
            if not (pdf > 0 and np.isfinite(pdf)) or max(w) <= 0:
                wo, pdf = np.zeros(3), 0.0
            rows.append([*wi, *wo, pdf])
    np.savetxt(a.out, np.array(rows), fmt="%.9g", header="wi_x wi_y wi_z wo_x wo_y wo_z pdf  (Mitsuba " +
               mi.__version__ + f" {a.bsdf} beckmann alpha={a.alpha} sample_visible={bool(a.visible)})")


if __name__ == "__main__":
    main()
