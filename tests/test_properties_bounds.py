"""Value checks of scene property lists at their boundaries (each bound on both sides)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from brdflab.errors import SceneError
from brdflab.scene.properties import MAX_COMPONENT, PropertyList


def _props(**kv) -> PropertyList:
    p = PropertyList("thing", "f.xml", 3)
    kinds = {float: "float", int: "integer", bool: "boolean", str: "string"}
    for k, v in kv.items():
        p.set(k, "color" if isinstance(v, np.ndarray) else kinds[type(v)], v, "f.xml", 7)
    return p


def test_positive_float():
    assert _props(x=1e-300).positive_float("x", 1.0) == 1e-300
    with pytest.raises(SceneError, match="> 0, got 0.0"):
        _props(x=0.0).positive_float("x", 1.0)
    assert _props(x=0.0).positive_float("x", 1.0, allow_zero=True) == 0.0
    with pytest.raises(SceneError, match="≥ 0"):
        _props(x=-1e-300).positive_float("x", 1.0, allow_zero=True)
    with pytest.raises(SceneError, match="finite"):
        _props(x=float("inf")).positive_float("x", 1.0)
    assert _props().positive_float("x", 2.5) == 2.5  # the default


def test_finite_float_and_int_ranges_are_inclusive():
    p = _props(a=0.25, b=64.0, c=0.2499, n=3, m=7)
    assert p.finite_float("a", 1.0, 0.25, 64.0) == 0.25 and p.finite_float("b", 1.0, 0.25, 64.0) == 64.0
    with pytest.raises(SceneError, match=r"in \[0.25, 64\]"):
        p.finite_float("c", 1.0, 0.25, 64.0)
    assert p.int_in_range("n", 1, 3, 7) == 3 and p.int_in_range("m", 1, 3, 7) == 7
    with pytest.raises(SceneError, match=r"must be in \[4, 7\], got 3"):
        p.int_in_range("n", 1, 4, 7)
    with pytest.raises(SceneError, match=r"must be in \[3, 6\], got 7"):
        p.int_in_range("m", 1, 3, 6)


def test_colour_bounds():
    edge = _props(c=np.array([MAX_COMPONENT, 0.0, 1.0]))
    assert np.array_equal(edge.nonnegative_color("c"), [MAX_COMPONENT, 0.0, 1.0])
    with pytest.raises(SceneError, match="above"):
        _props(c=np.array([MAX_COMPONENT * 1.0001, 0.0, 1.0])).nonnegative_color("c")
    with pytest.raises(SceneError, match="non-negative"):
        _props(c=np.array([0.5, -1e-300, 1.0])).nonnegative_color("c")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert np.array_equal(_props(c=np.array([1.0, 1.0, 1.0])).reflectance("c"), [1.0, 1.0, 1.0])
    with pytest.warns(UserWarning, match=r"f.xml:7: thing: 'c' = .* creates energy"):
        _props(c=np.array([1.0, 1.0000001, 0.0])).reflectance("c")


def test_getters_are_strict_and_located():
    p = _props(i=3, f=2.0, b=True, s="x")
    assert p.get_int("i") == 3 and p.get_float("f") == 2.0 and p.get_bool("b") is True and p.get_string("s") == "x"
    for getter, name, tag in ((p.get_float, "i", "float"), (p.get_int, "f", "integer"), (p.get_bool, "i", "boolean"),
                              (p.get_string, "b", "string"), (p.get_color, "f", "color")):
        with pytest.raises(SceneError, match=f"must be given as <{tag}>") as exc:
            getter(name)
        assert exc.value.line == 7
    with pytest.raises(SceneError, match='missing required property <float name="zz">') as exc:
        p.get_float("zz")
    assert exc.value.line == 3
    p.set("i", "integer", 5, "f.xml", 9)  # a duplicate replaces the earlier value
    assert p.get_int("i") == 5 and p.where("i") == ("f.xml", 9) and p.names() == ["i", "f", "b", "s"]


def test_integer_range_is_the_int64_range(tmp_path):
    from brdflab.scene.xmlparser import parse_scene_file
    from tests.conftest import write_scene

    def value(text):
        p = write_scene(tmp_path, f'<sampler type="independent"><integer name="n" value="{text}"/></sampler>')
        return parse_scene_file(p).children[0].props.get_int("n")

    assert value(str(2**63 - 1)) == 2**63 - 1 and value(str(-(2**63))) == -(2**63)
    for bad in (str(2**63), str(-(2**63) - 1)):
        with pytest.raises(SceneError, match="out of range"):
            value(bad)


def test_a_leaf_object_with_a_child_names_it(tmp_path):
    from brdflab.scene.loader import load_scene
    from tests.conftest import write_scene

    p = write_scene(tmp_path, '<integrator type="direct_ems">\n<bsdf type="diffuse"/></integrator>'
                    '<camera type="perspective"/>')
    with pytest.raises(SceneError, match=r"cannot contain <bsdf>") as exc:
        load_scene(p)
    assert exc.value.line == 3


def test_misses_have_no_triangle_and_no_mesh(tmp_path):
    from brdflab.scene.loader import load_scene
    from tests.conftest import QUAD_OBJ, write_scene

    body = ('<integrator type="normals"/><camera type="perspective"><integer name="width" value="4"/>'
            '<integer name="height" value="4"/></camera>'
            '<mesh type="obj"><string name="filename" value="q.obj"/></mesh>')
    g = load_scene(write_scene(tmp_path, body, {"q.obj": QUAD_OBJ})).geometry
    o = np.array([[0.0, 1.0, 0.0], [0.0, 1.0, 0.0], [5.0, 1.0, 0.0]])
    d = np.array([[0.0, -1.0, 0.0], [0.0, 1.0, 0.0], [0.0, -1.0, 0.0]])
    h = g.intersect(o, d, np.full(3, np.inf))
    assert h.valid.tolist() == [True, False, False]
    assert h.prim[1:].tolist() == [-1, -1] and h.mesh[1:].tolist() == [-1, -1] and h.mesh[0] == 0
    assert np.isinf(h.t[1:]).all() and h.t[0] == pytest.approx(1.0)
    empty = g.intersect(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))
    assert len(empty.valid) == 0
    # A scene without geometry: every ray misses.
    body = ('<integrator type="normals"/><camera type="perspective"><integer name="width" value="4"/>'
            '<integer name="height" value="4"/></camera>')
    g0 = load_scene(write_scene(tmp_path, body, name="empty.xml")).geometry
    h0 = g0.intersect(o, d, np.full(3, np.inf))
    assert not h0.valid.any() and h0.prim.tolist() == [-1] * 3 and h0.mesh.tolist() == [-1] * 3
    r0 = g0.trace(o, d, np.full(3, np.inf))
    assert r0.prim.tolist() == [-1] * 3


def test_degenerate_triangles_are_counted_exactly(tmp_path):
    """A collinear triangle away from the origin is degenerate (one warning, counted); a proper triangle whose
    third corner is −(first corner) is not."""
    from brdflab.scene.obj import load_obj

    (tmp_path / "m.obj").write_text("v 1 1 1\nv 2 1 1\nv 3 1 1\nv 1 0 0\nv 0 1 0\nv -1 0 0\nf 1 2 3\nf 4 5 6\n")
    with pytest.warns(UserWarning, match=r"m.obj:7: 1 degenerate \(zero-area\) triangle;"):
        m = load_obj(tmp_path / "m.obj")
    assert m.faces.shape == (2, 3)
    (tmp_path / "ok.obj").write_text("v 1 0 0\nv 0 1 0\nv -1 0 0\nf 1 2 3\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_obj(tmp_path / "ok.obj")


def test_procedural_sphere_by_hand():
    """uv_sphere: vertices at the radius around the centre, unit outward normals, (u, v) = (φ/2π, 1 − θ/π)
    spanning [0, 1]², counter-clockwise faces (winding normal along the vertex normals), no pole slivers."""
    from brdflab.scene.shapes import uv_sphere

    c = np.array([1.0, -2.0, 0.5])
    v, f, n, uv = uv_sphere(c, 2.0, 6, 8)
    np.testing.assert_allclose(np.linalg.norm(v - c, axis=1), 2.0)
    np.testing.assert_allclose(n, (v - c) / 2.0, atol=1e-12)
    assert uv.min(axis=0).tolist() == [0.0, 0.0] and uv.max(axis=0).tolist() == [1.0, 1.0]
    theta = np.arccos(np.clip(n[:, 1], -1, 1))
    np.testing.assert_allclose(uv[:, 1], 1 - theta / np.pi, atol=1e-12)
    wind = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    assert np.all(np.einsum("ij,ij->i", wind, n[f].mean(axis=1)) > 0)
    assert len(f) == 2 * 6 * 8 - 2 * 8  # the 2 · n_φ degenerate pole triangles dropped


def test_python_overrides_and_defaults(tmp_path):
    """load_scene's overrides: seed ≥ 0 (0 allowed), spp ≥ 1; uv_sphere's default centre is the origin."""
    from brdflab.errors import BrdflabError
    from brdflab.scene.loader import load_scene
    from brdflab.scene.shapes import uv_sphere
    from tests.conftest import write_scene

    p = write_scene(tmp_path, '<integrator type="normals"/><camera type="perspective"/>')
    assert load_scene(p, seed=0).seed == 0 and load_scene(p, spp=1).spp == 1
    for kw, message in (({"seed": -1}, "seed must be an integer ≥ 0"), ({"spp": 0}, "spp must be an integer ≥ 1"),
                        ({"seed": True}, "seed must be an integer"), ({"spp": 2.0}, "spp must be an integer")):
        with pytest.raises(BrdflabError, match=message):
            load_scene(p, **kw)
    v, _, n, _ = uv_sphere()
    np.testing.assert_allclose(v, n, atol=1e-12)
