"""The white furnace under path tracing (issue 44): the renders against computations that do not use the renderer.

* a non-transmissive BSDF on a convex sphere scatters once, so each pixel reads the directional albedo ρ(μ) by
  quadrature at its own μ (analytic ray–sphere intersection), pixel by pixel;
* a smooth dielectric sphere, diffuse with albedo 1 and the mirror are lossless: 1 within noise;
* a negative control: a conductor whose R0 is 0.9 instead of 1 is told apart from the R0 = 1 prediction.
"""

from __future__ import annotations

import numpy as np

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
