"""brdflab's ``roughconductor`` and ``roughdielectric`` against Mitsuba 3's: f·|cos θ_o| and pdf on random direction
pairs (issue 45).

Usage (brdflab's venv active; Mitsuba 3 in ``benchmarks/.venv-mitsuba``, see ``benchmarks/mitsuba/README.md``,
or ``$MITSUBA_PYTHON`` naming a Python that imports ``mitsuba``)::

    python benchmarks/mitsuba_oracle.py [--bsdf roughconductor|roughdielectric] [--n 100000]
        [--fixture tests/data/mitsuba_roughconductor.json]

For every configuration of :data:`CONFIGS` (GGX and Beckmann, isotropic and anisotropic α, visible normals or
not, explicit η/k) it draws ``n`` pairs (ω_i, ω_o) in the local frame — half with both directions uniform on the
upper hemisphere, half with ω_o sampled by brdflab's sampler (the lobe, where a render looks) — and evaluates
them in a child process running Mitsuba's ``scalar_rgb`` variant (``BSDF.eval``, which returns f·cos θ_o, and
``BSDF.pdf``; local directions, so α_u lies along x in both). It prints the median and 99th-percentile relative
error |brdflab − Mitsuba| / |Mitsuba| over the pairs where both are nonzero and Mitsuba's value is a normal
float32 (> 1e-30), and how many values only one of them calls zero (the other above 1e-18: Mitsuba sets D to 0
where D·cos θ_h < 1e-20). ``--fixture`` keeps 24 lobe pairs per
configuration with Mitsuba's values (numbers, not code) for ``tests/test_mitsuba_fixture.py``.

``--bsdf roughdielectric`` (:data:`DIELECTRIC_CONFIGS`, intIOR = 1.5, extIOR = 1): ω_i on the whole sphere (half
of them inside), ω_o half uniform on the sphere, half from brdflab's sampler (reflected and refracted), so the
pairs cover reflection and transmission from both sides. Mitsuba's ``BSDF.eval`` in its default radiance mode
scales the transmitted lobe by (η_i/η_t)² ("solid angle compression", its ``inv_eta²``): that is brdflab's
radiance BTDF (the η_i² of Walter's eq. 21 over the (η_i ω_i·ω_h + η_t ω_o·ω_h)²), so the two compare directly;
Mitsuba's roughdielectric is two-sided as brdflab's (the media exchanged for cos θ_i < 0). Without visible
normals Mitsuba's roughdielectric samples (and so its ``pdf`` is) D cos θ_h of a widened roughness
s·α, s = 1.2 − 0.2 √|cos θ_i| (Walter et al. 2007 §5.3's heuristic), where brdflab samples D cos θ_h of α itself:
its pdf is compared after the factor D(ω_h; s α_u, s α_v)/D(ω_h; α_u, α_v) (:func:`widened_pdf`), which checks
the rest of the density (F or 1 − F, the Jacobians).

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


#: name → brdflab keyword arguments of RoughDielectric (glass: intIOR 1.5 inside, extIOR 1 outside).
DIELECTRIC_CONFIGS: dict[str, dict] = {
    "ggx iso α=0.2 visible": dict(distribution="ggx", alpha_u=0.2, alpha_v=0.2, sample_visible=True),
    "ggx aniso 0.15/0.45 visible": dict(distribution="ggx", alpha_u=0.15, alpha_v=0.45, sample_visible=True),
    "ggx aniso 0.5/0.08 D·cos": dict(distribution="ggx", alpha_u=0.5, alpha_v=0.08, sample_visible=False),
    "beckmann iso α=0.3 D·cos": dict(distribution="beckmann", alpha_u=0.3, alpha_v=0.3, sample_visible=False),
    "beckmann aniso 0.1/0.4 D·cos": dict(distribution="beckmann", alpha_u=0.1, alpha_v=0.4, sample_visible=False),
    "beckmann aniso 0.3/0.15 visible": dict(distribution="beckmann", alpha_u=0.3, alpha_v=0.15, sample_visible=True),
}
IORS = dict(intIOR=1.5, extIOR=1.0)


def mitsuba_dict(bsdf: str, cfg: dict) -> dict:
    """Mitsuba 3's ``roughconductor`` or ``roughdielectric`` with the same parameters."""
    out = {"type": bsdf, "distribution": cfg["distribution"], "alpha_u": cfg["alpha_u"], "alpha_v": cfg["alpha_v"],
           "sample_visible": cfg["sample_visible"]}
    if bsdf == "roughdielectric":
        return {**out, "int_ior": IORS["intIOR"], "ext_ior": IORS["extIOR"]}
    return {**out, "eta": {"type": "rgb", "value": list(cfg["eta"])}, "k": {"type": "rgb", "value": list(cfg["k"])}}


def make(bsdf: str, cfg: dict):
    """brdflab's material of a configuration."""
    from brdflab import RoughConductor, RoughDielectric

    return RoughDielectric(**IORS, **cfg) if bsdf == "roughdielectric" else RoughConductor(**cfg)


def mitsuba_side(inp: str, out: str) -> None:
    """In the Mitsuba venv: f·cos θ_o (N, 3) and pdf (N,) of every configuration's pairs."""
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    data = np.load(inp)
    cfgs = json.loads(str(data["configs"]))
    ctx = mi.BSDFContext()  # radiance mode
    res = {"version": np.array(mi.__version__)}
    for k, cfg in enumerate(cfgs):
        bsdf = mi.load_dict(mitsuba_dict(str(data["bsdf"]), cfg))
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


def widened_pdf(bsdf: str, cfg: dict, wi: np.ndarray, wo: np.ndarray, p: np.ndarray) -> np.ndarray:
    """brdflab's pdf ``p`` turned into Mitsuba's: for roughdielectric without visible normals, the density of
    normals ∝ D cos θ_h with α widened by s = 1.2 − 0.2 √|cos θ_i| (module docstring); ``p`` otherwise."""
    if bsdf != "roughdielectric" or cfg["sample_visible"]:
        return p
    from brdflab.bsdf import microfacet as mf

    side = np.where(wi[:, 2] < 0, -1.0, 1.0)
    z = np.stack([np.ones_like(side), np.ones_like(side), side], axis=1)  # flip z where ω_i is inside
    wi_f, wo_f = wi * z, wo * z
    eta_i = np.where(wi[:, 2] < 0, IORS["intIOR"], IORS["extIOR"])[:, None]
    eta_t = np.where(wi[:, 2] < 0, IORS["extIOR"], IORS["intIOR"])[:, None]
    h = np.where(wo_f[:, 2:] > 0, wi_f + wo_f, -(eta_i * wi_f + eta_t * wo_f))
    h = h / (np.linalg.norm(h, axis=1) * np.where(h[:, 2] < 0, -1.0, 1.0))[:, None]
    s = 1.2 - 0.2 * np.sqrt(np.abs(wi[:, 2]))
    ax, ay = cfg["alpha_u"], cfg["alpha_v"]
    with np.errstate(divide="ignore", invalid="ignore"):
        r = mf.ndf(cfg["distribution"], h, ax * s, ay * s) / mf.ndf(cfg["distribution"], h, ax, ay)
        return np.where(p > 0, p * r, 0.0)


def pairs(bsdf: str, cfg: dict, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Half uniform pairs (the upper hemisphere, or the sphere for the dielectric), half with ω_o from brdflab's
    sampler."""
    from brdflab.math import warps

    sphere = bsdf == "roughdielectric"
    warp = warps.square_to_uniform_sphere if sphere else warps.square_to_uniform_hemisphere
    wi = warp(rng.random((n, 2)))
    wi[:, 2] = np.where(wi[:, 2] < 0, np.minimum(wi[:, 2], -1e-3), np.maximum(wi[:, 2], 1e-3))
    wi /= np.linalg.norm(wi, axis=1)[:, None]
    wo = warp(rng.random((n, 2)))
    h = n // 2
    s = make(bsdf, cfg).sample(wi[h:], rng.random((n - h, 3)))
    ok = (s.pdf > 0) & ((s.wo[:, 2] != 0) if sphere else (s.wo[:, 2] > 0))
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
    ap.add_argument("--bsdf", choices=("roughconductor", "roughdielectric"), default="roughconductor")
    ap.add_argument("--n", type=int, default=100_000, help="direction pairs per configuration")
    ap.add_argument("--seed", type=int, default=45)
    ap.add_argument("--fixture", help="write 24 lobe pairs per configuration with Mitsuba's values (JSON)")
    ap.add_argument("--mitsuba", nargs=2, metavar=("IN", "OUT"), help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.mitsuba:
        mitsuba_side(*a.mitsuba)
        return
    py = os.environ.get("MITSUBA_PYTHON") or str(ROOT / "benchmarks" / ".venv-mitsuba" / "bin" / "python")
    if not Path(py).exists():
        py = "/work/main/benchmarks/.venv-mitsuba/bin/python"
    rng = np.random.default_rng(a.seed)
    configs = DIELECTRIC_CONFIGS if a.bsdf == "roughdielectric" else CONFIGS
    names = list(configs)
    data = {}
    for k, name in enumerate(names):
        data[f"wi{k}"], data[f"wo{k}"] = pairs(a.bsdf, configs[name], a.n, rng)
    with tempfile.TemporaryDirectory() as tmp:
        inp, out = os.path.join(tmp, "in.npz"), os.path.join(tmp, "out.npz")
        np.savez(inp, configs=np.array(json.dumps([configs[n] for n in names])), bsdf=np.array(a.bsdf), **data)
        subprocess.run([py, __file__, "--mitsuba", inp, out], check=True)
        mres = dict(np.load(out))
    print(f"{a.bsdf}: Mitsuba {mres['version']} scalar_rgb vs brdflab, {a.n:,} pairs per configuration")
    worst_zero = 0.0
    print(f"{'configuration':38s} {'f·cos median':>13s} {'p99':>9s} {'pdf median':>11s} {'p99':>9s} {'zero≠':>6s}")
    fixture = {"mitsuba": str(mres["version"]), "variant": "scalar_rgb", "bsdf": a.bsdf, "configs": {}}
    if a.bsdf == "roughdielectric":
        fixture["iors"] = IORS
    for k, name in enumerate(names):
        m = make(a.bsdf, configs[name])
        wi, wo = data[f"wi{k}"], data[f"wo{k}"]
        f, p = m.eval_pdf(wi, wo)
        fc = f * np.abs(wo[:, 2:])
        p = widened_pdf(a.bsdf, configs[name], wi, wo, p)
        ef, zf = rel_errors(fc.ravel(), mres[f"f{k}"].ravel())
        ep, zp = rel_errors(p, mres[f"p{k}"])
        print(f"{name:38s} {np.median(ef):13.2e} {np.quantile(ef, 0.99):9.2e} {np.median(ep):11.2e} "
              f"{np.quantile(ep, 0.99):9.2e} {zf + zp:6d}")
        if a.bsdf == "roughdielectric":  # the transmitted pairs alone (ω_i and ω_o on opposite sides)
            t = wi[:, 2] * wo[:, 2] < 0
            et, _ = rel_errors(fc[t].ravel(), mres[f"f{k}"][t].ravel())
            ept, _ = rel_errors(p[t], mres[f"p{k}"][t])
            print(f"{'  transmission only (' + str(int(t.sum())) + ' pairs)':38s} {np.median(et):13.2e} "
                  f"{np.quantile(et, 0.99):9.2e} {np.median(ept):11.2e} {np.quantile(ept, 0.99):9.2e}")
        for got, ref in ((fc.ravel(), mres[f"f{k}"].ravel()), (p, mres[f"p{k}"])):
            worst_zero = max(worst_zero, float(np.max(np.abs(got[ref == 0]), initial=0.0)))
        h = a.n // 2
        lobe = np.arange(h, h + 24)
        fixture["configs"][name] = {"params": configs[name], "wi": wi[lobe].tolist(), "wo": wo[lobe].tolist(),
                                    "f_cos": mres[f"f{k}"][lobe].tolist(), "pdf": mres[f"p{k}"][lobe].tolist()}
    print(f"largest brdflab value where Mitsuba returns 0: {worst_zero:.3g} (Mitsuba zeroes D·cos θ_h < 1e-20)")
    if a.fixture:
        Path(a.fixture).write_text(json.dumps(fixture, indent=1) + "\n")
        print(f"fixture: {a.fixture}")


if __name__ == "__main__":
    sys.exit(main())
