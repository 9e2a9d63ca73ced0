"""The path tracers give the same image to the bit for any number of workers, either engine, and either grouping of
materials (one batched call per material family, or one call per material as a user's plugin gets).

The last holds because every live path draws its uniforms in camera-sample order at each bounce
(:func:`brdflab.integrator.wavefront.path_uniforms`), not in the shading points' family-sorted order: the
negative control draws them in point order and must change the image.
"""

from __future__ import annotations

import numpy as np
import pytest

import brdflab as bl
import brdflab.bsdf.base
from brdflab import kernels
from brdflab.integrator import wavefront
from tests.conftest import ROOT

SCENES = [ROOT / "scenes" / "cbox" / "cbox_glass_mis.xml", ROOT / "scenes" / "lights" / "mixed_lights_mis.xml"]


def _render(path, integrator: str, workers: int = 1) -> np.ndarray:
    return bl.render(bl.load_scene(path, integrator=integrator, width=40, height=30), spp=4, seed=9, workers=workers)


@pytest.mark.parametrize("path", SCENES, ids=[p.stem for p in SCENES])
def test_workers_and_engines_give_the_same_bits(path):
    for integrator in ("path", "path_nee", "path_mis"):
        with kernels.use_engine("numpy"):
            ref = _render(path, integrator)
        assert ref.mean() > 0
        with kernels.use_engine("numba"):
            np.testing.assert_array_equal(_render(path, integrator), ref, err_msg=f"{integrator}: engines")
            np.testing.assert_array_equal(_render(path, integrator, workers=2), ref, err_msg=f"{integrator}: workers")


def test_material_grouping_does_not_change_the_image(monkeypatch):
    """The Cornell box's three diffuse walls are one family (one call); without families each is its own group
    and the points come in another order: same image. Drawing in point order instead changes it (control)."""
    path = ROOT / "scenes" / "cbox" / "cbox_diffuse.xml"
    no_families = (brdflab.bsdf.base.BSDF, "family_key", lambda self: None)
    fast = _render(path, "path_mis")
    with monkeypatch.context() as m:
        m.setattr(*no_families)
        np.testing.assert_array_equal(_render(path, "path_mis"), fast)
    monkeypatch.setattr(wavefront, "path_uniforms", lambda rng, sp, dims: rng.random((len(sp.index), dims)))
    grouped = _render(path, "path_mis")
    monkeypatch.setattr(*no_families)
    assert not np.array_equal(_render(path, "path_mis"), grouped)
