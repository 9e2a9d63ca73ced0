"""The plugin registry and users' BSDFs: registration, parameters, scenes, the generic render path, the CLI."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import numpy as np
import pytest

import brdflab as bl
from brdflab import plugins
from brdflab.cli.main import main
from brdflab.errors import BrdflabError

ROOT = Path(__file__).resolve().parents[1]
PLUGIN = ROOT / "tests" / "plugins" / "uniform_lambert.py"
SHARED = ROOT.parent / "shared" / "scenes"


@pytest.fixture
def user_plugin():
    names = plugins.load_plugin(PLUGIN)
    yield names
    for n in names:
        plugins.unregister_bsdf(n)


def _plugin_scene(tmp_path: Path, source: Path, replace: dict[str, str], width: int = 48, height: int = 48) -> Path:
    """A copy of ``source`` (in tmp_path, mesh paths made absolute) with some BSDF types replaced."""
    text = source.read_text()
    text = re.sub(r'value="(meshes/[^"]+)"', lambda m: f'value="{source.parent / m.group(1)}"', text)
    for old, new in replace.items():
        text = text.replace(old, new)
    path = tmp_path / "plugin_scene.xml"
    path.write_text(text)
    return path


# -- registry ---------------------------------------------------------------------------------------------
def test_load_plugin_file_registers_its_classes(user_plugin):
    assert user_plugin == ["uniform_lambert", "uniform_lambert_broken"]
    assert "uniform_lambert" in plugins.bsdf_names()
    assert plugins.bsdf_parameters("uniform_lambert") == {"albedo": (0.5, 0.5, 0.5), "scale": 1.0}
    assert plugins.load_plugin(PLUGIN) == user_plugin  # loading twice is harmless


def test_module_class_path_and_entry_points(monkeypatch):
    name = plugins.load_plugin("tests.plugins.uniform_lambert:UniformLambert")
    assert name == ["uniform_lambert"]
    plugins.unregister_bsdf("uniform_lambert")

    class EP:
        name, value = "ep_lambert", "tests.plugins.uniform_lambert:UniformLambert"

        def load(self):
            from tests.plugins.uniform_lambert import UniformLambert

            return UniformLambert

    monkeypatch.setattr(plugins, "entry_points", lambda group: [EP()] if group == "brdflab.bsdfs" else [])
    monkeypatch.setattr(plugins, "_ENTRY_POINTS_LOADED", False)
    try:
        assert "ep_lambert" in plugins.bsdf_names()
        assert isinstance(plugins.make_bsdf("ep_lambert"), bl.BSDF)
    finally:
        plugins.unregister_bsdf("ep_lambert")


def test_parameters_are_converted_by_kind(user_plugin):
    b = plugins.make_bsdf("uniform_lambert", {"albedo": "0.9", "scale": "2"})
    assert np.array_equal(b.albedo, [0.9, 0.9, 0.9]) and b.scale == 2.0
    b = plugins.make_bsdf("uniform_lambert", {"albedo": "0.1,0.2,0.3", "scale": 3})
    assert np.array_equal(b.albedo, [0.1, 0.2, 0.3]) and b.scale == 3.0
    c = plugins.make_bsdf("roughconductor", {"R0": "0.9,0.8,0.7"}, alpha=0.2)
    assert np.array_equal(c.R0.value, [0.9, 0.8, 0.7]) and c.alpha_value == pytest.approx(0.2)


@pytest.mark.parametrize(("params", "alpha", "message"), [
    ({"bogus": "3"}, None, "unknown parameter 'bogus'"),
    ({"scal": "3"}, None, "did you mean 'scale'"),
    ({"scale": "abc"}, None, "expected a number, got 'abc'"),
    ({"scale": "nan"}, None, "expected a finite value"),
    ({"scale": "inf"}, None, "expected a finite value"),
    ({"albedo": "1,2"}, None, "expected a colour"),
    ({"scale": "x" * 500}, None, "…"),
    ({}, 0.1, "--alpha applies only to a BSDF with an 'alpha' parameter"),
])
def test_bad_parameters_are_errors(user_plugin, params, alpha, message):
    with pytest.raises(BrdflabError, match=re.escape(message)) as exc:
        plugins.make_bsdf("uniform_lambert", params, alpha=alpha)
    assert len(str(exc.value)) < 300


def test_builtin_parameter_ranges_are_checked():
    with pytest.raises(BrdflabError, match="non-negative"):
        plugins.make_bsdf("roughconductor", {"R0": "-1"})
    with pytest.raises(BrdflabError, match="> 0"):
        plugins.make_bsdf("roughconductor", alpha=0.0)
    with pytest.raises(BrdflabError, match="unknown BSDF type|unknown bsdf type"):
        plugins.make_bsdf("nonexistent")


def test_registration_rejects_broken_classes():
    class NoName(bl.BSDF):
        def eval(self, wi, wo, uv=None): ...
        def pdf(self, wi, wo, uv=None): ...
        def sample(self, wi, u, uv=None): ...

    class Incomplete(bl.BSDF):
        type_name = "incomplete"

        def eval(self, wi, wo, uv=None): ...

    class NoDefault(NoName):
        type_name = "nodefault"

        def __init__(self, exponent):
            self.exponent = exponent

    class Shadow(NoName):
        type_name = "diffuse"

    for cls, message in ((NoName, "type_name"), (Incomplete, "does not implement pdf, sample"),
                         (NoDefault, "'exponent'.*has no default"), (Shadow, "is a built-in"), (int, "not a subclass")):
        with pytest.raises(BrdflabError, match=message):
            plugins.register_bsdf(cls)


def test_plugin_file_errors(tmp_path):
    with pytest.raises(BrdflabError, match="not found"):
        plugins.load_plugin(tmp_path / "missing.py")
    bad = tmp_path / "bad.py"
    bad.write_text("import numpy as np\nraise RuntimeError('boom')\n")
    with pytest.raises(BrdflabError, match="failed to import: RuntimeError: boom"):
        plugins.load_plugin(bad)
    empty = tmp_path / "empty.py"
    empty.write_text("x = 1\n")
    with pytest.raises(BrdflabError, match="defines no subclass"):
        plugins.load_plugin(empty)
    with pytest.raises(BrdflabError, match="cannot import module"):
        plugins.load_plugin("no_such_package.mod:Class")


# -- scenes -----------------------------------------------------------------------------------------------
def test_scene_parameters_and_errors(tmp_path, user_plugin):
    src = ROOT / "scenes" / "cbox" / "cbox_diffuse.xml"
    path = _plugin_scene(tmp_path, src, {'<bsdf type="diffuse"><color name="albedo" value="0.63, 0.065, 0.05"/>':
                                         '<bsdf type="uniform_lambert"><float name="scale" value="0.5"/>'
                                         '<color name="albedo" value="0.63, 0.065, 0.05"/>'})
    scene = bl.load_scene(path)
    lam = [b for b in scene.bsdfs if b.type_name == "uniform_lambert"]
    assert len(lam) == 1 and lam[0].scale == 0.5 and np.allclose(lam[0].albedo, [0.63, 0.065, 0.05])
    text = path.read_text().replace('<float name="scale" value="0.5"/>', '<float name="bogus" value="0.5"/>')
    path.write_text(text)
    with pytest.raises(BrdflabError, match=r"plugin_scene.xml:\d+.*unknown property 'bogus'"):
        bl.load_scene(path)
    path.write_text(text.replace('<float name="bogus" value="0.5"/>', '<string name="scale" value="big"/>'))
    with pytest.raises(BrdflabError, match=r"plugin_scene.xml:\d+.*'scale' must be given as <float>"):
        bl.load_scene(path)
    path.write_text(text.replace('<float name="bogus" value="0.5"/>', '<float name="scale" value="inf"/>'))
    with pytest.raises(BrdflabError, match=r"plugin_scene.xml:\d+.*must be finite"):
        bl.load_scene(path)


def test_plugin_renders_like_the_builtin_it_matches(tmp_path, user_plugin):
    """Emitter sampling uses eval only: the plugin's f = albedo/π gives the built-in diffuse image."""
    src = ROOT / "scenes" / "cbox" / "cbox_diffuse.xml"
    plain = _plugin_scene(tmp_path, src, {})
    builtin = bl.render(bl.load_scene(plain, width=40, height=40), spp=8, seed=3, workers=1)
    path = _plugin_scene(tmp_path, src, {'bsdf type="diffuse"': 'bsdf type="uniform_lambert"'})
    scene = bl.load_scene(path, width=40, height=40)
    assert {b.type_name for b in scene.bsdfs} == {"uniform_lambert"}
    img = bl.render(scene, spp=8, seed=3, workers=1)
    np.testing.assert_allclose(img, builtin, rtol=1e-5, atol=1e-7)


def _course_or_bundled(rel: str, bundled: str) -> Path:
    p = SHARED / rel
    return p if p.exists() else ROOT / bundled


def test_plugin_ems_and_mats_agree_in_a_course_scene(tmp_path, user_plugin):
    """The plugin (uniform hemisphere sampling, unlike the built-in) renders the course Cornell box with
    emitter and with BSDF sampling; the image means agree within 1 % and within 4 standard errors."""
    src = _course_or_bundled("assignment-2/cbox/cbox_ems.xml", "scenes/cbox/cbox_diffuse.xml")
    path = _plugin_scene(tmp_path, src, {'bsdf type="diffuse"': 'bsdf type="uniform_lambert"'})
    means = {}
    for integrator, spp in (("direct_ems", 64), ("direct_mats", 256)):
        scene = bl.load_scene(path, integrator=integrator, width=64, height=48)
        runs = [bl.render(scene, spp=spp, seed=s + 11, workers=2).mean() for s in range(4)]
        means[integrator] = (np.mean(runs), np.std(runs, ddof=1) / 2)
    (m1, e1), (m2, e2) = means["direct_ems"], means["direct_mats"]
    assert abs(m1 - m2) <= 0.01 * m1, means
    assert abs(m1 - m2) <= 4 * np.hypot(e1, e2) + 1e-4 * m1, means


@pytest.mark.parametrize("integrator", ["direct_ems", "direct_mis"])
def test_family_fast_path_is_bit_identical_to_the_generic_path(monkeypatch, integrator):
    """Built-ins batched as material families give the image of the plain per-material path to the bit."""
    from brdflab.bsdf.diffuse import Diffuse
    from brdflab.bsdf.roughconductor import RoughConductor
    from brdflab.bsdf.roughsubstrate import RoughSubstrate

    for name in ("cbox/cbox_spheres.xml", "veach/veach_mis.xml"):
        scene = bl.load_scene(ROOT / "scenes" / name, integrator=integrator, width=48, height=36)
        fast = bl.render(scene, spp=4, seed=5, workers=1)
        with monkeypatch.context() as m:
            for cls in (Diffuse, RoughConductor, RoughSubstrate):
                m.setattr(cls, "batchable", False)
            generic_scene = bl.load_scene(ROOT / "scenes" / name, integrator=integrator, width=48, height=36)
            from brdflab.integrator.common import scene_tables

            fams = scene_tables(generic_scene).bsdf_families.families
            assert len(fams) == len(generic_scene.bsdfs)  # one family per material: the plain path
            generic = bl.render(generic_scene, spp=4, seed=5, workers=1)
        assert np.array_equal(fast, generic), name


# -- command line -----------------------------------------------------------------------------------------
def test_cli_chi2_and_validate_on_a_plugin(user_plugin, tmp_path, capsys):
    args = ["--plugin", str(PLUGIN), "--theta", "30", "--theta", "70", "--samples", "40000"]
    assert main(["chi2", *args, "--bsdf", "uniform_lambert", "--param", "scale=0.9",
                 "-o", str(tmp_path / "ok")]) == 0
    out = capsys.readouterr().out
    assert "scale=0.9" in out and "ALL PASSED" in out
    assert main(["chi2", *args, "--bsdf", "uniform_lambert_broken", "-o", str(tmp_path / "bad")]) == 1
    assert "FAIL" in capsys.readouterr().out
    assert main(["validate", *args, "--bsdf", "uniform_lambert", "-o", str(tmp_path / "val")]) == 0
    assert main(["chi2", "--plugin", str(PLUGIN), "--bsdf", "uniform_lambert", "--param", "bogus=3"]) == 2
    assert "unknown parameter 'bogus'" in capsys.readouterr().err
    assert main(["chi2", "--plugin", str(PLUGIN), "--bsdf", "uniform_lambert", "--alpha", "0.1"]) == 2
    assert main(["chi2", "--bsdf", "uniform_lambert_x", "--plugin", str(PLUGIN)]) == 2
    assert "did you mean 'uniform_lambert'" in capsys.readouterr().err


def test_cli_render_with_plugin(tmp_path, capsys):
    src = ROOT / "scenes" / "cbox" / "cbox_diffuse.xml"
    path = _plugin_scene(tmp_path, src, {'bsdf type="diffuse"': 'bsdf type="uniform_lambert"'})
    out = tmp_path / "img.exr"
    try:
        assert main(["render", str(path), "--spp", "2", "--workers", "1", "--quiet", "-o", str(out)]) == 2
        assert "uniform_lambert" in capsys.readouterr().err  # unknown without --plugin
        assert not out.exists()
        assert main(["render", str(path), "--spp", "2", "--workers", "1", "--quiet", "--plugin", str(PLUGIN),
                     "-o", str(out)]) == 0
        assert bl.read_exr(out).mean() > 0
    finally:
        for n in ("uniform_lambert", "uniform_lambert_broken"):
            plugins.unregister_bsdf(n)


def test_module_is_importable_as_given():
    assert sys.modules["brdflab"].__version__
    assert callable(bl.render) and callable(bl.load_scene)


@pytest.mark.parametrize("workers", ["1", "2"])
def test_render_with_a_broken_plugin_is_a_located_error(tmp_path, capsys, workers):
    """A plugin whose eval returns NaN stops the render with one located line, exit 2, no image."""
    plugin = tmp_path / "nan_bsdf.py"
    plugin.write_text(PLUGIN.read_text() + '''

class NaNLambert(UniformLambert):
    type_name = "nan_lambert"

    def eval(self, wi, wo, uv=None):
        f = super().eval(wi, wo, uv)
        f[::7] = np.nan
        return f
''')
    src = ROOT / "scenes" / "cbox" / "cbox_diffuse.xml"
    path = _plugin_scene(tmp_path, src, {'bsdf type="diffuse"': 'bsdf type="nan_lambert"'})
    out = tmp_path / "img.exr"
    try:
        status = main(["render", str(path), "--spp", "2", "--workers", workers, "--quiet", "--plugin", str(plugin),
                       "-o", str(out)])
    finally:
        for n in ("uniform_lambert", "uniform_lambert_broken", "nan_lambert"):
            plugins.unregister_bsdf(n)
    err = capsys.readouterr().err.strip()
    assert status == 2, err
    pattern = r"plugin_scene\.xml:\d+: bsdf \"nan_lambert\": nan_lambert\.eval\(.*\): non-finite value"
    assert re.search(pattern, err), err
    assert "Traceback" not in err and len(err.splitlines()) == 1 and len(err) <= 300
    assert not out.exists() and not out.with_suffix(".png").exists()


def test_guarded_scene_bsdf_pickles(user_plugin):
    """Scenes travel to cluster workers by pickle: the guard around a user's BSDF must survive it."""
    import pickle

    from brdflab.judges.core.guard import SceneCheckedBSDF

    b = SceneCheckedBSDF(plugins.make_bsdf("uniform_lambert", {"scale": "0.5"}), "scene.xml", 7)
    c = pickle.loads(pickle.dumps(b))
    assert (c.file, c.line, c.scale, c.type_name) == ("scene.xml", 7, 0.5, "uniform_lambert")
    wi = np.array([[0.0, 0.0, 1.0]])
    assert np.array_equal(c.eval(wi, wi), b.eval(wi, wi))
