"""User scenes from ../shared/scenes (skipped cleanly when that folder is absent; never copied)."""

from __future__ import annotations

import numpy as np
import pytest

from brdflab.errors import BrdflabError
from brdflab.imageio import read_exr
from brdflab.renderer import render
from brdflab.scene.loader import load_scene
from tests.conftest import shared_scene


def rel_mse(x: np.ndarray, r: np.ndarray) -> float:
    """Mean of (x − r)² / (r² + 0.01)."""
    x, r = x.astype(np.float64), r.astype(np.float64)
    return float(np.mean((x - r) ** 2 / (r * r + 0.01)))


def test_cbox_ems_converges_to_reference():
    """relMSE falls like 1/spp (64 spp ≤ 0.4 × 16 spp) and the mean is within 0.5 % of the reference."""
    scene = load_scene(shared_scene("assignment-2/cbox/cbox_ems.xml"))
    ref = read_exr(shared_scene("assignment-2/references/cbox_ems.exr"))
    images = {}
    render(scene, spp=64, seed=1, on_pass=lambda spp, t, film: images.__setitem__(spp, film.image()))
    e16, e64 = rel_mse(images[16], ref), rel_mse(images[64], ref)
    assert e64 <= 0.4 * e16, (e16, e64)
    assert abs(images[64].mean() / ref.mean() - 1) < 0.005
    # The light is exactly 40 and the red wall is on the image's right (mirrored camera).
    assert np.allclose(images[64][60, 400], 40.0)
    assert images[64][300, 700, 0] > 2 * images[64][300, 700, 2]


@pytest.mark.parametrize("rel", [
    "assignment-2/cbox/cbox_ems.xml",
    "assignment-2/aliasing/aliasing.xml",
    "assignment-2/bunny/bunny_ems.xml",
    "assignment-2/table/table_ems.xml",
])
def test_assignment2_scenes_render(rel):
    scene = load_scene(shared_scene(rel))
    scene.camera.width, scene.camera.height = scene.camera.width // 8, scene.camera.height // 8
    img, stats = render(scene, spp=2)
    assert np.isfinite(img).all() and img.min() >= 0 and img.mean() > 0
    assert stats.dropped == 0


@pytest.mark.parametrize("rel, missing", [
    ("assignment-2/serapis/serapis_ems.xml", "serapis.obj"),
    ("assignment-2/serapis/serapis_whitted.xml", "serapis.obj"),
    ("assignment-2/aliasing/cbox_ems.xml", "meshes/walls.obj"),
])
def test_missing_mesh_is_named(rel, missing):
    with pytest.raises(BrdflabError, match=missing) as exc:
        load_scene(shared_scene(rel))
    assert exc.value.line is not None


@pytest.mark.parametrize("rel", ["assignment-3/serapis/serapis_rough_ems.xml",
                                 "assignment-3/serapis/serapis_smooth_mats.xml"])
def test_assignment3_serapis_names_the_missing_mesh(rel):
    with pytest.raises(BrdflabError, match="mesh file 'serapis.obj' not found") as exc:
        load_scene(shared_scene(rel))
    assert exc.value.line is not None


@pytest.mark.parametrize("rel", ["assignment-3/cbox/cbox_conductors_ems.xml",
                                 "assignment-3/cbox/cbox_substrate_ems.xml",
                                 "assignment-3/bunny_env/bunny_rough_mis.xml",
                                 "assignment-3/bunny_env/bunny_smooth_mats.xml"])
def test_assignment3_scenes_render(rel):
    scene = load_scene(shared_scene(rel))
    scene.camera.width, scene.camera.height = scene.camera.width // 8, scene.camera.height // 8
    img, stats = render(scene, spp=4)
    assert np.isfinite(img).all() and img.mean() > 0 and stats.dropped == 0
