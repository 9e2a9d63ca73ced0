"""Own scenes converge to brdflab's own high-spp references (references/, made by make_references.sh):
relMSE falls like 1/spp (64 spp ≤ 0.4 × 16 spp) and the image mean is within 0.5 %."""

from __future__ import annotations

import pytest

from brdflab.imageio import read_exr
from brdflab.pages.metrics import compare
from brdflab.renderer import render
from brdflab.scene.loader import load_scene
from tests.conftest import ROOT


@pytest.mark.parametrize("scene, ref", [
    ("scenes/cbox/cbox_diffuse.xml", "references/cbox_diffuse.exr"),
    ("scenes/cbox/cbox_spheres.xml", "references/cbox_spheres.exr"),
    ("scenes/cbox/cbox_substrate.xml", "references/cbox_substrate.exr"),
    ("scenes/lights/mixed_lights_mis.xml", "references/mixed_lights.exr"),
])
def test_converges_to_reference(scene, ref):
    reference = read_exr(ROOT / ref)
    images = {}
    render(load_scene(ROOT / scene), spp=64, seed=3,
           on_pass=lambda spp, t, film: images.__setitem__(spp, film.image()))
    e16, e64 = compare(images[16], reference), compare(images[64], reference)
    assert e64.relmse <= 0.4 * e16.relmse, (e16.relmse, e64.relmse)
    assert abs(e64.bias) < 0.005, e64.bias
