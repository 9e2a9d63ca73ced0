"""Parameter conversion of users' BSDFs, one table over every kind and every route.

Kinds (``brdflab.plugins``): float, integer, boolean (every spelling), string, colour (every form). Routes:
the scene XML (typed property tags, spec §2.4), ``--param K=V`` (the CLI's ``bsdf_from_args`` and the
``--bsdf NAME:K=V`` / ``--param`` of plot and explore) and the API (``make_bsdf`` with Python values or
text). Each accepted spelling must arrive as the right Python value *and type* in the plugin's ``__init__``;
each rejected one must be an error naming the parameter.
"""

from __future__ import annotations

import argparse
import re

import numpy as np
import pytest

import brdflab as bl
from brdflab import plugins
from brdflab.errors import BrdflabError
from brdflab.scene.loader import load_scene
from brdflab.viz import spec as bspec
from tests.conftest import QUAD_OBJ, write_scene


class AllKinds(bl.BSDF):
    """A Lambertian plugin with one parameter of every kind (two booleans, defaults False and True)."""

    type_name = "allkinds_conv"

    def __init__(self, gain=1.5, count=3, mirror=False, lit=True, mode="plain", tint=(0.5, 0.5, 0.5)):
        self.args = {"gain": gain, "count": count, "mirror": mirror, "lit": lit, "mode": mode, "tint": tint}

    def eval(self, wi, wo, uv=None):
        return np.full((len(wi), 3), 1 / np.pi) * ((wi[:, 2] > 0) & (wo[:, 2] > 0))[:, None]

    def pdf(self, wi, wo, uv=None):
        return np.where((wi[:, 2] > 0) & (wo[:, 2] > 0), 1 / (2 * np.pi), 0.0)

    def sample(self, wi, u, uv=None):
        wo = bl.warps.square_to_uniform_hemisphere(u[:, :2])
        pdf = self.pdf(wi, wo)
        return bl.BSDFSample(wo, self.eval(wi, wo) * (2 * np.pi * wo[:, 2])[:, None], pdf)


@pytest.fixture(autouse=True)
def registered():
    plugins.register_bsdf(AllKinds)
    yield
    plugins.unregister_bsdf(AllKinds.type_name)


NAME = AllKinds.type_name
KINDS = {"gain": "float", "count": "integer", "mirror": "boolean", "lit": "boolean", "mode": "string",
         "tint": "color"}

# (parameter, text as written after --param K=, expected value); the XML route uses XML_OK below.
PARAM_OK = [
    ("gain", "2.5", 2.5), ("gain", "-1e-3", -1e-3), ("gain", " 4 ", 4.0), ("gain", "7", 7.0),
    ("count", "5", 5), ("count", "-2", -2), ("count", "0", 0),
    *[(p, t, True) for p in ("mirror", "lit") for t in ("true", "True", "TRUE", "1", "yes", "Yes")],
    *[(p, t, False) for p in ("mirror", "lit") for t in ("false", "False", "FALSE", "0", "no", "NO")],
    ("mode", "fancy", "fancy"), ("mode", "with space", "with space"), ("mode", "0", "0"), ("mode", "false", "false"),
    ("tint", "0.2,0.3,0.4", [0.2, 0.3, 0.4]), ("tint", "0.2 0.3 0.4", [0.2, 0.3, 0.4]), ("tint", "0.7", [0.7] * 3),
    ("tint", "1, 2, 3", [1.0, 2.0, 3.0]),
]
PARAM_BAD = [
    ("gain", "abc", "expected a number"), ("gain", "nan", "finite"), ("gain", "inf", "finite"), ("gain", "", "number"),
    ("count", "2.5", "expected an integer"), ("count", "x", "expected an integer"), ("count", "1e3", "integer"),
    *[(p, t, "expected true or false") for p in ("mirror", "lit") for t in ("2", "maybe", "", "t", "off", "-1")],
    ("tint", "1,2", "expected a colour"), ("tint", "1,2,3,4", "expected a colour"), ("tint", "red", "colour"),
    ("tint", "1,nan,2", "finite"),
]
TYPES = {"float": float, "integer": int, "boolean": bool, "string": str, "color": np.ndarray}


def _check(b: AllKinds, key: str, expected) -> None:
    got = b.args[key]
    kind = KINDS[key]
    assert type(got) is TYPES[kind] or (kind == "color" and isinstance(got, np.ndarray)), (key, type(got))
    if kind == "color":
        assert got.shape == (3,) and np.allclose(got, expected)
    else:
        assert got == expected and type(got) is type(expected) or kind == "float" and got == pytest.approx(expected)
    # The other parameters keep their defaults (and their types: the booleans stay bool, not int).
    for other, default in (("gain", 1.5), ("count", 3), ("mirror", False), ("lit", True), ("mode", "plain")):
        if other != key:
            assert b.args[other] == default and type(b.args[other]) is type(default), (other, b.args[other])


def test_kinds_come_from_the_defaults():
    """bool is a subclass of int: a boolean default must still be a boolean parameter."""
    assert plugins.parameter_kinds(AllKinds) == KINDS
    assert plugins.bsdf_parameters(NAME) == {"gain": 1.5, "count": 3, "mirror": False, "lit": True,
                                             "mode": "plain", "tint": (0.5, 0.5, 0.5)}
    assert plugins._kind_of(np.bool_(True)) == "boolean" and plugins._kind_of(np.int64(2)) == "integer"
    assert plugins._kind_of(np.float32(2)) == "float" and plugins._kind_of(np.zeros(3)) == "color"


def test_defaults_are_passed_with_their_types():
    b = plugins.make_bsdf(NAME)
    for k, v in {"gain": 1.5, "count": 3, "mirror": False, "lit": True, "mode": "plain"}.items():
        assert b.args[k] == v and type(b.args[k]) is type(v)


@pytest.mark.parametrize(("key", "text", "expected"), PARAM_OK)
def test_param_text_is_converted_by_kind(key, text, expected):
    """``--param K=V`` through every CLI route and the API's text form."""
    _check(plugins.make_bsdf(NAME, {key: text}), key, expected)
    args = argparse.Namespace(param=[f"{key}={text}"], alpha=None, theta=None, bsdf=NAME, plugin=None)
    from brdflab.cli.options import bsdf_from_args

    _check(bsdf_from_args(args), key, expected)
    if "," not in text:  # (a colour in --bsdf NAME:K=V keeps its commas, tested below)
        specs = bspec.resolve([NAME], None, [f"{key}={text}"])
        _check(bspec.build(specs[0]), key, expected)


def test_colour_inside_a_bsdf_spec_keeps_its_commas():
    (s,) = bspec.resolve([f"{NAME}:tint=0.1,0.2,0.3,mirror=yes"])
    b = bspec.build(s)
    assert np.allclose(b.args["tint"], [0.1, 0.2, 0.3]) and b.args["mirror"] is True


@pytest.mark.parametrize(("key", "text", "message"), PARAM_BAD)
def test_param_text_rejections(key, text, message):
    from brdflab.cli.options import bsdf_from_args

    for build in (lambda: plugins.make_bsdf(NAME, {key: text}),
                  lambda: bsdf_from_args(argparse.Namespace(param=[f"{key}={text}"], alpha=None, theta=None,
                                                            bsdf=NAME, plugin=None))):
        with pytest.raises(BrdflabError, match=re.escape(message)) as exc:
            build()
        assert f"'{key}'" in str(exc.value) and "\n" not in str(exc.value)


@pytest.mark.parametrize(("key", "value", "expected"), [
    ("gain", 2, 2.0), ("gain", np.float32(0.25), 0.25), ("count", 4, 4), ("count", np.int64(6), 6),
    ("mirror", True, True), ("lit", False, False), ("mirror", np.bool_(True), True),
    ("mode", "x", "x"), ("tint", 0.5, [0.5] * 3), ("tint", (0.1, 0.2, 0.3), [0.1, 0.2, 0.3]),
    ("tint", np.array([1.0, 2.0, 3.0]), [1.0, 2.0, 3.0]), ("count", 3.0, 3), ("mirror", "yes", True),
    ("lit", "0", False),
])
def test_api_values_keep_their_kind(key, value, expected):
    _check(plugins.make_bsdf(NAME, {key: value}), key, expected)


@pytest.mark.parametrize(("key", "value", "message"), [
    ("gain", float("nan"), "finite"), ("tint", (1.0, float("inf"), 0.0), "finite"), ("nope", 1, "unknown parameter"),
    ("gian", 1.0, "did you mean 'gain'"),
    ("count", 2.7, "expected an integer"), ("count", float("inf"), "expected an integer"),
    ("gain", True, "expected a number"), ("count", False, "expected an integer"), ("gain", [1.0], "a number"),
    ("mirror", 1, "expected true or false"), ("lit", 0.0, "expected true or false"), ("lit", None, "true or false"),
])
def test_api_rejections(key, value, message):
    with pytest.raises(BrdflabError, match=re.escape(message)):
        plugins.make_bsdf(NAME, {key: value})


XML_OK = [
    ("gain", "float", "2.5", 2.5), ("gain", "float", ".5", 0.5), ("gain", "float", "1e-3", 1e-3),
    ("gain", "integer", "2", 2.0),  # an <integer> for a float parameter is widened
    ("count", "integer", "5", 5), ("count", "integer", "-3", -3),
    *[(p, "boolean", t, True) for p in ("mirror", "lit") for t in ("true", "True", "TRUE")],
    *[(p, "boolean", t, False) for p in ("mirror", "lit") for t in ("false", "False", "FALSE")],
    ("mode", "string", "fancy", "fancy"), ("mode", "string", "false", "false"),
    ("tint", "color", "0.2,0.3,0.4", [0.2, 0.3, 0.4]), ("tint", "color", "0.2 0.3 0.4", [0.2, 0.3, 0.4]),
    ("tint", "color", "0.2, 0.3,  0.4", [0.2, 0.3, 0.4]),
]
XML_BAD = [
    ("gain", "float", "abc", "expected a number"), ("gain", "string", "2", "must be given as <float>"),
    ("gain", "float", "inf", "finite"),
    ("count", "float", "2", "must be given as <integer>"), ("count", "integer", "2.5", "base-10 integer"),
    *[(p, "boolean", t, "expected 'true' or 'false'") for p in ("mirror", "lit") for t in ("1", "0", "yes", "no", "")],
    *[(p, kind, "1", "must be given as <boolean>") for p in ("mirror", "lit") for kind in ("integer", "string")],
    ("mode", "integer", "3", "must be given as <string>"),
    ("tint", "color", "0.5", "expected 3 numbers"), ("tint", "color", "1,2,3,4", "expected 3 numbers"),
    ("tint", "point", "1,2,3", "must be given as <color>"), ("bogus", "float", "1", "unknown property 'bogus'"),
]


def _scene(tmp_path, tag: str, key: str, text: str):
    body = (f'<integrator type="direct_ems"/><camera type="perspective"><integer name="width" value="4"/>'
            f'<integer name="height" value="4"/></camera>'
            f'<mesh type="obj"><string name="filename" value="quad.obj"/><bsdf type="{NAME}">'
            f'<{tag} name="{key}" value="{text}"/></bsdf></mesh>'
            f'<emitter type="pointlight"><point name="position" value="0,2,0"/>'
            f'<color name="radiance" value="1,1,1"/></emitter>')
    return write_scene(tmp_path, body, {"quad.obj": QUAD_OBJ})


@pytest.mark.parametrize(("key", "tag", "text", "expected"), XML_OK)
def test_scene_xml_values_are_converted_by_kind(tmp_path, key, tag, text, expected):
    scene = load_scene(_scene(tmp_path, tag, key, text))
    (b,) = [b for b in scene.bsdfs if getattr(b, "type_name", "") == NAME or isinstance(b, AllKinds)
            or isinstance(getattr(b, "inner", None), AllKinds)] or [None]
    b = b if isinstance(b, AllKinds) else getattr(b, "inner", b)
    assert isinstance(b, AllKinds), scene.bsdfs
    _check(b, key, expected)


@pytest.mark.parametrize(("key", "tag", "text", "message"), XML_BAD)
def test_scene_xml_rejections(tmp_path, key, tag, text, message):
    with pytest.raises(BrdflabError, match=r"scene\.xml:\d+.*" + re.escape(message)) as exc:
        load_scene(_scene(tmp_path, tag, key, text))
    assert len(str(exc.value)) < 400
