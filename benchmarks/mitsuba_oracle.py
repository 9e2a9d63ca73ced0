"""brdflab's ``roughconductor`` against Mitsuba 3's: f·cos θ_o and pdf on random direction pairs (issue 45).

Usage (brdflab's venv active; Mitsuba 3 in ``benchmarks/.venv-mitsuba``, see ``benchmarks/mitsuba/README.md``,
or ``$MITSUBA_PYTHON`` naming a Python that imports ``mitsuba``)::

    python benchmarks/mitsuba_oracle.py [--n 100000] [--fixture tests/data/mitsuba_roughconductor.json]

For every configuration of :data:`CONFIGS` (GGX and Beckmann, isotropic and anisotropic α, visible normals or
not, explicit η/k) it draws ``n`` pairs (ω_i, ω_o) in the local frame — half with both directions uniform on the
upper hemisphere, half with ω_o sampled by brdflab's sampler (the lobe, where a render looks) — and evaluates
them in a child process running Mitsuba's ``scalar_rgb`` variant (``BSDF.eval``, which returns f·cos θ_o, and
``BSDF.pdf``; local directions, so α_u lies along x in both). It prints the median and 99th-percentile relative
error |brdflab − Mitsuba| / |Mitsuba| over the pairs where both are nonzero and Mitsuba's value is a normal
float32 (> 1e-30), and how many values only one of them calls zero (the other above 1e-18: Mitsuba sets D to 0
where D·cos θ_h < 1e-20). ``--fixture`` keeps 24 lobe pairs per
configuration with Mitsuba's values (numbers, not code) for ``tests/test_mitsuba_fixture.py``.

Mitsuba's scalar variants compute in float32: agreement is bounded by its rounding (≈ 1e-7 relative per
operation; more where D or G1 is steep). Mitsuba's Beckmann G1 is the same rational approximation as the
course's; its visible-normal pdf uses that G1 too, while brdflab's uses the exact (erf) G1 for which the
sampler's density is exact, so the Beckmann visible-normal pdfs differ by the approximation (≤ 0.35 %).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
CU = dict(eta=(0.2, 0.92, 1.1), k=(3.9, 2.45, 2.14))
AL = dict(eta=(1.66, 0.88, 0.52), k=(9.22, 6.27, 4.84))
#: name → brdflab keyword arguments of RoughConductor (Mitsuba's dictionary is derived from them).
CONFIGS: dict[str, dict] = {
    "ggx iso α=0.2 visible Cu": dict(distribution="ggx", alpha_u=0.2, alpha_v=0.2, sample_visible=True, **CU),
    "ggx aniso 0.2/0.45 visible Cu": dict(distribution="ggx", alpha_u=0.2, alpha_v=0.45, sample_visible=True, **CU),
    "ggx aniso 0.6/0.05 visible Al": dict(distribution="ggx", alpha_u=0.6, alpha_v=0.05, sample_visible=True, **AL),
    "ggx aniso 0.1/0.3 D·cos Cu": dict(distribution="ggx", alpha_u=0.1, alpha_v=0.3, sample_visible=False, **CU),
    "beckmann iso α=0.3 D·cos Cu": dict(distribution="beckmann", alpha_u=0.3, alpha_v=0.3, sample_visible=False, **CU),
    "beckmann aniso 0.1/0.4 D·cos Al": dict(distribution="beckmann", alpha_u=0.1, alpha_v=0.4, sample_visible=False,
                                            **AL),
    "beckmann aniso 0.3/0.15 visible Cu": dict(distribution="beckmann", alpha_u=0.3, alpha_v=0.15,
                                               sample_visible=True, **CU),
}


def mitsuba_dict(cfg: dict) -> dict:
    """Mitsuba 3's ``roughconductor`` with the same parameters."""
    return {"type": "roughconductor", "distribution": cfg["distribution"], "alpha_u": cfg["alpha_u"],
            "alpha_v": cfg["alpha_v"], "sample_visible": cfg["sample_visible"],
            "eta": {"type": "rgb", "value": list(cfg["eta"])}, "k": {"type": "rgb", "value": list(cfg["k"])}}


def mitsuba_side(inp: str, out: str) -> None:
    """In the Mitsuba venv: f·cos θ_o (N, 3) and pdf (N,) of every configuration's pairs."""
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    data = np.load(inp)
    cfgs = json.loads(str(data["configs"]))
    ctx = mi.BSDFContext()
    res = {"version": np.array(mi.__version__)}
    for k, cfg in enumerate(cfgs):
        bsdf = mi.load_dict(mitsuba_dict(cfg))
        wi, wo = data[f"wi{k}"], data[f"wo{k}"]
        f = np.zeros((len(wi), 3))
        p = np.zeros(len(wi))
        si = mi.SurfaceInteraction3f()
        for i in range(len(wi)):
            si.wi = mi.Vector3f(*wi[i])
            w = mi.Vector3f(*wo[i])
            f[i] = list(bsdf.eval(ctx, si, w))
            p[i] = bsdf.pdf(ctx, si, w)
        res[f"f{k}"], res[f"p{k}"] = f, p
    np.savez(out, **res)


def pairs(cfg: dict, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Half uniform pairs on the upper hemisphere, half with ω_o from brdflab's sampler."""
    from brdflab import RoughConductor
    from brdflab.math import warps

    wi = warps.square_to_uniform_hemisphere(rng.random((n, 2)))
    wi[:, 2] = np.maximum(wi[:, 2], 1e-3)
    wi /= np.linalg.norm(wi, axis=1)[:, None]
    wo = warps.square_to_uniform_hemisphere(rng.random((n, 2)))
    h = n // 2
    s = RoughConductor(**cfg).sample(wi[h:], rng.random((n - h, 3)))
    ok = (s.pdf > 0) & (s.wo[:, 2] > 0)
    wo[h:] = np.where(ok[:, None], s.wo, wo[h:])
    return wi, wo


def rel_errors(b: np.ndarray, m: np.ndarray) -> tuple[np.ndarray, int]:
    """Relative errors where both are nonzero and Mitsuba's value > 1e-30; the count where only one is zero and
    the other above 1e-18 (Mitsuba sets D to 0 where D·cos θ_h < 1e-20, and its float32 underflows)."""
    both = (np.abs(m) > 1e-30) & (b != 0)
    one = int(np.sum(((m == 0) & (np.abs(b) > 1e-18)) | ((b == 0) & (np.abs(m) > 1e-18))))
    return np.abs(b[both] - m[both]) / np.abs(m[both]), one


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=100_000, help="direction pairs per configuration")
    ap.add_argument("--seed", type=int, default=45)
    ap.add_argument("--fixture", help="write 24 lobe pairs per configuration with Mitsuba's values (JSON)")
    ap.add_argument("--mitsuba", nargs=2, metavar=("IN", "OUT"), help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.mitsuba:
        mitsuba_side(*a.mitsuba)
        return
    from brdflab import RoughConductor

    py = os.environ.get("MITSUBA_PYTHON") or str(ROOT / "benchmarks" / ".venv-mitsuba" / "bin" / "python")
    if not Path(py).exists():
        py = "/work/main/benchmarks/.venv-mitsuba/bin/python"
    rng = np.random.default_rng(a.seed)
    names = list(CONFIGS)
    data = {}
    for k, name in enumerate(names):
        data[f"wi{k}"], data[f"wo{k}"] = pairs(CONFIGS[name], a.n, rng)
    with tempfile.TemporaryDirectory() as tmp:
        inp, out = os.path.join(tmp, "in.npz"), os.path.join(tmp, "out.npz")
        np.savez(inp, configs=np.array(json.dumps([CONFIGS[n] for n in names])), **data)
        subprocess.run([py, __file__, "--mitsuba", inp, out], check=True)
        mres = dict(np.load(out))
    print(f"Mitsuba {mres['version']} scalar_rgb vs brdflab, {a.n:,} pairs per configuration")
    worst_zero = 0.0
    print(f"{'configuration':38s} {'f·cos median':>13s} {'p99':>9s} {'pdf median':>11s} {'p99':>9s} {'zero≠':>6s}")
    fixture = {"mitsuba": str(mres["version"]), "variant": "scalar_rgb", "configs": {}}
    for k, name in enumerate(names):
        m = RoughConductor(**CONFIGS[name])
        wi, wo = data[f"wi{k}"], data[f"wo{k}"]
        f, p = m.eval_pdf(wi, wo)
        fc = f * wo[:, 2:]
        ef, zf = rel_errors(fc.ravel(), mres[f"f{k}"].ravel())
        ep, zp = rel_errors(p, mres[f"p{k}"])
        print(f"{name:38s} {np.median(ef):13.2e} {np.quantile(ef, 0.99):9.2e} {np.median(ep):11.2e} "
              f"{np.quantile(ep, 0.99):9.2e} {zf + zp:6d}")
        for got, ref in ((fc.ravel(), mres[f"f{k}"].ravel()), (p, mres[f"p{k}"])):
            worst_zero = max(worst_zero, float(np.max(np.abs(got[ref == 0]), initial=0.0)))
        h = a.n // 2
        lobe = np.arange(h, h + 24)
        fixture["configs"][name] = {"params": CONFIGS[name], "wi": wi[lobe].tolist(), "wo": wo[lobe].tolist(),
                                    "f_cos": mres[f"f{k}"][lobe].tolist(), "pdf": mres[f"p{k}"][lobe].tolist()}
    print(f"largest brdflab value where Mitsuba returns 0: {worst_zero:.3g} (Mitsuba zeroes D·cos θ_h < 1e-20)")
    if a.fixture:
        Path(a.fixture).write_text(json.dumps(fixture, indent=1) + "\n")
        print(f"fixture: {a.fixture}")


if __name__ == "__main__":
    sys.exit(main())
