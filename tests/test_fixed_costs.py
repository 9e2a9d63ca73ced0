"""Fixed costs of a run: ``brdflab render`` imports no plotting or statistics library, prints its fixed
costs, and writes the EXR and the PNG together (same pixels as writing them one after the other)."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from brdflab.errors import ImageError
from brdflab.imageio import read_exr, read_png, srgb_bytes, write_images
from tests.conftest import ROOT

#: Libraries the render command must not import (each costs 0.3–1 s of start-up).
HEAVY = ("scipy", "matplotlib", "colour")

_PROBE = """
import json, sys
from importlib.metadata import entry_points
main = next(e for e in entry_points(group="console_scripts") if e.name == "brdflab").load()
status = main(sys.argv[1:])
print(json.dumps({"status": status, "modules": sorted({m.split(".")[0] for m in sys.modules})}))
"""


@pytest.mark.parametrize("engine", ["numpy", "numba"])
def test_render_command_imports_no_heavy_library_and_reports_fixed_costs(tmp_path, engine):
    """Neither engine imports anything heavy: the compiled engine loads its prebuilt kernels without numba
    (numba and what it imports only where the prebuilt module cannot be had), and the fixed-costs line
    counts their load and build time."""
    from brdflab.kernels import aot

    scene = ROOT / "scenes" / "envlit" / "envlit_ems.xml"
    out = subprocess.run([sys.executable, "-c", _PROBE, "--engine", engine, "render", str(scene), "--spp", "1",
                          "--workers", "1", "-o", str(tmp_path / "e.exr")], capture_output=True, text=True,
                         cwd=tmp_path, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    rec = json.loads(out.stdout.strip().splitlines()[-1])
    assert rec["status"] == 0
    allowed = set()
    prebuilt = aot.enabled() and aot.lookup().state == "built"  # built by the session start (conftest)
    if engine == "numba" and not prebuilt:
        allowed = set(json.loads(subprocess.run([sys.executable, "-c", "import json, sys, numba; "
                                                 "print(json.dumps(sorted(sys.modules)))"],
                                                capture_output=True, text=True).stdout))
    else:
        assert "numba" not in rec["modules"]
    assert not (set(HEAVY) - allowed) & set(rec["modules"]), set(HEAVY) & set(rec["modules"])
    line = next(ln for ln in out.stderr.splitlines() if "fixed costs" in ln)
    for part in ("start-up", "load", "OBJ", "BVH", "EXR", "PNG", "whole run"):
        assert part in line, line
    assert ("compiled kernels" in line) == (engine == "numba"), line
    assert (tmp_path / "e.exr").is_file() and (tmp_path / "e.png").is_file()


def test_whole_run_counts_the_render_done_by_workers(tmp_path):
    """The fixed-costs line's "whole run" is wall time: it includes a render the main process only waited for
    (here a render that idles 2.5 s, longer than the start-up fallback of :func:`brdflab.timing.process_seconds`
    to CPU time, which is what the line used to print: 0.3 s)."""
    code = ("import sys, time, brdflab.renderer as r\n"
            "real = r.render\n"
            "def idle(*a, **k):\n"
            "    time.sleep(2.5)\n"
            "    return real(*a, **k)\n"
            "r.render = idle\n"
            "from brdflab.cli.main import main\n"
            "sys.exit(main(sys.argv[1:]))\n")
    scene = ROOT / "scenes" / "envlit" / "envlit_ems.xml"
    out = subprocess.run([sys.executable, "-c", code, "--engine", "numpy", "render", str(scene), "--spp", "1",
                          "--workers", "1", "-o", str(tmp_path / "e.exr")], capture_output=True, text=True,
                         cwd=tmp_path, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    line = next(ln for ln in out.stderr.splitlines() if "fixed costs" in ln)
    assert float(line.split("whole run ")[1].split(" s")[0]) >= 2.5, line


def test_write_images_matches_separate_writes(tmp_path):
    rng = np.random.default_rng(1701)
    img = (rng.random((37, 53, 3)) * 1.3).astype(np.float32)
    exr_s, png_s = write_images(tmp_path / "a.exr", tmp_path / "a.png", img, extra={"k": "v"})
    assert exr_s >= 0 and png_s >= 0
    np.testing.assert_array_equal(read_exr(tmp_path / "a.exr"), img)
    np.testing.assert_array_equal(read_png(tmp_path / "a.png"), srgb_bytes(img))


def test_write_images_raises_when_the_png_cannot_be_written(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    img = np.zeros((4, 4, 3), np.float32)
    with pytest.raises(ImageError):
        write_images(tmp_path / "a.exr", blocker / "a.png", img)
    # The pair is replaced together or not at all (issue 18): no EXR without its PNG, no temporary left.
    assert not (tmp_path / "a.exr").exists() and not [p for p in tmp_path.iterdir() if p.name.startswith(".")]
