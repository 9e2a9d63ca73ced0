"""``brdflab check`` says where and what (brdflab/stats/attribution.py): planted bugs are attributed to the
strategy that carries them, an unbiased difference to nothing definite."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import stats

import brdflab.integrator.direct_mis as dm
from brdflab.cli.main import main
from brdflab.imageio import write_exr
from brdflab.scene.geometry import Geometry
from brdflab.stats import attribution as A
from brdflab.stats.jobs import RenderJob, run_job, run_seed
from brdflab.stats.render_check import Estimate, check_images
from tests.conftest import ROOT

CBOX = ROOT / "scenes" / "cbox" / "cbox_diffuse.xml"
SPHERES = ROOT / "scenes" / "cbox" / "cbox_spheres_mis.xml"
RES = (64, 64)


def _render(scene, integrator: str, seed: int, spp: int = 32) -> np.ndarray:
    return run_job(RenderJob(scene, integrator, spp, seed, RES, 1))[0]


def _shadow_bug(monkeypatch):
    """The student's bug: the shadow ray reaches past the light point, so the light itself blocks it (planted in
    the NumPy code: the compiled engine builds its shadow rays in :mod:`brdflab.kernels.direct`)."""
    monkeypatch.setenv("BRDFLAB_ENGINE", "numpy")
    orig = Geometry.shadow_occluded
    monkeypatch.setattr(Geometry, "shadow_occluded",
                        lambda self, p, ng, w, dist, idx: orig(self, p, ng, w, dist * 1.01 + 1e-3, idx))


def _bsdf_bug(monkeypatch):
    """A BSDF-sampling bug in direct_mis: the BSDF samples' contributions are dropped (weight 0)."""
    orig = dm.bsdf_rays

    def bug(scene, sp, u):
        live, weight, pdf, le, p_l = orig(scene, sp, u)
        return live, weight * 0.0, pdf, le, p_l

    monkeypatch.setattr(dm, "bsdf_rays", bug)


_SETUP: dict = {}


def _setup(scene, seed: int):
    """brdflab's estimate (3 × 32 spp direct_mis) and the auxiliary images (16 spp), once per scene."""
    if (scene, seed) not in _SETUP:
        est = Estimate.from_runs([_render(scene, "direct_mis", run_seed(seed, k, "reference")) for k in range(3)],
                                 run_spp=32)
        _SETUP[scene, seed] = est, A.render_aux(scene, 16, seed, RES, 1)
    return _SETUP[scene, seed]


def _attribute(scene, integrator: str, bug, monkeypatch, seed: int = 0, user_seed: int = 0):
    est, aux = _setup(scene, seed)
    with monkeypatch.context() as m:
        if bug is not None:
            bug(m)
        user = _render(scene, integrator, run_seed(seed, user_seed, "check"))
    res = check_images([user], est, user_spp=32)
    return res, A.attribute(res, [user], aux, integrator, estimate=est.mean)


def test_shadow_bug_follows_emitter_sampled_light(monkeypatch):
    res, att = _attribute(CBOX, "direct_mis", _shadow_bug, monkeypatch)
    assert not res.consistent and res.dark_blocks > 0
    w = att["whole_image"]
    assert "follows emitter-sampled light" in w["finding"], w
    a, b = w["fit"]["coef"]
    assert abs(a + 1.0) < 0.1  # all emitter-sampled light is lost
    big = att["regions"][0]
    assert big["sign"] == "too dark" and "follows emitter-sampled light" in big["finding"]
    assert big["emitters"][0]["name"].startswith("area #0") and big["emitters"][0]["share"] == pytest.approx(1.0)
    assert big["materials"][0]["name"].startswith("diffuse #0") and "white.obj" in big["materials"][0]["name"]
    lines = A.attribution_lines(att)
    assert 2 <= len(lines) <= 2 + A.PRINTED and "emitter-sampled" in lines[0]


def test_shadow_bug_in_direct_ems_names_light_sampling(monkeypatch):
    """The student's case: direct_ems with the shadow bug (every sample comes from light sampling)."""
    res, att = _attribute(CBOX, "direct_ems", _shadow_bug, monkeypatch, user_seed=1)
    assert not res.consistent
    f = att["whole_image"]["finding"]
    assert "light sampling" in f and "BSDF-sampled" not in f, f


def test_bsdf_bug_follows_bsdf_sampled_light(monkeypatch):
    res, att = _attribute(SPHERES, "direct_mis", _bsdf_bug, monkeypatch)
    assert not res.consistent
    w = att["whole_image"]
    assert "follows BSDF-sampled light" in w["finding"], w
    assert w["fit"]["coef"][1] < -0.5


def test_unbiased_render_is_not_attributed(monkeypatch):
    res, att = _attribute(SPHERES, "direct_mis", None, monkeypatch, user_seed=2)
    assert res.consistent
    assert "nothing definite" in att["whole_image"]["finding"]


def test_one_emitter_wrong_is_named():
    """Two area lights; the user's renderer halves the radiance of emitter 1 only."""
    from brdflab.renderer import render
    from brdflab.stats.jobs import load_for

    scene, res = ROOT / "scenes" / "lights" / "polygon_lights_ems.xml", (96, 72)
    est = Estimate.from_runs([run_job(RenderJob(scene, "direct_ems", 16, run_seed(3, k, "reference"), res, 1))[0]
                              for k in range(3)], run_spp=16)
    aux = A.render_aux(scene, 8, 3, res, 1)
    s = load_for(RenderJob(scene, "direct_ems", 16, 0, res, 1))
    s.emitters[1].scale *= 0.5
    user, _ = render(s, spp=16, seed=run_seed(3, 0, "check"), workers=1)
    r = check_images([user], est, user_spp=16)
    att = A.attribute(r, [user], aux, "direct_ems", estimate=est.mean)
    assert not r.consistent
    assert "only the light of area #1" in att["whole_image"]["finding"], att["whole_image"]
    assert len(att["whole_image"]["emitter_fit"]["coef"]) == 2


def test_fit_false_findings_and_power_synthetic():
    """On null data (noise only) a definite finding is rare: measured over 300 datasets, at most the
    binomial bound of 2·LEVEL (either part); a planted −0.3·E is found except where B is significant by
    chance (the same bound)."""
    rng = np.random.default_rng(7)
    yy, xx = np.mgrid[0:48, 0:48]
    e = 1.0 + np.sin(xx / 7.0) + 0.5 * (yy / 48.0)
    b = 0.3 + 0.3 * np.cos(yy / 5.0) * (xx / 48.0)
    mask = np.ones(e.shape, bool)
    definite = 0
    for _ in range(300):
        noise = rng.gamma(2.0, 0.05, e.shape) - 0.1
        f = A.fit_cells(noise, [e + 0.02 * rng.standard_normal(e.shape), b], ["E", "B"], mask, 4)
        definite += "follows" in A.interpret(f, -1)
    assert definite <= stats.binom.isf(0.01, 300, 2 * A.LEVEL), definite
    found = 0
    for _ in range(100):
        noise = rng.gamma(2.0, 0.05, e.shape) - 0.1
        f = A.fit_cells(noise - 0.3 * e, [e, b], ["E", "B"], mask, 4)
        found += "follows emitter-sampled" in A.interpret(f, -1)
        assert "BSDF-sampled" not in A.interpret(f, -1)
    assert 100 - found <= stats.binom.isf(0.01, 100, 2 * A.LEVEL), found


def test_lone_emitter_needs_the_others_near_zero():
    f = A.Fit([-1.0, -0.05], [0.1, 0.1], [1e-9, 0.6], 50, ["a", "b"])
    assert A.lone_emitter(f, -1) == 0
    f = A.Fit([-1.0, -0.7], [0.1, 0.3], [1e-9, 0.03], 50, ["a", "b"])  # the other could be as large
    assert A.lone_emitter(f, -1) is None


def test_check_cli_prints_where_and_what(tmp_path, monkeypatch, capsys):
    scene = tmp_path / "cb.xml"
    scene.write_text(CBOX.read_text().replace('"512"', '"64"').replace("meshes/", str(CBOX.parent / "meshes") + "/"))
    with monkeypatch.context() as m:
        _shadow_bug(m)
        bad = _render(scene, "direct_ems", 11, 16)
    write_exr(tmp_path / "bad.exr", bad, extra={"brdflab_spp": "16"})
    assert main(["check", str(tmp_path / "bad.exr"), "--scene", str(scene), "--spp", "16", "--runs", "2",
                 "--levels", "1", "--where-spp", "4", "--workers", "1", "-o", str(tmp_path / "c")]) == 1
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("BIASED") and out[1].startswith("where and what") and "region 1" in out[2]
    d = json.loads((tmp_path / "c" / "check.json").read_text())
    assert d["attribution"]["whole_image"]["fit"]["cells"] > 10
    assert "Where and what" in (tmp_path / "c" / "check.html").read_text()


def test_docstring_examples_run():
    import doctest

    assert doctest.testmod(A).failed == 0
