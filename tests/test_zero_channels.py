"""Colours with a zero channel, everywhere (issue 40): lights, albedos, R0, kd.

Every scene and test used to have lights and reflectances with no zero channel, so a kernel that decided whether
a light sample "contributes" from one channel would lose a light of radiance (17, 12, 0) unnoticed (31 % of its
image). Light transport is independent per channel and no sampling decision depends on these colours (uniform
emitter selection), so with one seed, channel c of the image depends on channel c of each colour only: setting
another channel to 0 must leave channel c unchanged (to rounding), on both engines and every direct integrator.
"""

from __future__ import annotations

import numpy as np
import pytest

import brdflab as bl
from tests.conftest import QUAD_OBJ, write_scene

CAMERA = """<camera type="perspective">
  <transform name="toWorld"><lookat origin="0,2.5,2.5" target="0,0,0" up="0,1,0"/></transform>
  <float name="fov" value="50"/><integer name="width" value="24"/><integer name="height" value="18"/>
</camera>"""
LIGHT_OBJ = "v -0.3 1.5 -0.3\nv 0.3 1.5 -0.3\nv 0.3 1.5 0.3\nv -0.3 1.5 0.3\nf 1 2 3 4\n"

MATERIALS = {
    "diffuse": '<bsdf type="diffuse"><color name="albedo" value="{c}"/></bsdf>',
    "roughconductor": '<bsdf type="roughconductor"><color name="R0" value="{c}"/><float name="alpha" value="0.3"/>'
                      '</bsdf>',
    "roughsubstrate": '<bsdf type="roughsubstrate"><color name="kd" value="{c}"/><float name="alpha" value="0.2"/>'
                      '</bsdf>',
}
BASE = "0.7, 0.5, 0.3"


def _scene(tmp_path, integrator, material, colour=BASE, area=BASE, point=BASE):
    area_l = "17, 12, 5" if area == BASE else area
    point_l = "3, 2, 1" if point == BASE else point
    body = (f'<integrator type="{integrator}"/>' + CAMERA
            + f'<emitter type="pointlight"><point name="position" value="0.8,1.2,0.5"/>'
              f'<color name="radiance" value="{point_l}"/></emitter>'
            + '<mesh type="obj"><string name="filename" value="light.obj"/><bsdf type="diffuse">'
              '<color name="albedo" value="0,0,0"/></bsdf>'
              f'<emitter type="area"><color name="radiance" value="{area_l}"/></emitter></mesh>'
            + '<mesh type="obj"><string name="filename" value="q.obj"/>'
            + MATERIALS[material].format(c=colour) + "</mesh>")
    name = f"s_{integrator}_{material}_{abs(hash((colour, area, point)))}.xml"
    return write_scene(tmp_path, body, {"q.obj": QUAD_OBJ, "light.obj": LIGHT_OBJ}, name=name)


def _render(path):
    return np.asarray(bl.render(bl.load_scene(path), spp=16, seed=3, workers=1), dtype=np.float64)


# (which colour, the full value, the same with one channel 0, the channel set to 0)
CASES = [("area", "17, 12, 5", "17, 12, 0", 2), ("area", "17, 12, 5", "0, 12, 5", 0),
         ("point", "3, 2, 1", "3, 2, 0", 2), ("point", "3, 2, 1", "0, 2, 1", 0),
         ("colour", "0.7, 0.5, 0.3", "0.7, 0.5, 0", 2), ("colour", "0.7, 0.5, 0.3", "0, 0.5, 0.3", 0)]


@pytest.mark.parametrize("engine", ["numba", "numpy"])
@pytest.mark.parametrize("integrator", ["direct_ems", "direct_mats", "direct_mis"])
@pytest.mark.parametrize("material", list(MATERIALS))
def test_a_zero_channel_leaves_the_other_channels_unchanged(tmp_path, engine, integrator, material):
    with bl.kernels.use_engine(engine):
        for which, full, zeroed, k in CASES:
            if which == "point" and integrator == "direct_mats":
                continue  # BSDF sampling never finds a point light: nothing of it in the image
            a = _render(_scene(tmp_path, integrator, material, **{which: full}))
            b = _render(_scene(tmp_path, integrator, material, **{which: zeroed}))
            keep = [c for c in range(3) if c != k]
            assert np.abs(a[..., keep]).max() > 0
            np.testing.assert_allclose(b[..., keep], a[..., keep], rtol=1e-12, atol=1e-300,
                                       err_msg=f"{which} = ({zeroed}) changed the other channels")
            if which == "colour":  # the material reflects nothing in channel k: only the light's own emission
                assert np.all(b[..., k] <= a[..., k] + 1e-12)


def test_the_check_sees_a_light_lost_by_one_channel(tmp_path, monkeypatch):
    """Negative control: a light term that drops a sample when its blue channel is 0 (the planted bug) fails."""
    from brdflab.integrator import common

    real = common.light_contributions if hasattr(common, "light_contributions") else None
    if real is None:
        pytest.skip("no NumPy light_contributions to plant the bug in")

    def one_channel(*args, **kwargs):
        c = real(*args, **kwargs)
        return np.where((c[:, 2] > 0)[:, None], c, 0.0)

    monkeypatch.setattr(common, "light_contributions", one_channel)
    with bl.kernels.use_engine("numpy"):
        a = _render(_scene(tmp_path, "direct_ems", "diffuse", area="17, 12, 5"))
        b = _render(_scene(tmp_path, "direct_ems", "diffuse", area="17, 12, 0"))
    assert not np.allclose(b[..., :2], a[..., :2], rtol=1e-12)
