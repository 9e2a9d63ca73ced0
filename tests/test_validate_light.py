"""``brdflab validate`` on light transport: emitter samplers (chi-square by area, environment directions,
sample().pdf against the hit pdf) with their negative controls, and the battery/report hook."""

from __future__ import annotations

import numpy as np

import brdflab as bl
from brdflab.emitter.area import DiscreteChooser
from brdflab.judges.estimators import agreement
from brdflab.judges.lights import samplers as emitters
from brdflab.judges.material.battery import Battery, run_battery
from brdflab.scene.loader import load_scene
from tests.conftest import ROOT

N = 40_000


def test_area_and_fused_light_samplers_pass():
    """Triangle-mesh light (faceted sphere), planar hexagon + smooth sphere and their fused set, the
    parallelogram quad light: points uniform by area; and sample().pdf equals the hit pdf."""
    for rel in ("scenes/lights/polygon_lights_mis.xml", "scenes/cbox/cbox_diffuse.xml"):
        s = load_scene(ROOT / rel)
        s.set_emitter_selection("power")
        chi, pdfs = bl.emitter_checks(s, n=N, seed=1)
        assert len(chi) == len(s.emitters) + (len(s.emitters) > 1)
        assert all(r.passed for r in chi), [(r.name, r.p_value) for r in chi]
        assert all(r.passed for r in pdfs), [(r.name, r.compared, r.max_rel_error) for r in pdfs]
        assert all(r.compared >= emitters.MIN_COMPARED for r in pdfs)


def test_environment_and_point_light_checks():
    s = load_scene(ROOT / "scenes/lights/mixed_lights_mis.xml")
    chi, pdfs = bl.emitter_checks(s, n=N, seed=2)
    assert {r.name for r in chi} == {"environment 1", "area light 2"} and all(r.passed for r in chi)
    assert any("point light" in r.name for r in pdfs) and all(r.passed for r in pdfs)
    env = load_scene(ROOT / "scenes/envlit/envlit_mis.xml").environment
    assert emitters.environment_test("sky", env, N, seed=3).passed


def test_negative_controls_are_rejected():
    """Each deliberately broken sampler/pdf fails its check: triangles chosen uniformly instead of by area,
    an environment pdf without 1/sin θ, a hit pdf without the light's cosine, and points off the light."""
    out = emitters.negative_controls(n=N)
    assert len(out) == 3 and all(rejected for _, rejected, _ in out), out
    # A sampler that misses the light (points 1 % too far) is rejected outright.
    s = load_scene(ROOT / "scenes/lights/sphere_light_mis.xml")
    em = s.emitters[0]
    ref, _ = emitters.reference_points(s, seed=4)
    areas = em.geometry.tri_area[em.tris]

    def far(x, u):
        r = em.sample(x, u)
        return r.wi, r.dist * 1.01

    r = emitters.area_points_test("too far", far, emitters.emitter_triangles(em), areas / areas.sum(), ref, 5000, 5)
    assert not r.passed and r.valid_fraction < 0.5
    # The fused set with a selection pmf that differs from the one it samples by is rejected.
    s = load_scene(ROOT / "scenes/lights/polygon_lights_mis.xml")
    ref, _ = emitters.reference_points(s, seed=6)
    fused_ok = emitters.fused_set_test("fused", s, ref, N, 7)
    assert fused_ok.passed
    from brdflab.integrator.common import area_light_set

    fused = area_light_set(s)
    fused.chooser = DiscreteChooser(np.ones(len(fused.chooser.pmf)))  # every triangle equally likely
    assert not emitters.fused_set_test("fused, wrong choice", s, ref, N, 8).passed


def test_subtriangle_cells_have_equal_area():
    rng = np.random.default_rng(9)
    u = rng.random((200_000, 2))
    f = u.sum(axis=1) > 1
    u[f] = 1 - u[f]
    for n in (1, 2, 3, 4):
        c = np.bincount(emitters.subtriangle_cell(u, n), minlength=n * n)
        assert len(c) == n * n
        expected = len(u) / (n * n)
        assert np.abs(c - expected).max() < 5 * np.sqrt(expected)


def test_battery_hook_and_report(tmp_path, monkeypatch):
    """run_battery(light_transport=True) fills the light-transport fields, counts them in the verdict, and
    the report shows them; a failed agreement or an unrejected control fails the battery."""
    from brdflab.pages.validation import write_validation_report

    s = load_scene(ROOT / "scenes/cbox/cbox_diffuse.xml")
    chi, pdfs = bl.emitter_checks(s, n=10_000)
    good = agreement.AgreementResult("scene (uniform)", 0.5, 40, "ems vs mis, block 3", {"direct_ems": 0.1})
    bad = agreement.AgreementResult("scene [negative control]", 1e-9, 40, "ems vs mats", {"direct_ems": 0.05})
    monkeypatch.setattr(emitters, "run", lambda n, progress=None: (chi, pdfs))
    monkeypatch.setattr(emitters, "negative_controls", lambda n, progress=None: [("broken", True, "p = 0")])
    monkeypatch.setattr(agreement, "run", lambda progress=None: ([good], [bad]))
    bat = run_battery(n=10_000, bsdfs=["diffuse"], warp_names=[], thetas=(30.0,), light_transport=True)
    assert bat.emitter_chi2 == chi and bat.agreement == [good] and bat.agreement_negative == [bad]
    assert bat.light_transport_passed and bat.passed, bat.failures()
    html = write_validation_report(bat, tmp_path).read_text()
    assert "Estimator agreement" in html and "Emitter samplers" in html and "rejected, as it must be" in html
    assert not run_battery(n=2000, bsdfs=["diffuse"], warp_names=[], thetas=(30.0,), full=False).agreement
    for broken in (Battery(agreement=[bad]), Battery(agreement_negative=[good]),
                   Battery(emitter_negative=[("x", False, "")])):
        assert not broken.passed and broken.failures()
