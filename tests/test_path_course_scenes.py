"""The path tracers on the course's assignment-4 scenes (read from ``../shared``, skipped without it; never copied).

* Every scene renders with every integrator — ``path``, ``path_nee``, ``path_mis`` and the direct ones, which
  accept the mirror and glass spheres (no emitter sample at a delta vertex, weight 1 in MIS) — at a small
  size: finite, non-negative, not black.
* ``brdflab check`` (the scene's own ``path_mis`` as brdflab's estimate) calls the ``path``, ``path_nee`` and
  ``path_mis`` renders of the Cornell box consistent, and a direct-lighting render BIASED (the negative
  control: the indirect light is missing, about a quarter of the image).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import brdflab as bl
from tests.conftest import SHARED

A4 = SHARED / "assignment-4"
SCENES = sorted(A4.glob("*/*.xml")) if A4.exists() else []
PATHS = ("path", "path_nee", "path_mis")


def _load(path, integrator, width, height):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # e.g. degenerate triangles in the course meshes
        return bl.load_scene(path, integrator=integrator, width=width, height=height)


@pytest.mark.skipif(not SCENES, reason=f"course scenes not available ({A4})")
@pytest.mark.parametrize("path", SCENES, ids=[p.stem for p in SCENES])
def test_every_scene_renders_with_every_integrator(path):
    for integrator in (*PATHS, "direct_ems", "direct_mats", "direct_mis"):
        img = bl.render(_load(path, integrator, 24, 18), spp=2, seed=5, workers=1)
        assert np.isfinite(img).all() and (img >= 0).all(), integrator
        assert img.mean() > 0.01, (integrator, img.mean())


@pytest.mark.skipif(not (A4 / "cbox" / "cbox_mis.xml").exists(), reason="course scenes not available")
@pytest.mark.parametrize("integrator,consistent", [(*p, True) for p in zip(PATHS, strict=True)]
                         + [("direct_mis", False)])
def test_check_of_the_cornell_box(integrator, consistent):
    scene = A4 / "cbox" / "cbox_mis.xml"
    w, h = 64, 48
    img = bl.render(_load(scene, integrator, w, h), spp=32, seed=101, workers=1)
    res = bl.check(img, scene, spp=32, runs=4, user_spp=32, resolution=(w, h), workers=1, where_spp=0, seed=7)
    assert res.consistent == consistent, res.to_dict()["verdict"]
    if not consistent:
        assert res.p_value < 1e-6 and res.to_dict()["verdict"].startswith("BIASED")
