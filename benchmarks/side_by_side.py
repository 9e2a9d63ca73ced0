"""brdflab against Mitsuba 3 on the bench scenes, rendered alternately in one run.

Usage (with brdflab's own environment active)::

    python benchmarks/side_by_side.py [--spp 64] [--rounds 3] [--variants scalar_rgb,llvm_ad_rgb] [--no-whole]
                                      [cases ...]

* Mitsuba is installed from PyPI into its own venv, ``benchmarks/.venv-mitsuba`` (created on first use).
* ``llvm_ad_rgb`` needs an LLVM shared library (Debian: ``apt-get install libllvm19``); the script looks
  for ``libLLVM*.so*`` and passes it as ``DRJIT_LIBLLVM_PATH``. Without one, that variant is skipped.
* Each (case, integrator) is rendered by brdflab (``python -m brdflab.benchmarking --one``, a fresh process) and
  by Mitsuba (``benchmarks/mitsuba/run_mitsuba.py``, a fresh process per variant) in every round; the
  order alternates between rounds so that drift in machine load affects both. Only the render is timed
  (no scene loading, BVH build or JIT compilation). Both use every core.
* brdflab is also timed as users run it: a whole ``brdflab render SCENE --spp N`` process (start-up,
  load, BVH, render, EXR + PNG write), reported as samples/s over that wall time (``brdflab_whole``) and
  compared with Mitsuba's render call alone (``--no-whole`` skips it: render-only comparisons in a
  quarter less time on a loaded machine). The course scenes (``../shared/scenes``, skipped when
  absent) are among the cases.
* ``--engines numba,numpy`` (default: both) times brdflab with each engine (``BRDFLAB_ENGINE``, see
  :mod:`brdflab.kernels`), alternately with the rest; the whole-process figures of the compiled engine include
  loading its prebuilt kernels (the first run after an install or an edit also builds them, about 6 s: run
  ``brdflab render`` once before timing).
* Prints a table of median samples/s and the ratio brdflab / Mitsuba per variant — the headline figure —
  and writes ``benchmarks/results/side_by_side.json`` plus a Markdown table for the README.
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import platform
import re
import statistics
import subprocess
import sys
import time
import venv
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(HERE / "mitsuba"))

from translate import translate  # noqa: E402

from brdflab.benchmarking import CASES, case_scene, whole_process_seconds  # noqa: E402

VENV = HERE / ".venv-mitsuba"
MITSUBA_PY = VENV / "bin" / "python"


def ensure_mitsuba(say=print) -> Path:
    """Create the Mitsuba venv and install ``mitsuba`` and ``numpy`` into it (once)."""
    if MITSUBA_PY.exists():
        probe = subprocess.run([str(MITSUBA_PY), "-c", "import mitsuba, numpy"], capture_output=True)
        if probe.returncode == 0:
            return MITSUBA_PY
    say(f"creating {VENV} and installing mitsuba from PyPI …")
    venv.create(VENV, with_pip=True, clear=True)
    subprocess.run([str(MITSUBA_PY), "-m", "pip", "install", "-q", "mitsuba", "numpy"], check=True)
    return MITSUBA_PY


def find_llvm() -> str | None:
    """Path of the newest LLVM shared library on the machine (for Dr.Jit's LLVM backend), or None."""
    if os.environ.get("DRJIT_LIBLLVM_PATH"):
        return os.environ["DRJIT_LIBLLVM_PATH"]
    found = glob.glob("/usr/lib/*/libLLVM*.so*") + glob.glob("/usr/lib/llvm-*/lib/libLLVM*.so*")

    def version(p: str) -> int:
        m = re.search(r"LLVM(?:\.so\.|-)(\d+)", p)
        return int(m.group(1)) if m else 0

    found = [p for p in found if version(p) >= 11]
    return max(found, key=version) if found else None


def scene_paths(case: str, integrator: str) -> tuple[Path, Path]:
    """(brdflab scene, Mitsuba translation) of a bench case, writing the translation if needed."""
    rel, _ = CASES[case]
    scene = case_scene(case)
    if rel.startswith(("<", "..")):  # generated or course scenes: translations stay out of the repository
        out = ROOT / ".bench-cache" / "mitsuba" / f"{case}_{integrator}.xml"
    else:
        out = HERE / "mitsuba" / f"{case}_{integrator}.xml"
    translate(scene, integrator, out)
    return scene, out


def run_brdflab(scene: Path, integrator: str, spp: int, case: str) -> dict:
    """One brdflab render in a fresh process; the bench record's single run."""
    cmd = [sys.executable, "-m", "brdflab.benchmarking", "--one", str(scene), integrator, str(spp), "1", "0", case]
    out = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, check=True)
    rec = json.loads(out.stdout.strip().splitlines()[-1])
    return rec["runs"][0] | {"load_seconds": rec["load_seconds"], "triangles": rec["triangles"],
                             "width": rec["width"], "height": rec["height"], "fixed": rec.get("fixed", {})}


def run_brdflab_whole(scene: Path, integrator: str, spp: int, pixels: int) -> dict:
    """One whole ``brdflab render`` process; samples/s over its wall time."""
    seconds = whole_process_seconds(scene, integrator, spp, None)
    return {"seconds": seconds, "samples_per_s": pixels * spp / seconds}


def run_mitsuba(xml: Path, spp: int, variant: str, llvm: str | None) -> dict:
    """One Mitsuba render in a fresh process."""
    env = dict(os.environ)
    if llvm:
        env["DRJIT_LIBLLVM_PATH"] = llvm
    cmd = [str(MITSUBA_PY), str(HERE / "mitsuba" / "run_mitsuba.py"), str(xml), "--spp", str(spp),
           "--variant", variant]
    out = subprocess.run(cmd, capture_output=True, text=True, cwd=xml.parent, env=env, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    """Run the side-by-side benchmark."""
    ap = argparse.ArgumentParser(description="brdflab vs Mitsuba 3, alternately in one run")
    ap.add_argument("cases", nargs="*", default=list(CASES))
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--variants", default="scalar_rgb,llvm_ad_rgb")
    ap.add_argument("--integrators", default="direct_ems,direct_mats,direct_mis")
    ap.add_argument("--json", type=Path, default=HERE / "results" / "side_by_side.json")
    ap.add_argument("--no-whole", action="store_true", help="skip the whole-process brdflab runs")
    ap.add_argument("--engines", default="numba,numpy", help="brdflab engines to time (BRDFLAB_ENGINE)")
    a = ap.parse_args(argv)
    engines = [e for e in a.engines.split(",") if e]
    ensure_mitsuba()
    variants = [v for v in a.variants.split(",") if v]
    llvm = find_llvm()
    if any(v.startswith("llvm") for v in variants) and llvm is None:
        print("no LLVM shared library found (Debian: apt-get install libllvm19): skipping llvm_* variants")
        variants = [v for v in variants if not v.startswith("llvm")]
    jobs = []
    for case in a.cases:
        if not case_scene(case).exists():
            print(f"{case}: scene {case_scene(case)} not found, skipped")
            continue
        for integ in CASES[case][1]:
            if integ in a.integrators.split(","):
                jobs.append((case, integ, *scene_paths(case, integ)))
    players = [f"brdflab@{e}" for e in engines] + ([] if a.no_whole else [f"brdflab_whole@{e}" for e in engines])
    runs: dict[tuple[str, str], dict[str, list[dict]]] = {(c, i): {p: [] for p in players} | {v: [] for v in variants}
                                                          for c, i, _, _ in jobs}
    pixels: dict[tuple[str, str], int] = {}
    for r in range(a.rounds):
        for case, integ, scene, xml in jobs:
            order = [*players, *variants] if r % 2 == 0 else [*variants, *players[::-1]]
            for who in order:
                if "@" in who:
                    os.environ["BRDFLAB_ENGINE"] = who.split("@")[1]  # inherited by the brdflab processes
                if who.startswith("brdflab@"):
                    rec = run_brdflab(scene, integ, a.spp, case)
                    pixels[(case, integ)] = rec["width"] * rec["height"]
                elif who.startswith("brdflab_whole@"):
                    if (case, integ) not in pixels:
                        from brdflab.scene.loader import load_scene

                        cam = load_scene(scene).camera
                        pixels[(case, integ)] = cam.width * cam.height
                    rec = run_brdflab_whole(scene, integ, a.spp, pixels[(case, integ)])
                else:
                    rec = run_mitsuba(xml, a.spp, who, llvm)
                runs[(case, integ)][who].append(rec)
                print(f"round {r + 1}/{a.rounds}  {case:13s} {integ:12s} {who:12s} "
                      f"{rec['samples_per_s'] / 1e6:6.2f} M samples/s", flush=True)
    rows = []
    for (case, integ), by in runs.items():
        row = {"case": case, "integrator": integ, "runs": by}
        med = {w: statistics.median(x["samples_per_s"] for x in recs) for w, recs in by.items()}
        row["median_samples_per_s"] = med
        row["ratio"] = {f"{p} vs {v}": med[p] / med[v] for p in players for v in variants}
        row["engine_speedup"] = {p: med[p] / med[p.replace("@numba", "@numpy")] for p in players
                                 if p.endswith("@numba") and p.replace("@numba", "@numpy") in med}
        row["brdflab_embree_share"] = {p: statistics.median(x["embree_share"] for x in by[p])
                                       for p in players if p.startswith("brdflab@")}
        rows.append(row)
    label = {p: p.replace("brdflab_whole@", "whole ").replace("brdflab@", "render ") for p in players}
    ratios = [(p, v) for p in players for v in variants if p.startswith("brdflab@") or v == "scalar_rgb"]
    head = ("| case | integrator | " + " | ".join(label[p] for p in players) + " | " +
            " | ".join(f"Mitsuba {v}" for v in variants) + " | " +
            " | ".join(f"{label[p]} vs {v}" for p, v in ratios) +
            "".join(f" | {label[p]}: numba / numpy" for p in players if p.endswith("@numba")
                    and p.replace("@numba", "@numpy") in players) + " |")
    print("\n" + head)
    print("|" + "---|" * (head.count("|") - 1))
    for row in rows:
        med = row["median_samples_per_s"]
        cells = [f"{med[p] / 1e6:.2f} M" for p in players] + [f"{med[v] / 1e6:.2f} M" for v in variants]
        cells += [f"**{row['ratio'][f'{p} vs {v}']:.2f}×**" for p, v in ratios]
        cells += [f"{x:.2f}×" for x in row["engine_speedup"].values()]
        print(f"| {row['case']} | {row['integrator']} | " + " | ".join(cells) + " |")
    print(f"\nsamples/s, median of {a.rounds} alternating rounds, {a.spp} spp, {os.cpu_count()} cores, "
          f"{time.strftime('%Y-%m-%d')}")
    doc = {"date": time.strftime("%Y-%m-%d %H:%M"), "spp": a.spp, "rounds": a.rounds,
           "machine": {"cpus": os.cpu_count(), "platform": platform.platform(), "processor": platform.processor()},
           "llvm": llvm, "results": [row | {"runs": row["runs"]} for row in rows]}
    a.json.parent.mkdir(parents=True, exist_ok=True)
    a.json.write_text(json.dumps(doc, indent=2))
    print(f"wrote {a.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
