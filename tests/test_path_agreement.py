"""``path``, ``path_nee`` and ``path_mis`` converge to the same image; the student bugs of spec §13.2.7–8 do not.

Estimator agreement (:mod:`brdflab.judges.estimators.agreement`: replicate renders with independent seeds, Welch
t-tests per pixel block, Šidák over blocks and pairs, verdict at 0.01) on two bundled scenes:

* ``cbox/cbox_glass`` — a mirror and a glass sphere in the Cornell box: delta vertices (emission found after
  them counts for ``path_nee``; MIS weight 1), refraction in and out, caustics;
* ``lights/mixed_lights`` — a triangle light, a point light and a constant environment over a diffuse and a
  glossy floor: the environment as an emitter under NEE and MIS, a delta light (``path`` cannot see it, so it
  is compared on the scene without it).

False alarms: 0 of 12 independent seeds on each scene at this test's settings (smallest family-wise p-values 0.13 on
mixed_lights and 0.17 on cbox_glass; measured 2026-12-04).

Negative controls (each must be rejected), planted by replacing one function of
:mod:`brdflab.integrator.wavefront` (the tests run in this process, ``workers=1``):

* NEE at delta vertices only — the inverted condition of the student's ``path_nee``;
* BSDF-found emission counted twice in ``path_mis`` (MIS-weighted, then again unweighted);
* ``path_nee`` dropping the emission found after a delta sample (the light seen in the mirror and through the
  glass) — only a scene with delta materials can show this one.

The direct integrators on delta materials (``direct_mats`` = ``direct_mis``; ``direct_ems`` adds nothing at a
delta vertex) and the light term through a transmitting material (a rough glass pane lit from behind: |cos θ_o|)
are checked here too, each with its negative control.
"""

from __future__ import annotations

import numpy as np
import pytest

import brdflab as bl
from brdflab.integrator import wavefront
from brdflab.judges.estimators import agreement as ag
from tests.conftest import ROOT, write_scene

GLASS = (ROOT / "scenes" / "cbox" / "cbox_glass_mis.xml", {"width": 48, "height": 48})
MIXED = (ROOT / "scenes" / "lights" / "mixed_lights_mis.xml", {})
_weight, _mask = wavefront.bsdf_emission_weight, wavefront.nee_mask


def agree(scene) -> ag.AgreementResult:
    path, size = scene
    return ag.estimator_agreement(path, estimators=ag.PATH_ESTIMATORS, **size)


@pytest.mark.parametrize("scene", [GLASS, MIXED], ids=["cbox_glass", "mixed_lights"])
def test_path_estimators_agree(scene):
    r = agree(scene)
    assert r.passed, (r.p_value, r.worst, r.means)
    assert r.tests > 50


def _nee_at_delta_only(scene, sp):
    mask = _mask(scene, sp)
    return np.zeros(len(sp.index), bool) if mask is None else ~mask


def _double_counted(mode, delta, p_bsdf, p_light):
    w = _weight(mode, delta, p_bsdf, p_light)
    if mode != "mis":
        return w
    return w + 1.0 if delta is None else np.where(delta, 1.0, w + 1.0)


def _no_emission_after_delta(mode, delta, p_bsdf, p_light):
    return np.zeros(len(p_bsdf)) if mode == "nee" else _weight(mode, delta, p_bsdf, p_light)


@pytest.mark.parametrize("name,planted,scene", [
    ("nee_mask", _nee_at_delta_only, MIXED),
    ("bsdf_emission_weight", _double_counted, MIXED),
    ("bsdf_emission_weight", _no_emission_after_delta, GLASS),
], ids=["nee-at-delta-vertices-only", "mis-bsdf-emission-double-counted", "nee-drops-emission-after-delta"])
def test_planted_bugs_are_rejected(monkeypatch, name, planted, scene):
    monkeypatch.setattr(wavefront, name, planted)
    r = agree(scene)
    assert not r.passed and r.p_value < 1e-6, (r.p_value, r.worst)


def test_direct_integrators_accept_delta_materials(monkeypatch):
    """direct_mats and direct_mis agree on the mirror and glass spheres (MIS weight 1 for delta samples, spec
    §13.2.5), and emitter sampling adds nothing at a delta vertex (its f is 0 for every light direction).
    Negative control: direct_mis weighting delta samples by the balance heuristic (p_b = the lobe's discrete
    probability) darkens the light seen in the mirror and through the glass, and is rejected."""
    from brdflab.integrator import common, direct_mats

    path = GLASS[0]
    r = ag.estimator_agreement(path, estimators=("direct_mats", "direct_mis"), **GLASS[1])
    assert r.passed, (r.p_value, r.worst)
    scene = bl.load_scene(path, width=64, height=64)
    rng = np.random.default_rng(3)
    o, d, tmax = scene.camera.generate_rays(rng.random(20_000) * 64, rng.random(20_000) * 64)
    _, sp = common.trace_camera(scene, o, d, tmax)
    c = common.light_term(scene, sp, rng.random((len(sp.index), common.light_dims(scene))))
    families = common.scene_tables(scene).bsdf_families.families
    delta = np.zeros(len(sp.index), bool)
    for g, sel in sp.groups:
        delta[sel] = getattr(families[g].members[0], "all_delta", False)
    assert delta.sum() > 500 and np.all(c[delta] == 0) and (c[~delta] > 0).any(axis=1).sum() > 1000
    sample = direct_mats.sample_bsdfs
    monkeypatch.setattr(direct_mats, "sample_bsdfs", lambda *a, **k: (*sample(*a, **k)[:3], None))
    r = ag.estimator_agreement(path, estimators=("direct_mats", "direct_mis"), **GLASS[1])
    assert not r.passed and r.p_value < 1e-4, (r.p_value, r.worst)


PANE = """<camera type="perspective">
<transform name="toWorld"><lookat origin="0.3,0.2,3" target="0,0,0" up="0,1,0"/></transform>
<float name="fov" value="40"/><integer name="width" value="32"/><integer name="height" value="32"/></camera>
<mesh type="obj"><string name="filename" value="pane.obj"/>
<bsdf type="roughdielectric"><float name="alpha" value="0.3"/></bsdf></mesh>
<mesh type="obj"><string name="filename" value="light.obj"/>
<emitter type="area"><color name="radiance" value="5,5,5"/></emitter></mesh>"""


def test_light_through_a_rough_glass_pane(tmp_path, monkeypatch):
    """A rough dielectric pane with the only light behind it: emitter samples count with |cos θ_o| on a
    transmitting material (CONTRACT §3), so every direct and path estimator agrees with BSDF sampling.
    Negative control: the one-sided max(cos θ_o, 0) drops all the light that NEE finds through the pane."""
    from brdflab.integrator import common

    scene = write_scene(tmp_path, '<integrator type="direct_ems"/>' + PANE, {
        "pane.obj": "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nf 1 2 3\nf 1 3 4\n",
        "light.obj": "v -0.3 -0.3 -1\nv 0.3 -0.3 -1\nv 0.3 0.3 -1\nv -0.3 0.3 -1\nf 1 2 3\nf 1 3 4\n"})
    for estimators in (ag.ESTIMATORS, ag.PATH_ESTIMATORS):
        r = ag.estimator_agreement(scene, estimators=estimators, width=32, height=32)
        assert r.passed and min(r.means.values()) > 0.05, (r.p_value, r.worst, r.means)
    monkeypatch.setattr(common, "transmitted_cos", lambda scene, sp, wo: wo)
    for estimators in (ag.ESTIMATORS, ag.PATH_ESTIMATORS):
        r = ag.estimator_agreement(scene, estimators=estimators, width=32, height=32)
        assert not r.passed and r.p_value < 1e-6, (r.p_value, r.worst)


def test_report_judges_path_tracers_against_path_mis():
    """``brdflab report`` with a path tracer takes ``path_mis`` renders as its reference (global illumination):
    path_nee shows no significant bias, while direct_mis in the same study (the control) is flagged dark."""
    st = bl.report(GLASS[0], ["path_nee", "direct_mis"], spp=[16], runs=5, ref_spp=64, resolution=(24, 24),
                   workers=1, flip=False, mis_weights=False)
    assert st.reference_integrator == "path_mis"
    rows = {r.integrator: r for r in st.rows}
    assert not rows["path_nee"].bias_significant, rows["path_nee"].bias_p
    assert rows["direct_mis"].bias_significant and rows["direct_mis"].bias < -0.1, rows["direct_mis"].bias
