"""BRDF views (brdflab plot): coordinates, CSV values against eval, overlays and the HTML page."""

from __future__ import annotations

import csv
import re

import numpy as np
import pytest

from brdflab.bsdf.roughconductor import RoughConductor
from brdflab.cli.main import main
from brdflab.viz import coords, views


def _read_csv(path):
    lines = [ln for ln in open(path) if not ln.startswith("#")]
    rows = list(csv.reader(lines))
    return rows[0], np.array([[float(x) for x in r] for r in rows[1:]])


def test_half_difference_round_trip():
    rng = np.random.default_rng(19)
    n = 2000
    th, ph = rng.uniform(0, np.pi / 2, n), rng.uniform(0, 2 * np.pi, n)
    td, pd = rng.uniform(0, np.pi / 2, n), rng.uniform(0, 2 * np.pi, n)
    wi, wo = coords.half_diff_to_io(th, ph, td, pd)
    np.testing.assert_allclose(np.linalg.norm(wi, axis=1), 1, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(wo, axis=1), 1, atol=1e-12)
    h = (wi + wo) / np.linalg.norm(wi + wo, axis=1, keepdims=True)
    np.testing.assert_allclose(h, coords.spherical(th, ph), atol=1e-12)
    np.testing.assert_allclose(np.arccos(np.sum(wi * h, axis=1)), td, atol=1e-7)  # θ_d = angle(ω_i, ω_h)
    for got, want in zip(coords.io_to_half_diff(wi, wo), (th, ph, td, pd), strict=True):
        np.testing.assert_allclose(got, want, atol=1e-9)
    # And the other way round, from random direction pairs of the upper hemisphere.
    a = coords.spherical(rng.uniform(0, 1.5, n), rng.uniform(0, 6.28, n))
    b = coords.spherical(rng.uniform(0, 1.5, n), rng.uniform(0, 6.28, n))
    wi2, wo2 = coords.half_diff_to_io(*coords.io_to_half_diff(a, b))
    np.testing.assert_allclose(wi2, a, atol=1e-9)
    np.testing.assert_allclose(wo2, b, atol=1e-9)


def test_plane_of_incidence_convention():
    for phi in (0.0, 70.0):
        wi = coords.incident(35.0, phi)
        w = coords.plane_directions([35.0, -35.0, 0.0], phi)
        np.testing.assert_allclose(w[0], [-wi[0], -wi[1], wi[2]], atol=1e-12)  # +θ_i: the mirror direction
        np.testing.assert_allclose(w[1], wi, atol=1e-12)  # −θ_i: ω_i itself
        np.testing.assert_allclose(w[2], [0, 0, 1], atol=1e-12)


def test_albedo_of_diffuse_and_plugin_path():
    """Quadrature of a generic BSDF (hemisphere path) is exact for Lambert and matches the furnace's for a conductor."""
    from brdflab.bsdf.diffuse import Diffuse

    class Opaque:  # not a built-in class: takes the generic quadrature
        def __init__(self, b):
            self.eval, self.sample = b.eval, b.sample

    rc = RoughConductor(1.0, 0.2)
    alb = views.albedo([Diffuse(0.5), Opaque(rc), rc], thetas=(0.0, 60.0, 85.0), n=4000, seed=3)
    np.testing.assert_allclose(alb.quadrature[0], 0.5, atol=1e-9)
    np.testing.assert_allclose(alb.quadrature[1], alb.quadrature[2], atol=2e-5)
    assert np.all(np.abs(alb.monte_carlo - alb.quadrature) <= 5 * alb.mc_stderr + 1e-6)


@pytest.fixture(scope="module")
def plot_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("plot") / "rc"
    assert main(["plot", "--bsdf", "roughconductor", "--alpha", "0.1", "--param", "R0=0.9", "--theta", "45",
                 "--size", "32", "--spp", "2", "--samples", "2000", "--workers", "1", "-o", str(out)]) == 0
    return out


def test_plot_writes_every_view(plot_dir):
    for view in ("polar", "lobe", "slice", "albedo", "sphere"):
        for ext in ("png", "svg"):
            assert (plot_dir / f"{view}.{ext}").stat().st_size > 1000, (view, ext)
    for name in ("polar.csv", "lobe.csv", "slice.csv", "albedo.csv", "sphere_0_0.exr", "sphere_0_1.exr"):
        assert (plot_dir / name).exists(), name
    page = (plot_dir / "index.html").read_text()
    assert page.count("data:image/png;base64,") >= 5
    assert not re.search(r"""(src|href)=["']?(https?:|//)""", page), "index.html must be self-contained"
    assert not list(plot_dir.parent.glob(".rc.*")), "temporary folder left behind"


def test_polar_csv_matches_eval(plot_dir):
    text = (plot_dir / "polar.csv").read_text()
    assert "positive angles lie on the side opposite omega_i's azimuth" in text
    header, data = _read_csv(plot_dir / "polar.csv")
    assert header[:2] == ["theta_o_deg", "cos_theta_o"] and len(header) == 3
    t = np.radians(data[:, 0])
    wo = np.stack([-np.sin(t), np.zeros_like(t), np.cos(t)], axis=1)  # φ_i = 0: ω_i in the +x half of x–z
    wi = np.tile([np.sin(np.radians(45.0)), 0.0, np.cos(np.radians(45.0))], (len(t), 1))
    f = RoughConductor(R0=0.9, alpha=0.1).eval(wi, wo)
    np.testing.assert_allclose(data[:, 2], f[:, 0], rtol=1e-8, atol=1e-12)
    assert data[np.argmax(data[:, 2]), 0] == pytest.approx(45.0, abs=3.0)  # peak near the mirror direction
    assert np.all(data[data[:, 0] < 0, 2] < data[:, 2].max() * 1e-3)  # back-scattering side is dark


def test_other_csvs_match_eval(plot_dir):
    header, data = _read_csv(plot_dir / "slice.csv")
    assert header[:2] == ["theta_h_deg", "theta_d_deg"]
    rows = data[np.isfinite(data[:, 2])][::97]
    wi, wo = coords.half_diff_to_io(np.radians(rows[:, 0]), 0.0, np.radians(rows[:, 1]), np.radians(90.0))
    np.testing.assert_allclose(rows[:, 2], RoughConductor(0.9, 0.1).eval(wi, wo)[:, 0], rtol=1e-6, atol=1e-9)
    header, data = _read_csv(plot_dir / "albedo.csv")
    assert header[0] == "theta_i_deg" and len(header) == 4
    assert np.all(np.abs(data[:, 1] - data[:, 2]) <= 5 * data[:, 3] + 1e-3)
    assert np.all(data[:, 1] <= 1.0)


def test_plot_bad_bsdf_spec_is_a_clean_error(tmp_path, capsys):
    out = tmp_path / "nothing"
    assert main(["plot", "--bsdf", "roughconductor:alpha", "-o", str(out)]) == 2
    assert "--bsdf" in capsys.readouterr().err
    assert main(["plot", "--bsdf", "nosuchbsdf", "-o", str(out)]) == 2
    assert not out.exists()


PLUGIN = '''
import numpy as np
import brdflab as bl


class TinyPhong(bl.BSDF):
    """Normalised Phong lobe about the mirror direction, sampled cosine-weighted (test plugin)."""

    type_name = "tinyphong_viz"

    def __init__(self, ks=0.8, exponent=30.0):
        self.ks, self.exponent = float(ks), float(exponent)

    def eval(self, wi, wo, uv=None):
        mirror = wi * np.array([-1.0, -1.0, 1.0])
        c = np.clip(np.sum(mirror * wo, axis=1), 0.0, 1.0)
        up = (wi[:, 2] > 0) & (wo[:, 2] > 0)
        f = self.ks * (self.exponent + 2) / (2 * np.pi) * c**self.exponent * up
        return np.repeat(f[:, None], 3, axis=1)

    def pdf(self, wi, wo, uv=None):
        return np.where((wi[:, 2] > 0) & (wo[:, 2] > 0), wo[:, 2] / np.pi, 0.0)

    def sample(self, wi, u, uv=None):
        wo = bl.warps.square_to_cosine_hemisphere(u[:, :2])
        pdf = self.pdf(wi, wo)
        w = self.eval(wi, wo) * np.where(pdf > 0, wo[:, 2] / np.maximum(pdf, 1e-300), 0.0)[:, None]
        return bl.BSDFSample(wo, w, pdf)
'''


def test_plot_overlays_builtins_and_a_plugin(tmp_path):
    from brdflab.plugins import unregister_bsdf

    plugin = tmp_path / "tinyphong.py"
    plugin.write_text(PLUGIN)
    out = tmp_path / "overlay"
    try:
        assert main(["plot", "--plugin", str(plugin), "--bsdf", "roughconductor", "--bsdf", "roughsubstrate:kd=0.3",
                     "--bsdf", "tinyphong_viz:exponent=50", "--alpha", "0.2", "--param", "R0=0.9", "--theta", "30",
                     "--views", "polar,albedo,sphere", "--size", "24", "--spp", "1", "--samples", "4000",
                     "--workers", "1", "-o", str(out)]) == 0
        header, data = _read_csv(out / "polar.csv")
        assert header[2:] == ["roughconductor alpha=0.2 R0=0.9", "roughsubstrate alpha=0.2 kd=0.3",
                              "tinyphong_viz exponent=50"]
        from brdflab.plugins import make_bsdf

        t = np.radians(data[:, 0])
        wo = np.stack([-np.sin(t), np.zeros_like(t), np.cos(t)], axis=1)
        wi = np.tile(coords.incident(30.0), (len(t), 1))
        for col, bsdf in zip((2, 3, 4), (RoughConductor(R0=0.9, alpha=0.2),
                                         make_bsdf("roughsubstrate", {"kd": 0.3}, alpha=0.2),
                                         make_bsdf("tinyphong_viz", {"exponent": "50"})), strict=True):
            np.testing.assert_allclose(data[:, col], bsdf.eval(wi, wo)[:, 1], rtol=1e-8, atol=1e-12)
        _, alb = _read_csv(out / "albedo.csv")
        phong_q, phong_mc, phong_se = alb[:, 7], alb[:, 8], alb[:, 9]
        assert np.all(np.abs(phong_q - phong_mc) <= 5 * phong_se + 1e-3)
        assert (out / "sphere_2_1.exr").exists() and "tinyphong_viz" in (out / "index.html").read_text()
    finally:
        unregister_bsdf("tinyphong_viz")


def test_bsdf_spec_syntax():
    from brdflab.viz.spec import resolve

    specs = resolve(["roughconductor:R0=0.95,0.64,0.54,alpha=0.3", "roughconductor", "diffuse"], [0.05, 0.5],
                    ["R0=0.9"])
    assert [(s.name, s.params, s.alpha) for s in specs] == [
        ("roughconductor", {"R0": "0.95,0.64,0.54", "alpha": "0.3"}, None),
        ("roughconductor", {"R0": "0.9"}, 0.05), ("roughconductor", {"R0": "0.9"}, 0.5), ("diffuse", {}, None)]
    assert specs[1].label == "roughconductor alpha=0.05 R0=0.9"
