"""The plugin registry's less travelled routes: ``module:Class`` as a scene type, a whole module, a class's own
``from_properties``, a ``KNOWN`` table that names parameters differently from ``__init__``, entry points
loaded once, messages that name where a bad class came from."""

from __future__ import annotations

import numpy as np
import pytest

import brdflab as bl
from brdflab import plugins
from brdflab.errors import BrdflabError
from brdflab.scene.loader import load_scene
from tests.conftest import QUAD_OBJ, write_scene

PATH = "tests.plugins.uniform_lambert:UniformLambert"


@pytest.fixture(autouse=True)
def clean_registry():
    yield
    for n in ("uniform_lambert", "uniform_lambert_broken", "own_props_test", "known_names_test"):
        plugins.unregister_bsdf(n)


def test_module_class_path_as_a_type():
    b = plugins.make_bsdf(PATH, {"scale": "2"})
    assert type(b).__name__ == "UniformLambert" and b.scale == 2.0


def test_module_class_path_in_a_scene(tmp_path):
    body = ('<integrator type="direct_ems"/><camera type="perspective"><integer name="width" value="4"/>'
            '<integer name="height" value="4"/></camera>'
            f'<mesh type="obj"><string name="filename" value="quad.obj"/><bsdf type="{PATH}">'
            '<float name="scale" value="0.5"/></bsdf></mesh>'
            '<emitter type="pointlight"><point name="position" value="0,2,0"/>'
            '<color name="radiance" value="1,1,1"/></emitter>')
    s = load_scene(write_scene(tmp_path, body, {"quad.obj": QUAD_OBJ}))
    found = [b for b in s.bsdfs if type(getattr(b, "inner", b)).__name__ == "UniformLambert"]
    assert len(found) == 1 and getattr(found[0], "inner", found[0]).scale == 0.5


def test_a_whole_module_registers_each_class():
    assert plugins.load_plugin("tests.plugins.uniform_lambert") == ["uniform_lambert", "uniform_lambert_broken"]


class OwnProps(bl.BSDF):
    """A plugin that builds itself from the property list (its own names and checks)."""

    type_name = "own_props_test"

    def __init__(self, shine=1.0):
        self.shine = shine
        self.built_by = "init"

    @classmethod
    def from_properties(cls, props):
        b = cls(2 * props.get_float("shine", 1.0))
        b.built_by = "from_properties"
        return b

    def eval(self, wi, wo, uv=None):
        return np.zeros((len(wi), 3))

    def pdf(self, wi, wo, uv=None):
        return np.zeros(len(wi))

    def sample(self, wi, u, uv=None):
        return bl.BSDFSample(wi.copy(), np.zeros((len(wi), 3)), np.zeros(len(wi)))


def test_own_from_properties_is_used():
    plugins.register_bsdf(OwnProps)
    b = plugins.make_bsdf("own_props_test", {"shine": "3"})
    assert b.built_by == "from_properties" and b.shine == 6.0


class KnownNames(OwnProps):
    """A ``KNOWN`` table whose scene names differ from the ``__init__`` argument (R0 ↔ shine)."""

    type_name = "known_names_test"
    KNOWN = {"R0": "float"}

    def __init__(self, shine=0.25):
        self.shine = shine

    @classmethod
    def from_properties(cls, props):
        return cls(props.get_float("R0", 0.25))


def test_known_table_maps_defaults_by_position():
    plugins.register_bsdf(KnownNames)
    assert plugins.bsdf_parameters("known_names_test") == {"R0": 0.25}
    assert plugins.make_bsdf("known_names_test", {"R0": "0.5"}).shine == 0.5


def test_entry_points_are_loaded_once(monkeypatch):
    calls = []
    monkeypatch.setattr(plugins, "entry_points", lambda group: calls.append(group) or [])
    monkeypatch.setattr(plugins, "_ENTRY_POINTS_LOADED", False)
    plugins.bsdf_names()
    plugins.bsdf_names()
    plugins.bsdf_class("diffuse")
    assert calls == ["brdflab.bsdfs"]


def test_bad_default_names_its_origin(tmp_path):
    f = tmp_path / "nodefault_plugin.py"
    f.write_text("import brdflab as bl\n\nclass NoDef(bl.BSDF):\n    type_name = 'nodef_test'\n\n"
                 "    def __init__(self, exponent):\n        self.exponent = exponent\n\n"
                 "    def eval(self, wi, wo, uv=None): ...\n\n    def pdf(self, wi, wo, uv=None): ...\n\n"
                 "    def sample(self, wi, u, uv=None): ...\n")
    with pytest.raises(BrdflabError, match=r"nodefault_plugin\.py: parameter 'exponent' of NoDef has no default"):
        plugins.load_plugin(f)


def test_import_error_message_is_one_bounded_line(tmp_path):
    f = tmp_path / "long_error_plugin.py"
    f.write_text("raise RuntimeError('" + "x" * 400 + "\\nsecond line')\n")
    with pytest.raises(BrdflabError) as exc:
        plugins.load_plugin(f)
    text = str(exc.value)
    detail, _, where = text.split("failed to import: ", 1)[1].rpartition(" (at ")
    assert "\n" not in text and "second line" not in text and len(detail) == 120 and detail.endswith("…")
    assert where.endswith("long_error_plugin.py:1)") and len(text) <= 300  # the plugin's own line, in one line
