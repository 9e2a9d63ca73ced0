"""The explorer's widgets for roughconductor's choices and alternatives (issue 45; no browser: the Bokeh document
driven as the server would): a dropdown of distributions, the visible-normal checkbox following it, α_u/α_v behind
a link to α, the Fresnel dropdown (Schlick R0, metals, η and k) with only the relevant widgets shown, and forged
choices refused."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("bokeh")
from bokeh.document import Document  # noqa: E402

from brdflab.bsdf.conductors import METALS_RGB  # noqa: E402
from brdflab.viz import explorer as explore  # noqa: E402


@pytest.fixture()
def doc():
    d = Document()
    explore.make_document(d)  # no server: every change updates at once
    return d


def _get(doc, name):
    return doc.get_model_by_name(name)


def _status(doc) -> str:
    return _get(doc, "status").text


def explore_last(doc) -> str:
    """The status line as text (the state the last update computed)."""
    import re

    return re.sub(r"<[^>]+>", "", _status(doc))


def test_distribution_is_a_dropdown_and_sample_visible_follows_it(doc):
    sel = _get(doc, "param_distribution")
    assert type(sel).__name__ == "Select" and list(sel.options) == ["beckmann", "ggx"] and sel.value == "beckmann"
    vis = _get(doc, "param_sample_visible")
    assert vis.active is False and "distribution=beckmann" in _status(doc)
    sel.value = "ggx"
    assert vis.active is True
    assert "distribution=ggx" in _status(doc) and "sample_visible=True" in _status(doc), _status(doc)
    vis.active = False
    assert "sample_visible=False" in _status(doc)


def test_alpha_u_alpha_v_are_linked_to_alpha_until_unlinked(doc):
    link = _get(doc, "param_alpha_link")
    u, v, a = _get(doc, "param_alpha_u"), _get(doc, "param_alpha_v"), _get(doc, "param_alpha")
    assert link.active is True and "alpha_u" not in explore_last(doc)  # isotropic: no α_u/α_v given
    a.value = 0.3
    link.active = False
    assert u.value == v.value == pytest.approx(0.3)
    v.value = 0.6
    s = explore_last(doc)
    assert "alpha_u=0.3" in s and "alpha_v=0.6" in s, s
    link.active = True
    assert a.value == pytest.approx(np.sqrt(0.3 * 0.6), abs=1e-9) and "alpha_u" not in explore_last(doc)


def test_alpha_rows_are_hidden_when_not_relevant(doc):
    link = _get(doc, "param_alpha_link")
    box = _get(doc, "params")

    def visible(name):
        w = _get(doc, name)
        row = next(c for c in box.children if hasattr(c, "children") and w in c.children)
        return row.visible

    assert visible("param_alpha") and not visible("param_alpha_u") and not visible("param_alpha_v")
    link.active = False
    assert not visible("param_alpha") and visible("param_alpha_u") and visible("param_alpha_v")


def test_fresnel_dropdown_shows_only_the_chosen_alternative(doc):
    fres, box = _get(doc, "param_fresnel"), _get(doc, "params")
    assert list(fres.options)[:1] == ["Schlick R0"] and {"Au", "Ag", "Cu", "Al"} <= set(fres.options)

    def visible(name):
        w = _get(doc, name)
        return next(c for c in box.children if hasattr(c, "children") and w in c.children).visible

    assert visible("param_R0") and not visible("param_eta") and not visible("param_k")
    fres.value = "Cu"
    assert "material=Cu" in explore_last(doc) and not visible("param_R0") and not visible("param_eta")
    fres.value = "η, k (typed)"
    assert visible("param_eta") and visible("param_k") and not visible("param_R0")
    eta = [float(x) for x in _get(doc, "param_eta").value.split(",")]
    assert eta == pytest.approx(METALS_RGB["Cu"][0], rel=1e-3)  # started at the last metal's η
    _get(doc, "param_k").value = "3, 2.5, 2"
    assert "peak f" in _status(doc) and "material" not in explore_last(doc)
    fres.value = "Schlick R0"
    assert visible("param_R0") and "peak f" in _status(doc)


@pytest.mark.parametrize("name, forged", [("param_distribution", "phong"), ("param_fresnel", "Unobtainium")])
def test_forged_choices_are_a_status_line(doc, name, forged):
    _get(doc, name).value = forged
    assert "must be one of" in _status(doc), _status(doc)
