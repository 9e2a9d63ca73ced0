"""Hostile input, part 4 (issue 41): numbers in other scripts, fits of tables and models that cannot be fitted,
the check's API arguments, brdflab's own point-light samples, MERL files whose size is wrong, and the bench's
failed runs. Each guard has a test here that fails when the guard is taken out (noted per test)."""

from __future__ import annotations

import ast
import tracemalloc

import numpy as np
import pytest

import brdflab as bl
from brdflab.bsdf.measured import HEADER, tabulate, write_merl
from brdflab.cli.main import main
from brdflab.errors import BrdflabError, ascii_int
from tests.conftest import CAMERA, QUAD_OBJ, ROOT, write_scene


def _one_line_error(capsys, pattern):
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.count("\n") == 1 and pattern in err, err


# -- numbers are ASCII digits ----------------------------------------------------------------------------------
def test_no_parser_trusts_isdigit():
    """The class of '²'.isdigit() (True, while int('²') raises): no module of brdflab calls str.isdigit,
    isdecimal or isnumeric to validate a number; they use :func:`brdflab.errors.ascii_int`."""
    calls = []
    for path in [*(ROOT / "brdflab").rglob("*.py"), *(ROOT / "cli").rglob("*.py")]:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Attribute) and node.attr in ("isdigit", "isdecimal", "isnumeric"):
                calls.append(f"{path.relative_to(ROOT)}:{node.lineno}")
    assert not calls, calls


@pytest.mark.parametrize("text", ["²", "\u0661", "１", "1²", "", " ", "+", "0x1"])
def test_ascii_int_refuses_other_digits(text):
    assert ascii_int(text) is None


def test_emitter_target_with_a_superscript_is_a_clean_error(tmp_path, capsys):
    scene = ROOT / "scenes/checker/checker_point.xml"
    samples = tmp_path / "s.txt"
    samples.write_text("0 0 0 0 1 0 0 0 0 1 1\n")
    assert main(["chi2", "--samples", str(samples), "--against-emitter", f"{scene}:²", "-o",
                 str(tmp_path / "o")]) == 2
    _one_line_error(capsys, "not found")


@pytest.mark.parametrize("n", ["\u0661", "²", "１"])
def test_count_options_refuse_other_digits(n, capsys):
    with pytest.raises(SystemExit) as e:
        main(["render", "scenes/cbox/cbox_diffuse.xml", "--spp", n])
    assert e.value.code == 2
    assert "expected an integer" in capsys.readouterr().err


# -- fits that cannot be done are errors, not results ----------------------------------------------------------
@pytest.fixture(scope="module")
def conductor_table():
    return tabulate(bl.RoughConductor(R0=[0.9, 0.6, 0.5], alpha=0.25))


@pytest.mark.parametrize("what, fill, message", [
    ("all NaN", np.nan, "no usable value"),
    ("all negative", -1.0, "no usable value"),
    ("all zero", 0.0, "nothing to fit"),
])
def test_fit_of_a_table_without_data_is_refused(tmp_path, capsys, what, fill, message):
    """Without _check_table the fit 'succeeds' with a relative error of 1e299 % (all NaN or negative values
    were read as 0)."""
    path = tmp_path / "m.binary"
    write_merl(path, np.full((90, 90, 180, 3), fill))
    with pytest.raises(BrdflabError, match=message):
        bl.fit(path, "roughconductor", stride=(4, 6, 12))
    assert main(["fit", str(path), "--effort", "quick", "-o", str(tmp_path / "f")]) == 2
    _one_line_error(capsys, message)
    assert not (tmp_path / "f" / "fit.html").exists()


def test_fit_leaves_unmeasured_nodes_out(conductor_table):
    """MERL marks unmeasured nodes negative: they are left out of the fit (not fitted as f = 0), so a table
    with a third of its nodes unmeasured still gives the model's parameters."""
    table = conductor_table.copy()
    table[np.random.default_rng(4).random(table.shape[:3]) < 1 / 3] = -1.0
    res = bl.fit(table, "roughconductor", stride=(4, 6, 12))
    assert abs(res.params["alpha"] - 0.25) < 1e-3, res.params


def test_fit_needs_enough_nodes(conductor_table):
    """stride (1000,)*3 left 3 residuals and a 'perfect' fit; now refused, naming the stride."""
    with pytest.raises(BrdflabError, match="usable node"):
        bl.fit(conductor_table, "roughconductor", stride=(60, 60, 120))
    for bad in ((1000, 1000, 1000), (0, 1, 1), (2, 3), ("a", 1, 1), (1.5, 1, 1), (True, 1, 1)):
        with pytest.raises(BrdflabError, match="stride"):
            bl.fit(conductor_table, "roughconductor", stride=bad)


class NaNModel(bl.BSDF):
    type_name = "hostile4_nan"
    KNOWN = {"alpha": "float"}

    def __init__(self, alpha=0.3):
        self.alpha = alpha

    @classmethod
    def from_properties(cls, props):
        return cls(props.get_float("alpha", 0.3))

    def eval(self, wi, wo, uv=None):
        f = np.full((len(wi), 3), 0.2)
        f[::7] = np.nan
        return f

    def pdf(self, wi, wo, uv=None):
        return np.ones(len(wi))

    def sample(self, wi, u, uv=None):
        raise NotImplementedError


class RaisingModel(NaNModel):
    type_name = "hostile4_raising"

    def eval(self, wi, wo, uv=None):
        raise ZeroDivisionError("division by zero in my model")


class HugeModel(NaNModel):
    type_name = "hostile4_huge"

    def eval(self, wi, wo, uv=None):
        return np.full((len(wi), 3), 1e200 / self.alpha)


@pytest.fixture
def models():
    from brdflab import plugins

    for cls in (NaNModel, RaisingModel, HugeModel):
        bl.register_bsdf(cls)
    yield
    for cls in (NaNModel, RaisingModel, HugeModel):
        plugins.unregister_bsdf(cls.type_name)


def test_fit_with_a_model_returning_nan_is_an_error(conductor_table, models):
    with pytest.raises(BrdflabError, match="returned NaN or infinite f"):
        bl.fit(conductor_table, "hostile4_nan", stride=(4, 6, 12))


def test_fit_with_a_raising_model_names_the_model(conductor_table, models):
    with pytest.raises(BrdflabError, match="raised ZeroDivisionError: division by zero in my model"):
        bl.fit(conductor_table, "hostile4_raising", stride=(4, 6, 12))


def test_fit_whose_residual_overflows_is_an_error(conductor_table, models):
    with pytest.raises(BrdflabError, match="overflowed|NaN or infinite"):
        bl.fit(conductor_table, "hostile4_huge", loss="linear", stride=(4, 6, 12))


def test_fit_tries_the_documented_starts(conductor_table):
    """Issue 40: the extra starts (α ∈ {0.05, 0.2, 0.5}) are really tried, in the α slot (a wrong index would put
    them into R0's channels and keep α at its default in every start)."""
    res = bl.fit(conductor_table, "roughconductor", stride=(4, 6, 12))
    alphas = [s["start"]["alpha"] for s in res.starts]
    assert alphas[1:] == [0.05, 0.2, 0.5] and len(set(alphas)) == 4
    r0 = [tuple(s["start"]["R0"]) for s in res.starts]
    assert len(set(r0)) == 1  # only α moves between starts


# -- the check's API arguments ---------------------------------------------------------------------------------
def _tiny_scene(tmp_path):
    point = '<emitter type="pointlight"><point name="position" value="0,2,0"/></emitter>'
    mesh = '<mesh type="obj"><string name="filename" value="q.obj"/></mesh>'
    return write_scene(tmp_path, '<integrator type="direct_ems"/>' + CAMERA + point + mesh, {"q.obj": QUAD_OBJ})


@pytest.mark.parametrize("where_spp", [-3, 2.5, "8", True])
def test_check_refuses_a_bad_where_spp(tmp_path, where_spp):
    scene = _tiny_scene(tmp_path)
    img = np.zeros((24, 32, 3), np.float32)
    with pytest.raises(BrdflabError, match="where_spp"):
        bl.check(img, scene, spp=1, runs=2, user_spp=1, where_spp=where_spp)


def test_check_takes_a_cluster_address(tmp_path):
    """bl.check(cluster='local:1') gave an AttributeError traceback ('str' has no attribute 'imap')."""
    scene = _tiny_scene(tmp_path)
    mine = bl.render(bl.load_scene(scene), spp=2, seed=3, workers=1)
    res = bl.check(mine, scene, spp=2, runs=2, user_spp=2, block=8, levels=1, where_spp=0, workers=1,
                   cluster="local:1")
    assert res.consistent in (True, False) and np.isfinite(res.p_value)


# -- brdflab's own point-light samples pass ---------------------------------------------------------------------
def test_own_point_light_samples_pass_and_a_wrong_pdf_fails(tmp_path):
    """brdflab's own point-light samples failed '--against-emitter' (pdf: 'no front-facing sample on an area
    light'; distribution: 1 cell, p = nan); a point light's pdf of 0.5 instead of 1 must still fail."""
    from brdflab.judges.samples.light_samples import check_emitter_samples, own_samples
    from brdflab.scene.loader import load_scene

    for rel in ("scenes/checker/checker_point.xml", "scenes/lights/mixed_lights_mis.xml"):
        scene = load_scene(ROOT / rel)
        rows = own_samples(scene, 0, 4_000, seed=7)
        np.savetxt(tmp_path / "good.txt", rows)
        res = check_emitter_samples(tmp_path / "good.txt", scene, 0)
        assert res.passed, res.messages()
        rows[:, 9] *= 0.5
        np.savetxt(tmp_path / "bad.txt", rows)
        res = check_emitter_samples(tmp_path / "bad.txt", scene, 0)
        assert not res.passed and any("point light" in c.hint for c in res.checks if not c.passed), res.messages()


# -- MERL files of the wrong size are refused from their size ---------------------------------------------------
def test_a_huge_sparse_merl_file_is_refused_without_reading_it(tmp_path):
    path = tmp_path / "huge.binary"
    with open(path, "wb") as f:
        f.write(HEADER.tobytes())
        f.truncate(2 * 2**30)  # 2 GiB, sparse: costs nothing on disk
    tracemalloc.start()
    try:
        with pytest.raises(BrdflabError, match="bytes, expected"):
            bl.fit(path, "roughconductor")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 64 * 2**20, f"peak {peak / 2**20:.0f} MiB while refusing a file by its size"


# -- the bench's failed runs: one line, never the child's traceback --------------------------------------------
def test_bench_says_why_a_run_failed_in_one_line(tmp_path, capsys):
    plugin = tmp_path / "boom.py"
    plugin.write_text("import brdflab as bl\n\nclass Boom(bl.BSDF):\n    type_name = 'boom4'\n\n"
                      "    def eval(self, wi, wo, uv=None):\n        raise ValueError('boom in eval')\n\n"
                      "    pdf = sample = eval\n")
    point = '<emitter type="pointlight"><point name="position" value="0,2,0"/></emitter>'
    mesh = '<mesh type="obj"><string name="filename" value="q.obj"/><bsdf type="boom4"/></mesh>'
    scene = write_scene(tmp_path, '<integrator type="direct_ems"/>' + CAMERA + point + mesh, {"q.obj": QUAD_OBJ})
    status = main(["bench", str(scene), "--plugin", str(plugin), "--spp", "1", "--runs", "1", "--workers", "1",
                   "--json", str(tmp_path / "b.json")])
    out = capsys.readouterr()
    assert status == 1
    assert "Traceback" not in out.out + out.err and 'File "' not in out.out + out.err
    assert "boom in eval" in out.out, out.out



def test_fit_bounds_by_parameter_name():
    """The bounds fit() gives each parameter (module docstring: α ∈ [10⁻³, 1], reflectances and colours in
    [0, 1], indices of refraction in [1, 3], anything else in [0, 10·default], at least [0, 1])."""
    from brdflab.fitting_data import bounds as _bounds

    assert _bounds("alpha", "float", 0.1) == (1e-3, 1.0)
    assert _bounds("alpha_u", "float", 0.1) == _bounds("alpha_v", "float", 0.1) == (1e-3, 1.0)
    assert _bounds("eta", "color", None) == (0.02, 5.0) and _bounds("k", "color", None) == (0.0, 10.0)  # a metal
    assert _bounds("R0", "color", 0.5) == (0.0, 1.0) and _bounds("kd", "float", 0.5) == (0.0, 1.0)
    assert _bounds("intIOR", "float", 1.5) == (1.0, 3.0)
    assert _bounds("exponent", "float", 20.0) == (0.0, 200.0)
    assert _bounds("exponent", "float", 0.01) == (0.0, 1.0)


def test_fit_standard_errors_follow_the_parameters(conductor_table):
    """Each parameter gets its own standard errors (a colour three, a float one), small for a noiseless table of
    the model itself, and none for a parameter at a bound (the linear approximation fails there)."""
    noisy = conductor_table * (1 + 0.03 * np.random.default_rng(9).standard_normal(conductor_table.shape))
    res = bl.fit(noisy, "roughconductor", stride=(4, 6, 12))
    se = res.uncertainty
    assert np.shape(se["R0"]) == (3,) and np.all(np.asarray(se["R0"]) > 0) and np.all(np.asarray(se["R0"]) < 0.01)
    assert isinstance(se["alpha"], float) and 0 < se["alpha"] < 0.01
    assert set(se) == {"R0", "alpha"} and res.to_dict()["uncertainty"]["alpha"] == se["alpha"]
