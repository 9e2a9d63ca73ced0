"""Resources: a 1-million-triangle scene at 800×600 loads, builds and renders within a stated memory
budget, and memory does not grow with the sample count (fixed-size work units). Speed is not tested here
(see ``brdflab bench``)."""

from __future__ import annotations

import json
import subprocess
import sys

from brdflab.benchmarking import ROOT, mesh1m_scene

#: Stated budget for the 1 M-triangle scene at 800×600 (peak resident memory of the whole process).
PEAK_BUDGET_BYTES = 1.5 * 2**30


def _run(spp: int) -> dict:
    scene = mesh1m_scene(ROOT / ".bench-cache")
    out = subprocess.run([sys.executable, "-m", "brdflab.benchmarking", "--one", str(scene), "direct_ems", str(spp),
                          "1", "0", "mesh1m"], capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_million_triangles_within_budget():
    one = _run(1)
    assert one["triangles"] >= 1_000_000
    # No time assertion (a shared 2-core machine can be 2× slower): load speed is measured by `brdflab bench`.
    # Memory instead: the load adds about 300 B per triangle (810 before the OBJ fast path and row-by-row tables).
    assert one["bytes_per_triangle"] < 400, one["bytes_per_triangle"]
    assert one["peak_rss_bytes"] < PEAK_BUDGET_BYTES, one["peak_rss_bytes"] / 2**20
    assert one["worker_peak_rss_bytes"] < PEAK_BUDGET_BYTES, one["worker_peak_rss_bytes"] / 2**20
    four = _run(4)
    # Four times the samples, (almost) the same peak: work units have a fixed size.
    assert four["peak_rss_bytes"] < one["peak_rss_bytes"] * 1.15 + 64 * 2**20
    assert four["worker_peak_rss_bytes"] < one["worker_peak_rss_bytes"] * 1.15 + 64 * 2**20
