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
