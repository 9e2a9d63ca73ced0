"""Readable chi-square pages: (φ′, cos θ′) views, residual maps that locate a fault, negative-control verdicts."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from brdflab.cli.main import main
from brdflab.judges.material import chi2 as c2
from brdflab.judges.material.battery import NoJacobianConductor, run_chi2
from brdflab.pages import chi2_views as cv

EXAMPLE = Path(__file__).resolve().parent.parent / "examples" / "skewed_sampler.py"


def test_residual_map_locates_a_skewed_azimuth(tmp_path):
    """The example's sampler squares ξ₂ (half-vector azimuth): the page fails it and the residual map is
    strongly positive in a narrow azimuth band and negative elsewhere; a correct sampler's map is noise."""
    from brdflab.plugins import make_bsdf, unregister_bsdf

    out = tmp_path / "skewed"
    try:
        assert main(["chi2", "--plugin", str(EXAMPLE), "--bsdf", "skewed_azimuth_conductor", "--alpha", "0.3",
                     "--theta", "45", "--samples", "30000", "-o", str(out)]) == 1
        page = (out / "index.html").read_text()
        assert 'class="badge fail"' in page and "chi2_view" not in page  # figures are embedded, not linked
        assert page.count("data:image/png;base64,") >= 2
        bsdf = make_bsdf("skewed_azimuth_conductor", alpha=0.3)
        r = c2.bsdf_test("skewed_azimuth_conductor", bsdf, 45.0, 30_000, seed=5, params={"alpha": 0.3, "theta": 45.0})
        view = cv.view_of(r, 60_000, seed=6)
    finally:
        unregister_bsdf("skewed_azimuth_conductor")
    res = np.nan_to_num(view.residual)
    by_phi = res.sum(axis=0) / np.sqrt(res.shape[0])  # per azimuth column, ~N(0, 1) per column for a correct sampler
    hot = np.flatnonzero(by_phi > 10)
    assert 0 < len(hot) <= res.shape[1] // 4, by_phi  # a narrow band of azimuths is sampled far too often …
    assert np.sum(by_phi < -3) >= res.shape[1] // 3  # … and most other azimuths too rarely
    # Control: the correct conductor, same view: residuals are noise.
    good = run_chi2([("bsdf", "roughconductor", 0.3, 45.0)], 30_000, 1e-3)[0]
    gv = cv.view_of(good, 60_000, seed=7)
    g = np.nan_to_num(gv.residual)
    assert good.passed and np.abs(g.sum(axis=0) / np.sqrt(g.shape[0])).max() < 6
    assert np.mean(g[gv.expected > 20] ** 2) < 2.0  # E[r²] ≈ 1 for Poisson counts


def test_negative_control_is_shown_as_rejected(tmp_path):
    from brdflab.judges.material.battery import Battery
    from brdflab.pages.validation import write_validation_report

    neg = c2.bsdf_test("roughconductor without Jacobian", NoJacobianConductor(0.5, 0.3), 30.0, 20_000, seed=1,
                       params={"alpha": 0.3, "theta": 30.0})
    ok = run_chi2([("warp", "uniform_disk", None, None), ("warp", "beckmann", 0.1, None)], 20_000, 1e-3)
    bat = Battery(chi2=ok, negative_control=[neg], threshold=1e-3)
    path = write_validation_report(bat, tmp_path / "rep", view_samples=20_000)
    page = path.read_text()
    assert not neg.passed
    assert "rejected, as it must be" in page
    assert re.search(r'badge rejected">θ_i = 30°: p = [^<]*rejected, as it must be', page)
    assert "everything passed" in page  # a rejected negative control is not a failure
    assert page.count('class="fig"') >= 3  # detailed views: the negative control and both warps
    assert not re.search(r"""(src|href)=["']?(https?:|//)""", page)
