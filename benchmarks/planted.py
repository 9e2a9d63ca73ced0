"""Planted bugs: realistic mistakes, one at a time, against the tests and ``brdflab validate`` (a benchmark).

Run from the repository root (CPU-heavy, ~1 min per bug)::

    python benchmarks/planted.py                 # every planted bug
    python benchmarks/planted.py --only fresnel  # bugs whose id contains "fresnel"
    python benchmarks/planted.py --list

Where :mod:`benchmarks.mutation` makes small syntactic edits everywhere, this file keeps a hand-written
set of the bugs students make implementing this assignment and refactorings introduce — the categories
of issue #15: missing Jacobians, a wrong G1 branch, a wrong Fresnel argument, lobe-selection mismatches,
a forgotten light-selection probability, MIS weights that do not sum to one, an environment pdf without
sin θ, CDF off-by-one, float32 where float64 is needed, and their relatives in the emitters and
integrators. Each bug is an exact text replacement in one file (it must apply exactly once).

A bug is judged in stages, stopping at the first that catches it:

1. the fast test selection of :mod:`benchmarks.mutation` (``TESTS``);
2. ``brdflab validate`` (the default battery, fewer samples), through the command line;
3. the rest of the model and light-transport tests (:data:`BROAD`).

It is *caught* when a stage fails; *missed* when all three pass. Results go to
``benchmarks/planted_results.json``.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))

from mutation import TESTS, copy_env, copy_tree  # noqa: E402

BROAD = ["tests/test_validate.py", "tests/test_validate_light.py", "tests/test_integrators.py",
         "tests/test_light_paths.py", "tests/test_render.py", "tests/test_references.py",
         "tests/test_open_checks.py"]


@dataclass(frozen=True)
class Bug:
    """One planted bug: replace ``old`` by ``new`` (exactly one occurrence) in ``path``."""

    id: str
    what: str
    path: str
    old: str
    new: str


MF = "brdflab/bsdf/microfacet.py"
RC = "brdflab/bsdf/roughconductor.py"
FR = "brdflab/bsdf/fresnel.py"
RS = "brdflab/bsdf/roughsubstrate.py"
WARPS = "brdflab/math/warps.py"
AREA = "brdflab/emitter/area.py"
COMMON = "brdflab/integrator/common.py"
ENV = "brdflab/emitter/environment.py"
POINT = "brdflab/emitter/point.py"
MIS = "brdflab/integrator/direct_mis.py"
GEOM = "brdflab/scene/geometry.py"

BUGS = [
    # --- microfacet model -------------------------------------------------------------------------------
    Bug("d-cos3", "Beckmann D with cos³θ_h instead of cos⁴θ_h", MF,
        "(np.pi * a2 * cs**4)", "(np.pi * a2 * cs**3)"),
    Bug("d-alpha", "Beckmann D normalised by α instead of α²", MF,
        "/ (np.pi * a2 * cs**4)", "/ (np.pi * np.sqrt(a2) * cs**4)"),
    Bug("g1-branch", "rational G1 used for b ≥ 1.6 (branch inverted)", MF,
        "small = b < 1.6", "small = b >= 1.6"),
    Bug("g1-coef", "G1 numerator 2.181 b² typed as 2.181 b", MF,
        "(3.535 * bs + 2.181 * bs * bs)", "(3.535 * bs + 2.181 * bs)"),
    Bug("g1-no-chi", "G1 without the χ⁺(v·ω_h / v·n) test", MF,
        "return np.where(chi, g, 0.0)", "return g"),
    Bug("jacobian-missing", "microfacet pdf without the 1/(4 ω_o·ω_h) Jacobian", MF,
        "p = d * np.maximum(wh[:, 2], 0.0) / (4.0 * oh)", "p = d * np.maximum(wh[:, 2], 0.0)"),
    Bug("jacobian-wi", "Jacobian with ω_o·n instead of ω_o·ω_h", MF,
        "p = d * np.maximum(wh[:, 2], 0.0) / (4.0 * oh)",
        "p = d * np.maximum(wh[:, 2], 0.0) / (4.0 * np.abs(wo[:, 2]))"),
    Bug("schlick-cos-n", "Schlick with cos θ_i (to the normal) instead of ω_i·ω_h", RC,
        "f = fresnel_schlick(np.clip(hi, 0.0, 1.0), r0, s)", "f = fresnel_schlick(np.clip(ci, 0.0, 1.0), r0, s)"),
    Bug("schlick-pow4", "Schlick with (1 − cos)⁴", FR,
        "    m5 *= m  # (1 − cos θ)⁵", "    m5 *= 1.0  # (1 − cos θ)⁵"),
    Bug("conductor-2cos", "conductor f with 1/(2 cos θ_i cos θ_o)", RC,
        "s = np.where(ok, d * g / (4.0 * ci * co), 0.0)", "s = np.where(ok, d * g / (2.0 * ci * co), 0.0)"),
    Bug("conductor-one-g1", "conductor with G1(ω_i) only (shadowing of ω_o forgotten)", RC,
        "g = smith_g1(wi, wh, a, hi) * smith_g1(wo, wh, a)\n            with np.errstate(divide=\"ignore\", "
        "invalid=\"ignore\"):\n                s =",
        "g = smith_g1(wi, wh, a, hi)\n            with np.errstate(divide=\"ignore\", invalid=\"ignore\"):\n"
        "                s ="),
    Bug("warp-beckmann-alpha", "Beckmann warp tan²θ = −α ln(1 − ξ) (α not squared)", WARPS,
        "tan2 = -(alpha * alpha) * np.log1p(-u[:, 0])", "tan2 = -alpha * np.log1p(-u[:, 0])"),
    Bug("warp-beckmann-pdf-nocos", "Beckmann warp pdf D without cos θ", WARPS,
        "beckmann_d(cos_t, alpha) * np.maximum(cos_t, 0.0)", "beckmann_d(cos_t, alpha)"),
    # --- dielectric / substrate ---------------------------------------------------------------------------
    Bug("fresnel-eta-swap", "dielectric Fresnel with η_i and η_t swapped (from inside)", FR,
        "eta_i, eta_t, ci = eta_ext, eta_int, cos_i", "eta_i, eta_t, ci = eta_int, eta_ext, cos_i"),
    # (Dropping the TIR mask alone is equivalent: cos θ_t is clamped to 0 there, which gives r_s = r_p = 1.)
    Bug("fresnel-tir-zero", "total internal reflection gives F = 0 instead of 1", FR,
        "return np.where(tir | ~np.isfinite(f), 1.0, np.clip(f, 0.0, 1.0))",
        "return np.where(tir, 0.0, np.where(np.isfinite(f), np.clip(f, 0.0, 1.0), 1.0))"),
    Bug("substrate-fdiff-exp", "substrate diffuse (1 − cos/2)⁴", RS,
        "(1.0 - (1.0 - 0.5 * ci) ** 5)", "(1.0 - (1.0 - 0.5 * ci) ** 4)"),
    Bug("substrate-fdiff-const", "substrate diffuse scale 28/(23) without 1/π", RS,
        "28.0 / (23.0 * np.pi)", "28.0 / 23.0"),
    Bug("substrate-lobe-mismatch", "lobe picked with p_s but pdf mixed with 1/2 : 1/2", RS,
        "pdf = np.where(ci > 0, ps * p_mf + (1.0 - ps) * p_d, 0.0)",
        "pdf = np.where(ci > 0, 0.5 * p_mf + 0.5 * p_d, 0.0)"),
    Bug("substrate-lobe-inverted", "specular lobe chosen with probability 1 − p_s", RS,
        "spec = np.flatnonzero(u[:, 2] < ps)", "spec = np.flatnonzero(u[:, 2] >= ps)"),
    Bug("substrate-fresnel-cos-n", "coat Fresnel at cos θ_i instead of ω_i·ω_h", RS,
        "fr = fresnel_dielectric(np.clip(hi, 0.0, 1.0), self.ext_ior, self.int_ior)",
        "fr = fresnel_dielectric(np.clip(ci, 0.0, 1.0), self.ext_ior, self.int_ior)"),
    Bug("diffuse-no-inv-pi", "cosine-hemisphere pdf cos θ without 1/π", WARPS,
        "return np.where(w[:, 2] >= 0, w[:, 2] * INV_PI, 0.0)", "return np.where(w[:, 2] >= 0, w[:, 2], 0.0)"),
    # --- emitters ---------------------------------------------------------------------------------------
    Bug("area-pdf-no-dist2", "area light pdf 1/(A cos θ_l) without the squared distance", AREA,
        "pdf = dist2 * np.take(self._pdf_scale, k) / cos_l", "pdf = np.take(self._pdf_scale, k) / cos_l"),
    Bug("area-pdf-hit-cos", "light pdf of BSDF-sampled hits without cos θ_l", AREA,
        "pdf = dist * dist * np.take(self._emitter_pdf_scale, emitter) / cos_l",
        "pdf = dist * dist * np.take(self._emitter_pdf_scale, emitter)"),
    Bug("area-single-no-cos", "single area light pdf ‖y−x‖²/A (cos θ_l forgotten)", AREA,
        "            pdf = dist2 / (self.area * cos_l)\n        ok",
        "            pdf = np.where(cos_l > 0, dist2 / self.area, 0.0)\n        ok"),
    Bug("triangle-fold", "triangle warp without folding (points outside the triangle)", WARPS,
        "fold = u[:, 0] + u[:, 1] > 1.0", "fold = u[:, 0] + u[:, 1] > 2.0"),
    Bug("cdf-off-by-one", "short CDF inverted with u > c instead of u ≥ c, over all entries", AREA,
        "    for c in cdf[:-1]:\n        k += u >= c", "    for c in cdf[1:]:\n        k += u >= c"),
    Bug("selection-pmf-missing", "multi-emitter pdf without the selection probability", COMMON,
        "pdf[sel] = r.pdf * scene.emitter_pmf[e]", "pdf[sel] = r.pdf"),
    Bug("selection-pmf-hit", "BSDF-hit pdf of a non-fused light without p_e", COMMON,
        "pdf[at] = emitter.pdf_hit(rows(h.t, sel), ns, d_e) * scene.emitter_pmf[e]",
        "pdf[at] = emitter.pdf_hit(rows(h.t, sel), ns, d_e)"),
    Bug("env-pdf-no-sin", "environment pdf without 1/sin θ", ENV,
        "out = p * (self.w * self.h) / (2 * np.pi**2 * st)", "out = p * (self.w * self.h) / (2 * np.pi**2)"),
    Bug("env-pdf-2pi", "environment pdf with 1/(2π²) → 1/(4π²)", ENV,
        "pdf = p_xy * (self.w * self.h) / (2 * np.pi**2 * st)", "pdf = p_xy * (self.w * self.h) / (4 * np.pi**2 * st)"),
    Bug("env-v-flip", "environment lookup with v not flipped", ENV,
        "return (1.0 - u) * self.w, (1.0 - v) * self.h,", "return (1.0 - u) * self.w, v * self.h,"),
    Bug("point-inverse-r", "point light I/r instead of I/r²", POINT,
        "self.intensity / np.where(ok, dist2, 1.0)", "self.intensity / np.where(ok, dist, 1.0)"),
    # --- integrators ------------------------------------------------------------------------------------
    Bug("mis-not-sum-to-one", "MIS BSDF weight p_b/(p_b + p_b·p_l)", MIS,
        "accumulate(Lsp, live, weight, Le, mis_weight(p_b, p_l, self.beta))",
        "accumulate(Lsp, live, weight, Le, mis_weight(p_b, p_b * p_l, self.beta))"),
    Bug("mis-delta-weighted", "point-light samples MIS-weighted against the BSDF pdf", MIS,
        "np.where(ls.delta, 1.0, mis_weight(ls.pdf, p_bsdf, self.beta))", "mis_weight(ls.pdf, p_bsdf, self.beta)"),
    Bug("mis-power-unsquared", "power heuristic with β = 1", MIS,
        "self.beta = 1.0 if heuristic == \"balance\" else 2.0", "self.beta = 1.0"),
    Bug("shadow-no-offset", "shadow rays end exactly at the light (no shortening)", GEOM,
        "t = dist * (1.0 - 1e-3)", "t = dist * (1.0 + 1e-3)"),
    Bug("float32-warp", "Beckmann warp in float32", WARPS,
        "alpha = np.asarray(alpha, dtype=np.float64)\n    with",
        "alpha = np.asarray(alpha, dtype=np.float32)\n    u = u.astype(np.float32)\n    with"),
]


def run(cmd: list[str], workdir: Path, timeout: float) -> tuple[bool, str]:
    """(passed, first failure line) of ``cmd`` run in ``workdir`` with the copy first on the path."""
    try:
        r = subprocess.run(cmd, cwd=workdir, env=copy_env(workdir), capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return False, "timeout"
    out = r.stdout + r.stderr
    lines = out.splitlines()
    first = next((line for line in lines if line.startswith(("FAILED", "ERROR", "FAIL "))), "")
    return r.returncode == 0, first.strip()[:160]


def stages(workdir: Path, samples: int):
    py = sys.executable
    pytest = [py, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", "-W", "ignore"]
    yield "fast tests", pytest + TESTS
    cli = "import sys; from brdflab.cli.main import main; sys.exit(main())"
    yield "brdflab validate", [py, "-c", cli, "validate", "--samples", str(samples), "-o", str(workdir / "validation")]
    yield "broad tests", pytest + BROAD


def judge(workdir: Path, timeout: float, samples: int) -> tuple[str, str, str]:
    """('caught' | 'missed', stage, failure) of the tree in ``workdir``."""
    for name, cmd in stages(workdir, samples):
        ok, first = run(cmd, workdir, timeout)
        if not ok:
            return "caught", name, first
    return "missed", "", ""


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", action="append", default=[], help="substring of bug ids (repeatable)")
    ap.add_argument("--list", action="store_true")
    ap.add_argument("--timeout", type=float, default=900.0)
    ap.add_argument("--samples", type=int, default=50000, help="samples per chi-square test of validate")
    ap.add_argument("--baseline", action="store_true", help="also check that the unmodified tree passes")
    ap.add_argument("-o", "--output", type=Path, default=ROOT / "benchmarks" / "planted_results.json")
    args = ap.parse_args(argv)
    bugs = [b for b in BUGS if not args.only or any(o in b.id for o in args.only)]
    if args.list:
        for b in bugs:
            print(f"{b.id:26s} {b.path}: {b.what}")
        return 0
    tmp = Path(tempfile.mkdtemp(prefix="brdflab-planted-"))
    rows = []
    t0 = time.monotonic()
    try:
        copy_tree(tmp)
        originals = {b.path: (tmp / b.path).read_text() for b in bugs}
        for b in bugs:
            n = originals[b.path].count(b.old)
            if n != 1:
                print(f"bug {b.id}: its text occurs {n} times in {b.path}", file=sys.stderr)
                return 2
        if args.baseline:
            status, stage, first = judge(tmp, args.timeout, args.samples)
            print(f"baseline: {'passes' if status == 'missed' else 'FAILS at ' + stage + ': ' + first}", flush=True)
            if status != "missed":
                return 2
        for k, b in enumerate(bugs):
            target = tmp / b.path
            target.write_text(originals[b.path].replace(b.old, b.new))
            t = time.monotonic()
            try:
                status, stage, first = judge(tmp, args.timeout, args.samples)
            finally:
                target.write_text(originals[b.path])
            rows.append({"id": b.id, "what": b.what, "path": b.path, "status": status, "stage": stage,
                         "failure": first, "seconds": round(time.monotonic() - t, 1)})
            print(f"[{k + 1}/{len(bugs)}] {status:6s} {b.id:26s} {stage:16s} {first[:90]}", flush=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    caught = sum(r["status"] == "caught" for r in rows)
    summary = {"bugs": len(rows), "caught": caught, "missed": len(rows) - caught,
               "by_stage": {s: sum(r["stage"] == s for r in rows) for s in ("fast tests", "brdflab validate",
                                                                              "broad tests")},
               "seconds": round(time.monotonic() - t0)}
    args.output.write_text(json.dumps({"summary": summary, "results": rows}, indent=1, ensure_ascii=False))
    print(json.dumps(summary, ensure_ascii=False))
    for r in rows:
        if r["status"] == "missed":
            print(f"MISSED {r['id']}: {r['what']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
