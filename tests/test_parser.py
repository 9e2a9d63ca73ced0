"""Scene parser: property types, transform operations, and clear errors with line numbers."""

from __future__ import annotations

import numpy as np
import pytest

from brdflab.errors import BrdflabError, MeshError, SceneError
from brdflab.scene.loader import load_scene
from brdflab.scene.xmlparser import parse_scene_file
from tests.conftest import CAMERA, QUAD_OBJ, write_scene


def test_property_types(tmp_path):
    p = write_scene(tmp_path, """
<integrator type="direct_ems">
</integrator>
<sampler type="independent"><integer name="sampleCount" value="-3"/><float name="x" value=".5"/>
<boolean name="b" value="TRUE"/><string name="s" value="a b"/><point name="p" value="1,2 ,3"/>
<vector name="v" value="0 0 1"/><color name="c" value="0.1, 0.2,0.3"/></sampler>""")
    props = parse_scene_file(p).children[1].props
    assert props.get_int("sampleCount") == -3
    assert props.get_float("x") == 0.5
    assert props.get_bool("b") is True
    assert props.get_string("s") == "a b"
    np.testing.assert_array_equal(props.get_point("p"), [1, 2, 3])
    np.testing.assert_array_equal(props.get_vector("v"), [0, 0, 1])
    np.testing.assert_allclose(props.get_color("c"), [0.1, 0.2, 0.3])
    with pytest.raises(SceneError, match="must be given as <point>, not <vector>"):
        props.get_point("v")


def _transform(tmp_path, ops: str) -> np.ndarray:
    p = write_scene(tmp_path, f'<mesh type="obj"><transform name="toWorld">{ops}</transform></mesh>')
    return parse_scene_file(p).children[0].props.get_transform("toWorld").matrix


def test_transform_ops(tmp_path):
    m = _transform(tmp_path, '<translate value="1,2,3"/>')
    np.testing.assert_allclose(m[:3, 3], [1, 2, 3])
    m = _transform(tmp_path, '<scale value="2,3,4"/>')
    np.testing.assert_allclose(np.diag(m), [2, 3, 4, 1])
    m = _transform(tmp_path, '<rotate angle="90" axis="0,0,1"/>')
    np.testing.assert_allclose(m[:3, :3] @ [1, 0, 0], [0, 1, 0], atol=1e-12)
    m = _transform(tmp_path, '<matrix value="1 0 0 5 0 1 0 6 0 0 1 7 0 0 0 1"/>')
    np.testing.assert_allclose(m[:3, 3], [5, 6, 7])
    m = _transform(tmp_path, '<lookat origin="0,0,0" target="0,0,5" up="0,1,0"/>')
    np.testing.assert_allclose(m[:3, 2], [0, 0, 1])
    np.testing.assert_allclose(m[:3, 0], [1, 0, 0])  # l = up × d
    # Composition: first listed op is applied first (M ← Op·M).
    m = _transform(tmp_path, '<scale value="2,2,2"/><translate value="1,0,0"/>')
    np.testing.assert_allclose(m @ [1, 0, 0, 1], [3, 0, 0, 1])


@pytest.mark.parametrize(
    "body, pattern, line",
    [
        ("<integrator type='direct_ems'>", "malformed XML", 3),
        ('<integrator type="nope"/>', 'unknown integrator type "nope"; valid types: .*direct_ems', 2),
        ('<integrator type="vpl"/>', "does not support", 2),
        ('<integrator type="path">\n<integer name="maxDepth" value="0"/></integrator>' + CAMERA,
         "'maxDepth' must be -1 \\(no limit\\) or ≥ 1, got 0", 3),
        ('<integrator type="path_mis">\n<integer name="rrDepth" value="0"/></integrator>' + CAMERA,
         "'rrDepth' must be in \\[1, 1,000,000\\], got 0", 3),
        ('<integrator type="path_nee">\n<float name="maxDepth" value="3"/></integrator>' + CAMERA,
         "'maxDepth' must be given as <integer>, not <float>", 3),
        ("<foo/>", "expected an object tag", 2),
        ('<integrator type="direct_ems"/>\n<camera type="perspective"><integer name="fov" value="30"/></camera>',
         "'fov' must be given as <float>, not <integer>", 3),
        ('<integrator type="direct_ems"/>\n<camera type="perspective"><float name="fov" value="abc"/></camera>',
         "expected a number", 3),
        ('<integrator type="direct_ems"/>\n<camera type="perspective"><float name="fovv" value="3"/></camera>',
         "unknown property 'fovv' \\(did you mean 'fov'\\?\\)", 3),
        ('<integrator type="direct_ems"/>' + CAMERA
         + '\n<mesh type="obj"><string name="filename" value="x.obj"/></mesh>',
         "mesh file 'x.obj' not found", 6),
        ('<integrator type="direct_ems"/>\n<integrator type="direct_ems"/>' + CAMERA, "only one <integrator>", 3),
        ('<integrator type="direct_ems"/>', "no <camera>", None),
        ('<camera type="perspective"/>', "no <integrator>", None),
        ('<integrator type="direct_ems"/>\n<sampler type="independent"><integer name="sampleCount" value="0"/>'
         "</sampler>" + CAMERA, "'sampleCount' must be at least 1", 3),
        ('<integrator type="direct_ems"/>\n<camera type="perspective"><float name="fov" value="180"/></camera>',
         "strictly between 0 and 180", 3),
        ('<integrator type="direct_ems"/>\n<camera type="perspective"><integer name="width" value="100000"/>'
         '<integer name="height" value="100000"/></camera>', "too large .* MiB", 3),
        ('<integrator type="direct_ems"/>\n<camera type="perspective"><transform name="toWorld">'
         '<lookat origin="0,0,0" target="0,0,0" up="0,1,0"/></transform></camera>', "origin and target", 3),
        ('<integrator type="direct_ems"/>\n<emitter type="pointlight"><color name="radiance" value="1,2"/>'
         "</emitter>", "expected 3 numbers", 3),
        ('<integrator type="direct_ems">text</integrator>', "unexpected text", 2),
        ('<translate value="1,2,3"/>', "must be inside a <transform>", 2),
        ('<integrator type="direct_ems"/>\n<emitter type="area"/>', "inside a <mesh>", 3),
    ],
)
def test_bad_scenes(tmp_path, body, pattern, line):
    p = write_scene(tmp_path, body)
    with pytest.raises(BrdflabError, match=pattern) as exc:
        load_scene(p)
    assert exc.value.file == str(p)
    if line is not None:
        assert exc.value.line == line


def test_wrong_root(tmp_path):
    p = tmp_path / "s.xml"
    p.write_text('<mesh type="obj"/>')
    with pytest.raises(SceneError, match="root element must be <scene>"):
        load_scene(p)


@pytest.mark.parametrize(
    "obj, pattern, line",
    [
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "references position 4, but only 3", 4),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", "references position 0", 4),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", "at least 3 vertices", 4),
        ("v 0 0 0\nv 1 x 0\nv 0 1 0\nf 1 2 3\n", "expected 3 numbers", 2),
        ("v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n", "not finite", 2),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1 2 3\n", "every face vertex must reference one", 5),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3\n", "does not match the form", 5),
        ("# empty\n", "no faces", None),
    ],
)
def test_bad_obj(tmp_path, obj, pattern, line):
    p = write_scene(tmp_path, '<integrator type="direct_ems"/>' + CAMERA
                    + '<mesh type="obj"><string name="filename" value="m.obj"/></mesh>', {"m.obj": obj})
    with pytest.raises(MeshError, match=pattern) as exc:
        load_scene(p)
    assert exc.value.file.endswith("m.obj")
    if line is not None:
        assert exc.value.line == line


def test_obj_polygons_and_negative_indices(tmp_path):
    from brdflab.scene.obj import load_obj

    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv -1 0.5 0\nf -5 -4 -3 -2 -1\n")
    m = load_obj(tmp_path / "m.obj")
    assert m.faces.shape == (3, 3)
    assert m.triangle_areas().sum() == pytest.approx(1.5)


def test_defaults_and_quad(tmp_path):
    p = write_scene(tmp_path, '<integrator type="direct_ems"/>' + CAMERA
                    + '<mesh type="obj"><string name="filename" value="q.obj"/></mesh>', {"q.obj": QUAD_OBJ})
    s = load_scene(p)
    assert s.spp == 1 and s.seed == 0
    assert s.filter.kind == "gaussian" and s.filter.radius == 2.0
    np.testing.assert_allclose(s.bsdfs[0].albedo.value, 0.5)
    assert s.geometry.triangle_count == 2
