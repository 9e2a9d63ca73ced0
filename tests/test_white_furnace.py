"""The white furnace under path tracing (issue 44): the renders against computations that do not use the renderer.

* a non-transmissive BSDF on a convex sphere scatters once, so each pixel reads the directional albedo ρ(μ) by
  quadrature at its own μ (analytic ray–sphere intersection), pixel by pixel;
* a smooth dielectric sphere, diffuse with albedo 1 and the mirror are lossless: 1 within noise;
* a negative control: a conductor whose R0 is 0.9 instead of 1 is told apart from the R0 = 1 prediction.
"""

from __future__ import annotations

import numpy as np

import brdflab as bl
from brdflab.judges.material.entries import make_named_bsdf
from brdflab.viz import white_furnace as wf

SIZE, SPP = 32, 32


def _render(bsdfs):
    return wf.render_furnace(bsdfs, None, SIZE, SPP, seed=3, workers=1)


def test_non_transmissive_pixels_read_the_directional_albedo():
    bsdfs = [make_named_bsdf("roughconductor", 0.6, {"R0": "1"}), make_named_bsdf("roughsubstrate", 0.3, {"kd": "1"})]
    res, mask, mu = _render(bsdfs)
    inner = mask & (mu.min(axis=2) > 0.3)  # away from the silhouette, where the tessellation differs most
    assert inner.sum() > 200
    for b, r in zip(bsdfs, res, strict=True):
        want = wf.single_scattering(b, mu).mean(axis=2)
        # pixel by pixel, then pooled in rings of μ (pixels are independent: the error's spread gives the σ)
        err, m = (r.image - want)[inner], mu.mean(axis=2)[inner]
        z = []
        for lo, hi in zip(np.linspace(0.3, 1.0, 6)[:-1], np.linspace(0.3, 1.0, 6)[1:], strict=True):
            e = err[(m >= lo) & (m < hi + 1e-9)]
            z.append(e.mean() / (e.std(ddof=1) / np.sqrt(len(e))))
        assert np.max(np.abs(z)) < 4.0, (r.label, np.round(z, 2))
        assert np.abs(err).mean() < 0.15  # no pixel far off (32 spp of one bounce)
        pred = wf.predicted_losses([b], [r], mask, mu)[r.label]
        assert abs(r.loss - pred) < 4 * r.stderr + 3e-3, (r.label, r.loss, pred, r.stderr)
        assert r.loss > 0.05  # these do lose energy at this roughness


def test_lossless_materials_read_one():
    bsdfs = [make_named_bsdf(n, None, p) for n, p in (("dielectric", {}), ("mirror", {}), ("diffuse", {"albedo": "1"}))]
    res, mask, mu = _render(bsdfs)
    for r in res:
        assert abs(r.mean - 1.0) < 4 * r.stderr + 2e-3, (r.label, r.mean, r.stderr)


def test_a_conductor_with_r0_09_is_told_from_r0_1():
    """Negative control: the prediction of R0 = 1 must reject the render of R0 = 0.9."""
    right = make_named_bsdf("roughconductor", 0.3, {"R0": "1"})
    wrong = make_named_bsdf("roughconductor", 0.3, {"R0": "0.9"})
    res, mask, mu = _render([wrong])
    pred = wf.predicted_losses([right], res, mask, mu)[res[0].label]
    assert abs(res[0].loss - pred) > 4 * res[0].stderr + 3e-3


def test_figure_keeps_its_legend_inside(tmp_path):
    res = [wf.FurnaceResult("roughconductor alpha=0.1", 0.1, 0.99, 1e-3, 16, np.zeros((2, 2))),
           wf.FurnaceResult("roughconductor alpha=0.5", 0.5, 0.9, 1e-3, 16, np.zeros((2, 2))),
           wf.FurnaceResult("dielectric", None, 1.0, 1e-3, 16, np.zeros((2, 2)))]
    fig = wf.furnace_figure(res, {"roughconductor alpha=0.1": 0.01, "roughconductor alpha=0.5": 0.1})
    fig.savefig(tmp_path / "f.png")
    ax = fig.axes[0]
    leg = ax.get_legend()
    renderer = fig.canvas.get_renderer()
    assert ax.get_window_extent(renderer).contains(*leg.get_window_extent(renderer).p0)
    assert ax.get_window_extent(renderer).contains(*leg.get_window_extent(renderer).p1)


# -- validate's page (issue 44: "as a plot view and in validate's page") --

class _UserLambert(bl.BSDF):
    """A user's BSDF (not a built-in): albedo 0.8 Lambertian, its single-bounce loss is 20 %."""

    type_name = "user_lambert"

    def eval(self, wi, wo, uv=None):
        return (((wi[:, 2] > 0) & (wo[:, 2] > 0)) * (0.8 / np.pi))[:, None] * np.ones(3)

    def pdf(self, wi, wo, uv=None):
        return np.where((wi[:, 2] > 0) & (wo[:, 2] > 0), wo[:, 2] / np.pi, 0.0)

    def sample(self, wi, u, uv=None):
        from brdflab.math.warps import square_to_cosine_hemisphere

        wo = square_to_cosine_hemisphere(u)
        return bl.BSDFSample(wo, np.full((len(u), 3), 0.8), self.pdf(wi, wo))


class _Raising(_UserLambert):
    type_name = "user_raising"

    def sample(self, wi, u, uv=None):
        raise RuntimeError("boom")


def _csv(path):
    import csv

    with open(path, newline="") as f:
        return list(csv.reader(line for line in f if not line.startswith("#")))


def test_validate_page_carries_the_furnace_with_the_plot_views_numbers(tmp_path):
    from brdflab.judges.material.entries import FURNACE_ALPHAS

    bat = bl.validate(["roughconductor", "dielectric"], samples=2000, thetas=[30], alphas=[0.3],
                      output=tmp_path / "val", furnace_render="quick")
    run = bat.white_furnace
    size, spp = wf.LEVELS["quick"]
    assert [r.label for r in run.results] == [f"roughconductor R0=1 alpha={a:g}" for a in FURNACE_ALPHAS] + \
        ["dielectric"]
    assert (run.size, run.spp) == (size, spp) and all(r.spp == spp and not r.error for r in run.results)
    html = (tmp_path / "val" / "index.html").read_text()
    assert "White furnace under path tracing" in html and (tmp_path / "val" / "furnace.png").stat().st_size > 0
    for r in run.rows():
        assert f"{100 * r['loss']:+.2f} % ± {200 * r['stderr']:.2f}" in html  # the table
    # the plot view of the same BSDFs in the same order: the same numbers, figure for figure
    objs = [make_named_bsdf("roughconductor", a, {"R0": "1"}) for a in FURNACE_ALPHAS] + \
        [make_named_bsdf("dielectric", None, {})]
    bl.plot(objs, tmp_path / "plot", views=["furnace"], size=size, spp=spp // wf.SPP_FACTOR,
            labels=[r.label for r in run.results])
    got, want = _csv(tmp_path / "val" / "furnace.csv"), _csv(tmp_path / "plot" / "furnace.csv")
    assert got == want and len(got) == 7
    assert got[-1][-1] == "" and all(row[-1] for row in got[1:-1])  # no single-bounce quadrature for glass


def test_validate_furnace_of_plugins_and_a_raising_one():
    """A user's BSDF renders through the generic path (its loss: 1 − albedo); one that raises gets its row
    with the error while the others still render."""
    run = wf.battery_furnace([("user_lambert", lambda a, p: _UserLambert()),
                              ("user_raising", lambda a, p: _Raising())], level="quick")
    ok, bad = run.results
    assert not ok.error and abs(ok.loss - 0.2) < 4 * ok.stderr + 2e-3, (ok.loss, ok.stderr)
    assert abs(run.predicted["user_lambert"] - 0.2) < 1e-3
    assert "RuntimeError" in bad.error and "user_raising.sample()" in bad.error and np.isnan(bad.loss)
    assert "user_raising,,nan" in wf.csv_text(run.results, run.predicted, "validate")  # the CSV keeps the row
    assert [r["bsdf"] for r in run.rows()] == ["user_lambert", "user_raising"]


def test_validate_furnace_render_off_and_bad_level(tmp_path):
    import pytest

    from brdflab.errors import BrdflabError

    bat = bl.validate(["diffuse"], samples=2000, thetas=[30], output=tmp_path, furnace_render="off")
    assert bat.white_furnace is None and not (tmp_path / "furnace.png").exists()
    with pytest.raises(BrdflabError, match="furnace_render"):
        bl.validate(["diffuse"], samples=2000, thetas=[30], furnace_render="fast")


def test_figure_reads_in_grey_print():
    """Every material has its own marker and its own line style (not colour alone)."""
    res = [wf.FurnaceResult(f"{n} alpha={a}", a, 1 - a * k / 10, 1e-3, 16, np.zeros((2, 2)))
           for k, n in enumerate(("roughconductor", "roughdielectric", "roughsubstrate"), 1) for a in (0.1, 0.5)]
    res += [wf.FurnaceResult(n, None, 1.0, 1e-3, 16, np.zeros((2, 2))) for n in ("mirror", "dielectric", "diffuse")]
    fig = wf.furnace_figure(res)
    leg = fig.axes[0].get_legend()
    assert len(leg.get_texts()) == 6
    lines = [ln for ln in fig.axes[0].get_lines() if ln.get_marker() not in ("None", None, "")
             and ln.get_linestyle() not in ("None", "")]  # the renders' lines (not the hollow quadrature marks)
    assert len({ln.get_marker() for ln in lines}) == 6
    assert len({repr(ln._dash_pattern) for ln in lines}) == 6  # (offset, dashes) as drawn
