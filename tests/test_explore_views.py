"""The explorer's overlay, typed values, live lit sphere and transmitted lobes (issues 43, 44), driven in process
through the Bokeh document (server-side callbacks run on every property change)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("bokeh")

from bokeh.document import Document  # noqa: E402

from brdflab.viz import explorer, explorer_views  # noqa: E402


def _doc(**kw):
    doc = Document()
    explorer.make_document(doc, **kw)
    return doc, doc.get_model_by_name


def test_a_second_and_third_material_are_overlaid_and_removed():
    doc, g = _doc()
    g("bsdf_2").value = "roughdielectric"
    text = g("status").text
    assert text.startswith("<b>roughconductor</b>") and "· 2: roughdielectric " in text
    assert "alpha=0.1" in text.split("· 2: roughdielectric")[1]  # the glass's options follow its IORs
    polar = g("polar")
    assert polar.y_range.start < -1  # a transmitting material: the whole circle
    lines = [r for r in polar.renderers if "x" in r.data_source.data and len(r.data_source.data["x"]) > 0]
    assert len(lines) == 2 and len({(r.glyph.line_color, str(r.glyph.line_dash)) for r in lines}) == 2
    legend = polar.legend[0]
    shown = [i.label.value for i in legend.items if i.visible]
    assert shown[0].startswith("1: roughconductor") and shown[1].startswith("2: roughdielectric")
    g("param2_alpha").value = 0.3  # the overlay's own parameters
    status = g("status").text
    assert "alpha=0.3" in status.split("2: roughdielectric")[1] and "alpha=0.1," in status  # 1 unchanged
    g("bsdf_3").value = "dielectric"
    assert "· 3: dielectric" in g("status").text
    g("bsdf_2").value = explorer.NONE
    text = g("status").text
    assert "2: roughdielectric" not in text and "3: dielectric" in text
    for forged in ("os:system", "", "x" * 10_000):
        g("bsdf_3").value = forged
        assert g("bsdf_3").value == "dielectric" and "refused" in g("status").text


def test_typed_values_are_validated_and_move_the_slider():
    doc, g = _doc()
    g("typed_param_alpha").value = "0.0137"
    assert g("param_alpha").value == pytest.approx(0.0137) and "alpha=0.0137" in g("status").text
    for bad, why in (("abc", "type a number"), ("5", "from 0.002 to 1"), ("nan", "type a number"),
                     ("1e400", "type a number"), ("-inf", "type a number"), ("x" * 100_000, "type a number")):
        g("typed_param_alpha").value = bad
        text = g("status").text
        assert why in text and "nothing changed" in text and len(text) < 400 and "Traceback" not in text
        assert g("param_alpha").value == pytest.approx(0.0137)
    g("typed_theta_i").value = " 60 "
    assert "θ_i = 60°" in g("status").text
    g("theta_i").value = 30  # and the slider writes its value into the box
    assert g("typed_theta_i").value == "30"


def test_the_lit_sphere_previews_then_refines_and_drops_stale_work():
    jobs = []
    doc, g = _doc(background=lambda job, done: jobs.append((job, done)))
    src = g("sphere").renderers[0].data_source
    assert len(src.data["image"]) == 2  # point light and environment, one material
    assert src.data["image"][0].shape == (explorer_views.PREVIEW[0],) * 2 and "preview" in g("sphere").title.text
    (job, done), = jobs
    g("bsdf_2").value = "diffuse"  # a newer update: the first refine is stale
    assert len(jobs) == 2 and len(src.data["image"]) == 4
    assert job() is None  # its stop event was set: the render stopped
    done(job())
    assert "preview" in g("sphere").title.text  # a stale result is never shown
    job2, done2 = jobs[1]
    images = job2()
    assert len(images) == 2 and len(images[0]) == 2 and images[0][0].shape[0] == explorer_views.REFINED[0]
    done2(images)
    assert "spp" in g("sphere").title.text and src.data["image"][0].shape[0] == explorer_views.REFINED[0]
    bright = [float(np.mean(im.view(np.uint8).reshape(*im.shape, 4)[..., :3])) for im in src.data["image"]]
    assert all(b > 1 for b in bright)  # a lit sphere, not a black square


def test_delta_and_transmitting_materials_are_drawn_below_the_horizon():
    doc, g = _doc()
    g("bsdf").value = "dielectric"
    text = g("status").text
    assert "delta lobes only" in text and "ρ(θ_i) = 1.0000" in text
    spikes = next(r for r in g("polar").renderers if "text" in r.data_source.data).data_source.data["text"]
    assert [s.split(" = ")[0] for s in spikes] == ["R", "T"]
    g("bsdf").value = "roughdielectric"
    assert g("lobe").y_range.start < -1 and "whole sphere" in g("lobe").title.text
    assert "reflection only" in g("slice").title.text
    pts = [r for r in g("samples").renderers if "c" in r.data_source.data][0].data_source.data
    assert "#ff7f0e" in pts["c"]  # transmitted samples, drawn in their own colour


def test_a_served_burst_waits_for_its_end_but_not_forever():
    """The changes of a burst that queued behind a running update arrive one by one: with a quiet period the
    update runs once, after the last of them; a drag longer than ``max_wait_ms`` still updates on its way."""
    from brdflab.viz.coalesce import Coalescer

    now, pending, ran, stops = [0.0], [], [], []
    c = Coalescer(lambda: ran.append(now[0]), pending.append, quiet_ms=60, max_wait_ms=1000,
                  on_request=lambda: stops.append(1), clock=lambda: now[0])
    for _ in range(10):  # ten changes 50 ms apart: never 60 ms quiet
        c.request()
        now[0] += 0.05
        if pending:  # the timer fires (and re-arms itself while changes arrive)
            pending.pop()()
    assert ran == [] and len(stops) == 10
    now[0] += 0.1
    pending.pop()()
    assert ran == [pytest.approx(0.6)] and c.runs == 1 and not c.scheduled
    for _ in range(30):  # a 1.5 s drag: at most one update on its way after 1 s, then one at its end
        c.request()
        now[0] += 0.05
        if pending:
            pending.pop()()
    now[0] += 0.1
    while pending:
        pending.pop()()
    assert c.runs == 3 and ran[1] == pytest.approx(0.6 + 1.0, abs=0.06)
