"""Variance report: generated at tiny spp and checked in a real headless browser."""

from __future__ import annotations

import csv
import html
import json
import shutil
import subprocess

import pytest

from brdflab.cli.main import main
from brdflab.pages.variance import Checkpoint, time_to_reach
from tests.conftest import CAMERA, QUAD_OBJ, write_scene
from tests.test_render import LIGHT_OBJ

CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync"]


def _chromium() -> str | None:
    return shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")


def test_time_to_reach_interpolates_in_log_log():
    curve = [Checkpoint("a", 1, 1.0, 1.0, 0, 0, 0), Checkpoint("a", 4, 4.0, 0.25, 0, 0, 0)]
    assert time_to_reach(curve, 0.5) == pytest.approx(2.0)
    assert time_to_reach(curve, 0.1) is None
    assert time_to_reach(curve, 2.0) == 1.0


@pytest.fixture(scope="module")
def report_dir(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("report")
    scene = write_scene(tmp, '<integrator type="direct_ems"/>' + CAMERA
                        + '<mesh type="obj"><string name="filename" value="quad.obj"/>'
                          '<transform name="toWorld"><scale value="10,1,10"/></transform></mesh>'
                          '<mesh type="obj"><string name="filename" value="light.obj"/>'
                          '<emitter type="area"><color name="radiance" value="1,1,1"/></emitter></mesh>',
                        {"quad.obj": QUAD_OBJ, "light.obj": LIGHT_OBJ}, name="tiny.xml")
    out = tmp / "reports" / "tiny"
    assert main(["report", str(scene), "--spp", "1,2,4", "--ref-spp", "32", "--runs", "2", "--workers", "1",
                 "-o", str(out)]) == 0
    return out


def test_report_outputs(report_dir):
    rows = list(csv.DictReader(open(report_dir / "results.csv")))
    assert {r["integrator"] for r in rows} == {"direct_ems", "direct_mats", "direct_mis"}
    assert {int(r["spp"]) for r in rows} >= {1, 2, 4}
    meta = json.loads((report_dir / "results.json").read_text())
    assert "independent seed" in meta["reference"]
    assert any(r["flip"] is not None and 0 <= r["flip"] <= 1 for r in meta["rows"])  # HDR-FLIP beside relMSE
    for name in ("error_vs_time.png", "error_vs_time.svg", "error_vs_spp.svg", "relmse_map_direct_mis.png",
                 "tiny_direct_mis_4spp.exr", "tiny_direct_ems_1spp.png", "report.html"):
        assert (report_dir / name).exists(), name
    text = (report_dir / "report.html").read_text()
    assert "reaches relMSE" in text or "lowest error" in text
    assert (report_dir.parent / "index.html").exists()


def test_report_in_browser(report_dir):
    exe = _chromium()
    if exe is None:
        pytest.skip("no Chromium on this machine (CI installs Debian's chromium)")
    url = (report_dir / "report.html").resolve().as_uri() + "#selftest"
    user_dir = report_dir.parent / "chromium-profile"
    out = subprocess.run([exe, *CHROMIUM_FLAGS, f"--user-data-dir={user_dir}", "--virtual-time-budget=5000",
                          "--dump-dom", url], capture_output=True, text=True, timeout=120)
    start = out.stdout.find('data-selftest="')
    assert start >= 0, out.stderr[-2000:]
    raw = out.stdout[start + len('data-selftest="'):]
    result = json.loads(html.unescape(raw[:raw.index('"')]))
    assert result["images"] == result["loaded"] and result["images"] >= 8
    assert result["plots"] >= 4
    assert result["renders"] >= 4 and result["zoomed"] == result["renders"]
    # A/B flip: every non-reference render of the equal-spp and equal-time rows swaps with the reference and back.
    assert result["flippable"] >= 6 and result["flipped"] == result["restored"] == result["flippable"]
    # tev-style controls (issue 43): the exposure slider acts on the renders, the pixel read-out reads them
    assert result["exposure"] == 1 and result["readout"] == 1, result
