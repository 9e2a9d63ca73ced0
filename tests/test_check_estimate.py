"""``check`` must not share the user's bug (issue 40): with a user's BSDF in the scene, brdflab's own estimate
avoids the plugin's sampler and pdf by default (``direct_ems`` calls only ``eval``), and says which of the user's
methods it ran. Negative control: asked for the scene's ``direct_mis`` explicitly, the same check is blind to a
sampler bug (the render and the estimate share it), as documented."""

from __future__ import annotations

import numpy as np

import brdflab as bl
from brdflab.workflows import estimate_integrator
from tests.conftest import ROOT

PHONG = str(ROOT / "examples" / "phong.py")


def _scene(tmp_path, material: str, integrator: str = "direct_mis"):
    text = (ROOT / "examples" / "phong_scene.xml").read_text()
    text = text.replace('<integrator type="direct_ems"/>', f'<integrator type="{integrator}"/>')
    text = text.replace('<bsdf type="phong">', f'<bsdf type="{material}">')
    text = text.replace('value="160"', 'value="64"').replace('value="120"', 'value="48"')
    text = text.replace('"../scenes/', f'"{ROOT}/scenes/')
    path = tmp_path / "scene.xml"
    path.write_text(text)
    return path


def test_the_estimate_avoids_a_plugins_sampler_and_says_so(tmp_path):
    bl.load_plugin(PHONG)
    sc = bl.load_scene(_scene(tmp_path, "phong"))
    chosen, note = estimate_integrator(sc, None)
    assert chosen == "direct_ems"
    assert "eval()" in note and "pdf(), sample() are not used" in note and "direct_mis" in note
    chosen, note = estimate_integrator(sc, "direct_mis")
    assert chosen == "direct_mis" and "eval(), pdf(), sample()" in note and "not used" not in note
    builtin = bl.load_scene(ROOT / "scenes/cbox/cbox_spheres_mis.xml")
    assert estimate_integrator(builtin, None) == ("direct_mis", "")  # built-ins: the scene's own, no note


def _pdf2_plugin(tmp_path):
    path = tmp_path / "phong_pdf2.py"
    path.write_text(f"import importlib.util\nspec = importlib.util.spec_from_file_location('phong_ex', {PHONG!r})\n"
                    "mod = importlib.util.module_from_spec(spec)\nspec.loader.exec_module(mod)\n\n\n"
                    "class PhongPdf2(mod.Phong):\n    type_name = 'phong_pdf2'\n\n"
                    "    def pdf(self, wi, wo, uv=None):\n        return 4.0 * super().pdf(wi, wo, uv)\n")
    bl.load_plugin(str(path))


def test_a_sampler_bug_is_found_by_default_and_hidden_when_shared(tmp_path):
    _pdf2_plugin(tmp_path)
    scene = _scene(tmp_path, "phong_pdf2")
    # the user's renders: the plugin's 4× pdf under MIS (too dark on the spheres)
    mine = [bl.render(bl.load_scene(scene), spp=64, seed=s, workers=1) for s in (1, 2)]
    res = bl.check(mine, scene, spp=64, runs=4, user_spp=64, block=8, levels=2, where_spp=0, workers=1)
    assert not res.consistent and res.estimate_integrator == "direct_ems", res.verdict()
    assert "sample() are not used" in res.estimate_note
    shared = bl.check(mine, scene, integrator="direct_mis", spp=64, runs=4, user_spp=64, block=8, levels=2,
                      where_spp=0, workers=1)
    assert shared.consistent, shared.verdict()  # the documented blind spot of a shared bug
    assert np.isfinite(res.p_value) and res.p_value < 0.01
