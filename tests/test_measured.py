"""The ``measured`` BSDF (MERL tables) and ``fit`` (issue 25): the loader is exact to the format, the table of
an analytic model samples, validates, renders and fits like the model, and a planted sampling bug is caught."""

from __future__ import annotations

import struct

import numpy as np
import pytest

import brdflab as bl
from brdflab.bsdf import measured as M
from brdflab.cli.main import main
from brdflab.viz import coords

CBOX = "scenes/cbox/cbox_diffuse.xml"


@pytest.fixture(scope="module")
def conductor():
    return bl.RoughConductor(R0=[0.95, 0.64, 0.54], alpha=0.3)


@pytest.fixture(scope="module")
def table(conductor):
    return M.tabulate(conductor)


@pytest.fixture(scope="module")
def merl_file(tmp_path_factory, table):
    path = tmp_path_factory.mktemp("merl") / "rc03.binary"
    M.write_merl(path, table)
    return path


def test_loader_is_exact_to_the_format(tmp_path):
    """A file written byte by byte from the format's definition: int32 dims, then all red, green, blue
    doubles, index (θh·90 + θd)·180 + φd, scale 1/1500, 1.15/1500, 1.66/1500, negative = unmeasured."""
    n = 90 * 90 * 180
    raw = np.zeros((3, n))
    i_th, i_td, i_pd = 37, 51, 123
    flat = (i_th * 90 + i_td) * 180 + i_pd
    raw[:, flat] = [1500.0, 3000.0, 4500.0]
    raw[0, 0] = -1.0
    path = tmp_path / "one.binary"
    path.write_bytes(struct.pack("<3i", 90, 90, 180) + raw.astype("<f8").tobytes())
    t = M.read_merl(path)
    assert t.shape == (90, 90, 180, 3)
    assert t[i_th, i_td, i_pd] == pytest.approx([1.0, 2.0 * 1.15, 3.0 * 1.66], rel=1e-15)
    assert t[0, 0, 0, 0] == 0.0 and np.count_nonzero(t) == 3
    # the node's directions, by the format's index formulas (θh = (i/90)²·90°, θd = i/90·90°, φd = i/180·180°)
    th, td, pd = np.radians((i_th / 90) ** 2 * 90), np.radians(i_td), np.radians(i_pd)
    wi, wo = coords.half_diff_to_io(th, 0.3, td, pd)
    assert M.Measured(table=t).eval(wi, wo)[0] == pytest.approx([1.0, 2.3, 4.98], rel=1e-9)
    # reciprocity folds φd: swapping the directions gives the same node
    assert M.Measured(table=t).eval(wo, wi)[0] == pytest.approx([1.0, 2.3, 4.98], rel=1e-9)
    M.write_merl(tmp_path / "again.binary", t)
    assert (tmp_path / "again.binary").read_bytes()[:12] == struct.pack("<3i", 90, 90, 180)
    assert np.array_equal(M.read_merl(tmp_path / "again.binary"), t)


@pytest.mark.parametrize("content, message", [
    (struct.pack("<3i", 90, 90, 90), "dimensions"),
    (struct.pack("<3i", 90, 90, 180) + b"\0" * 80, "bytes, expected"),
    (b"\1\2", "too short"),
])
def test_bad_merl_files_are_refused(tmp_path, content, message):
    path = tmp_path / "bad.binary"
    path.write_bytes(content)
    with pytest.raises(bl.BrdflabError, match=message):
        M.read_merl(path)


def test_table_of_a_model_evaluates_like_the_model(table, conductor):
    m = M.Measured(table=table)
    rng = np.random.default_rng(41)
    wi = bl.warps.square_to_cosine_hemisphere(rng.random((20000, 2)))
    wo = bl.warps.square_to_cosine_hemisphere(rng.random((20000, 2)))
    fa, fm = conductor.eval(wi, wo), m.eval(wi, wo)
    assert np.sum(np.abs(fm - fa)) / np.sum(fa) < 0.01  # trilinear interpolation error (measured: 0.1–0.9 %)
    assert np.allclose(m.eval(wi, wo), m.eval(wo, wi), rtol=1e-9, atol=0)  # reciprocal like the model


@pytest.mark.parametrize("theta", [0.0, 45.0, 80.0])
def test_table_sampler_passes_chi_square_and_consistency(table, theta):
    m = M.Measured(table=table)
    # measured false-alarm rate of this test on this table: 0 of 120 seeds below p = 0.01 (θ 0°, 45°, 80°)
    r = bl.chi2_test(m, theta=theta, samples=60_000, seed=11)
    assert r.passed, r.message
    assert bl.consistency_test(m, theta=theta, samples=10_000).passed


def test_a_table_sampler_with_the_wrong_pdf_fails(table, monkeypatch):
    """Negative control: the pdf without the defensive cosine share (the samples still contain it)."""
    m = M.Measured(table=table)
    monkeypatch.setattr(M, "DEFENSIVE", 0.0)  # pdf() now leaves the cosine share out; sample() too…
    broken = M.Measured(table=table)
    original_sample = M.Measured.sample

    def sample_with_share(self, wi, u, uv=None):  # …but the sampler keeps drawing 10 % cosine samples
        monkeypatch.setattr(M, "DEFENSIVE", 0.1)
        try:
            return original_sample(self, wi, u, uv)
        finally:
            monkeypatch.setattr(M, "DEFENSIVE", 0.0)

    monkeypatch.setattr(broken, "sample", sample_with_share.__get__(broken))
    assert not bl.chi2_test(broken, theta=30, samples=60_000, seed=12).passed
    assert bl.chi2_test(m, theta=30, samples=60_000, seed=12).passed


def test_albedo_of_the_table_matches_the_model(table, conductor):
    m = M.Measured(table=table)
    for theta in (0.0, 60.0):
        ca = bl.furnace_test(conductor, thetas=(theta,), samples=40_000)[0]
        cm = bl.furnace_test(m, thetas=(theta,), samples=40_000)[0]
        assert abs(cm.monte_carlo - ca.quadrature) < 4 * cm.mc_stderr + 0.005


def test_render_of_the_table_is_checked_consistent_with_the_model(tmp_path, merl_file, monkeypatch):
    """The measured table on the tall block renders within noise of the analytic model (``check``)."""
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    text = (root / CBOX).read_text()
    text = re.sub(r'value="(meshes/[^"]+)"', lambda m: f'value="{root / "scenes/cbox" / m.group(1)}"', text)
    i = text.rindex('<bsdf type="diffuse">')
    j = text.index("</bsdf>", i) + len("</bsdf>")
    analytic = tmp_path / "analytic.xml"
    analytic.write_text(text[:i] + '<bsdf type="roughconductor"><color name="R0" value="0.95, 0.64, 0.54"/>'
                        '<float name="alpha" value="0.3"/></bsdf>' + text[j:])
    table_scene = tmp_path / "table.xml"
    table_scene.write_text(text[:i] + f'<bsdf type="measured"><string name="filename" value="{merl_file.name}"/>'
                           '</bsdf>' + text[j:])
    (tmp_path / merl_file.name).symlink_to(merl_file)
    mine = bl.render(bl.load_scene(table_scene, width=48, height=48, integrator="direct_mis"), spp=32, seed=3,
                     workers=1)
    res = bl.check(mine, analytic, integrator="direct_mis", spp=32, runs=2, user_spp=32, block=8, levels=1,
                   resolution=(48, 48), workers=1)
    assert res.consistent, res.verdict()


def test_fit_recovers_the_model_and_the_cli_writes_its_page(tmp_path, merl_file, table, capsys):
    rng = np.random.default_rng(8)
    noisy = table * rng.lognormal(0.0, 0.05, table.shape)  # 5 % multiplicative noise, like a measurement
    res = bl.fit(noisy, "roughconductor", stride=(3, 5, 10))
    assert res.params["alpha"] == pytest.approx(0.3, rel=0.02)
    assert res.params["R0"] == pytest.approx([0.95, 0.64, 0.54], rel=0.02)
    out = tmp_path / "fit"
    assert main(["fit", str(merl_file), "--model", "roughconductor", "-o", str(out), "--json", "--effort",
                 "quick"]) == 0
    import json

    d = json.loads(capsys.readouterr().out)
    assert d["params"]["alpha"] == pytest.approx(0.3, rel=1e-6)
    assert (out / "fit.html").exists() and (out / "fit_slices.png").exists()


def test_measured_through_the_commands(tmp_path, merl_file, capsys):
    assert main(["chi2", "--bsdf", "measured", "--param", f"filename={merl_file}", "--theta", "30",
                 "-n", "40000"]) == 0
    assert main(["plot", "--bsdf", f"measured:filename={merl_file}", "--views", "polar,slice,albedo", "-o",
                 str(tmp_path / "p"), "--effort", "quick", "--samples", "4000"]) == 0
    assert main(["chi2", "--bsdf", "measured", "--param", f"filename={tmp_path / 'missing.binary'}"]) == 2
    assert "not found" in capsys.readouterr().err


def test_a_measured_table_is_an_input_no_output_may_replace(tmp_path, merl_file, capsys):
    """The table is found like meshes (the scene's folder first) and counted among the run's inputs."""
    import shutil
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    table = tmp_path / "table.exr"  # a table whose name a render output could take
    shutil.copy(merl_file, table)
    text = (root / CBOX).read_text().replace('value="meshes/', f'value="{root / "scenes/cbox/meshes"}/')
    i = text.rindex('<bsdf type="diffuse">')
    j = text.index("</bsdf>", i) + len("</bsdf>")
    scene = tmp_path / "m.xml"
    scene.write_text(text[:i] + '<bsdf type="measured"><string name="filename" value="table.exr"/></bsdf>' + text[j:])
    assert table in [Path(p) for p in bl.load_scene(scene).inputs]
    before = table.read_bytes()
    assert main(["render", str(scene), "--spp", "1", "-o", str(table), "--force", "--quiet"]) == 2
    assert "is an input of this run" in capsys.readouterr().err and table.read_bytes() == before
