"""Checks for any BSDF (issue 14, parts 3–5): a user's plugin through chi-square, consistency, furnace,
stability and the battery; contract violations as verdicts; per-test seeds; lobes of any shape; users'
own samples through ``chi2 --samples FILE --against NAME``."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

import brdflab.judges as v
from brdflab import BSDF, BSDFSample
from brdflab.bsdf.roughconductor import RoughConductor
from brdflab.cli.main import main
from brdflab.judges.material import chi2 as c2

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "phong.py"


def _load_example():
    spec = importlib.util.spec_from_file_location("example_phong", EXAMPLE)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


phong = _load_example()


# -- the example plugin through the battery API ---------------------------------------------------------
def test_example_phong_passes_the_whole_battery():
    bat = v.run_battery(n=10_000, bsdfs=[phong.Phong], warp_names=[], thetas=(0.0, 70.0),
                        consistency_thetas=(30.0,), furnace_thetas=(0.0, 60.0))
    assert bat.passed, bat.failures()
    # θ-only sweep (no alpha parameter) × the class's declared exponent grid.
    assert len(bat.chi2) == 3 * 2 and {r.params["exponent"] for r in bat.chi2} == {5.0, 20.0, 100.0}
    assert all("alpha" not in r.params for r in bat.chi2)
    assert len({r.seed for r in bat.chi2}) == len(bat.chi2)
    assert len(bat.consistency) == 3 and len(bat.albedo) == 6 and len(bat.stability) == 27
    # Golden value: the normalised lobe has ρ(0) = k_s exactly (module docstring of examples/phong.py).
    for p in (p for p in bat.albedo if p.theta == 0.0):
        assert p.quadrature == pytest.approx(0.8, abs=1e-6) and abs(p.monte_carlo - 0.8) < 5 * p.mc_stderr + 1e-6


def test_example_phong_broken_twin_fails_chi2():
    bat = v.run_battery(n=20_000, bsdfs=[("phong_broken", lambda a, p: phong.PhongBroken(**p))], warp_names=[],
                        thetas=(0.0, 45.0), params={"exponent": 20.0}, full=False)
    assert not bat.passed
    by_theta = {r.params["theta"]: r for r in bat.chi2}
    assert by_theta[0.0].passed  # about the normal the bug is invisible …
    assert not by_theta[45.0].passed and by_theta[45.0].p_value < 1e-9  # … and obvious elsewhere
    assert any("phong_broken" in f for f in bat.failures())


def test_furnace_quadrature_agrees_with_monte_carlo_for_phong():
    """The Phong plugin that gave quadrature 0.671 against Monte Carlo 0.706: now both agree."""
    res = v.furnace_test(phong.Phong(exponent=20.0), thetas=(30.0, 70.0, 85.0), samples=40_000)
    assert res.passed, res.message
    for p in res:
        assert abs(p.quadrature - p.monte_carlo) < 4 * p.sigma + 5e-4


def test_furnace_disagreement_fails_with_a_message():
    class Unnormalised(phong.Phong):  # eval 10 % too bright; sampler and pdf unchanged
        def eval(self, wi, wo, uv=None):
            return 1.1 * super().eval(wi, wo, uv)

        def sample(self, wi, u, uv=None):
            r = super().sample(wi, u, uv)
            return r._replace(weight=r.weight / 1.1)

    p = v.furnace_test(Unnormalised(exponent=20.0), theta=30.0, samples=20_000)[0]
    assert not p.passed and "DISAGREE" in p.message


# -- contract violations are verdicts, not tracebacks ---------------------------------------------------
class _Lambert(BSDF):
    type_name = "test_lambert_guard"
    reciprocal = True

    def __init__(self, albedo: float = 0.5) -> None:
        self.albedo = albedo

    def eval(self, wi, wo, uv=None):
        up = (wi[:, 2] > 0) & (wo[:, 2] > 0)
        return np.repeat((up * self.albedo / np.pi)[:, None], 3, axis=1)

    def pdf(self, wi, wo, uv=None):
        return np.where((wi[:, 2] > 0) & (wo[:, 2] > 0), wo[:, 2] / np.pi, 0.0)

    def sample(self, wi, u, uv=None):
        r, phi = np.sqrt(u[:, 0]), 2 * np.pi * u[:, 1]
        wo = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(np.maximum(0, 1 - u[:, 0]))], axis=1)
        pdf = self.pdf(wi, wo)
        return BSDFSample(wo, np.where((pdf > 0)[:, None], self.albedo, 0.0) * np.ones((1, 3)), pdf)


class _Raises(_Lambert):
    def sample(self, wi, u, uv=None):
        raise ZeroDivisionError("oops")


class _WrongShape(_Lambert):
    def eval(self, wi, wo, uv=None):
        return super().eval(wi, wo, uv)[:, 0]


class _NaNPdf(_Lambert):
    def pdf(self, wi, wo, uv=None):
        p = super().pdf(wi, wo, uv)
        return np.where(wo[:, 0] > 0.5, np.nan, p)


class _NegativePdf(_Lambert):
    def pdf(self, wi, wo, uv=None):
        return super().pdf(wi, wo, uv) - 0.01


class _WrongWeight(_Lambert):
    def sample(self, wi, u, uv=None):
        r = super().sample(wi, u, uv)
        return r._replace(weight=r.weight * 2.0)


@pytest.mark.parametrize(("cls", "method", "what"), [
    (_Raises, "sample", "raised ZeroDivisionError: oops"), (_WrongShape, "eval", "returned shape ("),
    (_NaNPdf, "pdf", "non-finite"), (_NegativePdf, "pdf", "negative value")])
def test_broken_plugins_get_a_verdict_naming_method_params_and_directions(cls, method, what):
    b = cls(albedo=0.7)
    results = [v.consistency_test(b, theta=20.0, samples=2_000), v.furnace_test(b, theta=20.0, samples=2_000)[0]]
    if method != "eval":  # chi-square never calls eval
        results.append(v.chi2_test(b, theta=20.0, samples=2_000))
    for r in results:
        assert not r.passed
        text = r.fault or r.message
        # A pdf fault shows first through sample() (which returns the pdf too): "….sample(…): … in pdf".
        assert "albedo=0.7" in text and (f".{method}(" in text or f"in {method}" in text) and what in text, text
        assert "at wi=(" in text, text


def test_inconsistent_weight_is_named_with_its_directions():
    r = v.consistency_test(_WrongWeight(0.5), theta=30.0, samples=5_000)
    assert not r.passed and "≠ eval·cos/pdf" in r.message and "first at wi=(" in r.message
    assert "0.866025), wo=" in r.message  # θ_i = 30°, at the test's own azimuth


def test_reciprocity_required_unless_declared_otherwise():
    class Skew(_Lambert):  # f depends on wi and wo differently: not reciprocal
        def eval(self, wi, wo, uv=None):
            return super().eval(wi, wo, uv) * (0.5 + 0.5 * wi[:, 2:3])

        def sample(self, wi, u, uv=None):
            r = super().sample(wi, u, uv)
            return r._replace(weight=r.weight * (0.5 + 0.5 * wi[:, 2:3]))

    class DeclaredSkew(Skew):
        reciprocal = False

    bad, ok = v.consistency_test(Skew(), theta=40.0, samples=5_000), v.consistency_test(DeclaredSkew(), theta=40.0,
                                                                                         samples=5_000)
    assert not bad.passed and "f(wi, wo) ≠ f(wo, wi)" in bad.message
    assert ok.passed and ok.max_reciprocity_error > 1e-3 and "not required" in ok.message


def test_pdf_with_more_than_unit_mass_fails():
    class Heavy(_Lambert):
        def pdf(self, wi, wo, uv=None):
            return 1.2 * super().pdf(wi, wo, uv)

    r = v.chi2_test(Heavy(), theta=10.0, samples=5_000)
    assert not r.passed and r.integral == pytest.approx(1.2, rel=1e-3) and "∫ p dω" in r.fault


def test_each_test_has_its_own_stream():
    """Six configurations of one plugin (formerly all p = 0.1049 from seed 0) get six seeds and p-values."""
    res = [v.chi2_test(phong.Phong(exponent=e), theta=t, samples=4_000) for e in (10.0, 30.0) for t in (0, 30, 60)]
    assert len({r.seed for r in res}) == 6 and len({round(r.p_value, 6) for r in res}) == 6
    again = v.chi2_test(phong.Phong(exponent=10.0), theta=0, samples=4_000)
    assert again.seed == res[0].seed and again.p_value == res[0].p_value  # reproducible


# -- lobes of any shape ---------------------------------------------------------------------------------
class _TwoLobes(phong.Phong):
    """A mirror lobe plus a retro-reflection lobe (about ω_i), chosen with probability ``w_retro``."""

    type_name = "test_two_lobes"

    def __init__(self, exponent: float = 200.0, w_retro: float = 0.3, sample_w: float | None = None) -> None:
        super().__init__(exponent=exponent)
        self.w_retro, self.sample_w = w_retro, w_retro if sample_w is None else sample_w

    def _lobe(self, axis, wo):
        n = self.exponent
        return (n + 1) / (2 * np.pi) * np.clip(np.sum(axis * wo, axis=1), 0, 1) ** n

    def pdf(self, wi, wo, uv=None):
        p = (1 - self.w_retro) * self._lobe(self._mirror(wi), wo) + self.w_retro * self._lobe(wi, wo)
        return np.where(wi[:, 2] > 0, p, 0.0)

    def eval(self, wi, wo, uv=None):
        up = (wi[:, 2] > 0) & (wo[:, 2] > 0)
        return np.where(up, 0.5 * self.pdf(wi, wo), 0.0)[:, None] * np.ones(3)

    def sample(self, wi, u, uv=None):
        retro = u[:, 2] < self.sample_w
        self._axis = np.where(retro[:, None], wi, self._mirror(wi))
        return super().sample(wi, u, uv)

    def _lobe_axis(self, wi):
        return self._axis


@pytest.mark.parametrize("theta", [35.0, 75.0])
def test_two_sharp_lobes_anywhere(theta):
    assert v.chi2_test(_TwoLobes(), theta=theta, samples=20_000).passed
    wrong = v.chi2_test(_TwoLobes(sample_w=0.36), theta=theta, samples=20_000)  # lobe choice ≠ pdf's weights
    assert not wrong.passed


def test_very_sharp_lobe_is_integrated():
    r = v.chi2_test(phong.Phong(exponent=1e5), theta=60.0, samples=20_000)
    assert r.passed and r.integral == pytest.approx(r.valid_fraction, abs=1e-4)


def test_pilot_is_independent_of_the_observed_sample():
    """The bins come from their own stream: the same seed with another observed stream gives other counts."""
    b = RoughConductor(R0=0.5, alpha=0.2)
    r1 = c2.bsdf_test("rc", b, 30.0, 5_000, seed=11)
    r2 = c2.bsdf_test("rc", b, 30.0, 5_000, seed=12)
    assert not np.array_equal(r1.theta_edges, r2.theta_edges) and r1.passed and r2.passed


# -- users' own samples (chi2 --samples FILE --against NAME) ---------------------------------------------
def _beckmann_reference(wi: np.ndarray, u: np.ndarray, alpha: float, warp_bug: bool = False):
    """An independent Beckmann sampler (as a C++ renderer would write it): ω_h by inversion, reflect ω_i."""
    tan2 = -(alpha if warp_bug else alpha * alpha) * np.log(1.0 - u[:, 0])  # bug: α instead of α²
    cos_h = 1.0 / np.sqrt(1.0 + tan2)
    sin_h = np.sqrt(np.maximum(0.0, 1.0 - cos_h**2))
    phi = 2.0 * np.pi * u[:, 1]
    h = np.stack([sin_h * np.cos(phi), sin_h * np.sin(phi), cos_h], axis=1)
    d = np.sum(wi * h, axis=1)
    wo = 2.0 * d[:, None] * h - wi
    D = np.exp(-tan2 / alpha**2) / (np.pi * alpha**2 * cos_h**4)
    pdf_h = D * cos_h
    pdf = pdf_h / (4.0 * np.abs(np.sum(wo * h, axis=1)))
    failed = (d <= 0) | (wo[:, 2] <= 0)
    return np.where(failed[:, None], 0.0, wo), np.where(failed, 0.0, pdf), np.where(failed, 0.0, pdf_h)


def _write(path: Path, alpha: float, n: int = 6_000, seed: int = 3, **kw) -> tuple[Path, Path]:
    rng = np.random.default_rng(seed)
    rows, rows_h = [], []
    for theta in (20.0, 65.0):
        wi = np.tile([np.sin(np.radians(theta)), 0.0, np.cos(np.radians(theta))], (n, 1))
        wo, pdf, pdf_h = _beckmann_reference(wi, rng.random((n, 2)), alpha, **kw)
        rows.append(np.column_stack([wi, wo, pdf]))
        rows_h.append(np.column_stack([wi, wo, pdf_h]))
    np.savetxt(path, np.concatenate(rows), fmt="%.8g", header="wi_x wi_y wi_z wo_x wo_y wo_z pdf")
    bad = path.with_name("noJacobian_" + path.name)
    np.savetxt(bad, np.concatenate(rows_h), fmt="%.8g")
    return path, bad


def _o(tmp_path: Path) -> list[str]:
    """The report folder of ``chi2 --samples`` (it writes an HTML report; not into the repository's reports/)."""
    return ["-o", str(tmp_path / "r")]


def test_external_beckmann_samples_pass(tmp_path, capsys):
    good, _ = _write(tmp_path / "beckmann.txt", 0.2)
    assert main(["chi2", "--samples", str(good), "--against", "roughconductor", "--alpha", "0.2"] + _o(tmp_path)) == 0
    out = capsys.readouterr().out
    assert "2 wi group(s)" in out and "ALL PASSED" in out
    # The warp itself: microfacet normals "x y z pdf", with the independent inversion above.
    u = np.random.default_rng(4).random((6_000, 2))
    tan2 = -0.04 * np.log(1.0 - u[:, 0])
    c = 1.0 / np.sqrt(1.0 + tan2)
    s = np.sqrt(1.0 - c * c)
    h = np.stack([s * np.cos(2 * np.pi * u[:, 1]), s * np.sin(2 * np.pi * u[:, 1]), c], axis=1)
    np.savetxt(tmp_path / "h.txt", np.column_stack([h, np.exp(-tan2 / 0.04) / (np.pi * 0.04 * c**3)]), fmt="%.9g")
    h_txt = str(tmp_path / "h.txt")
    assert main(["chi2", "--samples", h_txt, "--against", "beckmann", "--alpha", "0.2"] + _o(tmp_path)) == 0
    assert main(["chi2", "--samples", h_txt, "--against", "beckmann", "--alpha", "0.25"] + _o(tmp_path)) == 1


def test_external_warp_bug_and_missing_jacobian_fail_saying_which(tmp_path, capsys):
    wrong, _ = _write(tmp_path / "bug.txt", 0.2, warp_bug=True)
    assert main(["chi2", "--samples", str(wrong), "--against", "roughconductor", "--alpha", "0.2"] + _o(tmp_path)) == 1
    out = capsys.readouterr().out
    assert "WRONG DISTRIBUTION" in out
    _, nojac = _write(tmp_path / "ok.txt", 0.2)
    assert main(["chi2", "--samples", str(nojac), "--against", "roughconductor", "--alpha", "0.2"] + _o(tmp_path)) == 1
    out = capsys.readouterr().out
    assert "WRONG PDF COLUMN" in out and "lacks the 1/(4|ωo·ωh|) Jacobian" in out and "WRONG DISTRIBUTION" not in out
    assert f"{nojac}:" in out  # the worst sample is located by file:line


def test_external_npy_weights_and_warp_files(tmp_path):
    b = RoughConductor(R0=0.9, alpha=0.3)
    rng = np.random.default_rng(8)
    wi = np.tile([0.5, 0.0, np.sqrt(0.75)], (8_000, 1))
    s = b.sample(wi, rng.random((8_000, 3)))
    np.save(tmp_path / "rc.npy", np.column_stack([wi, s.wo, s.pdf, s.weight]))
    res = v.check_samples(tmp_path / "rc.npy", "roughconductor", alpha=0.3, params={"R0": 0.9})
    assert res.passed, res.messages()
    assert res.groups[0].weight.max_rel_error < 1e-9 and res.groups[0].pdf.max_rel_error < 1e-9
    cos_bug = np.column_stack([wi, s.wo, s.pdf, s.weight * (wi[:, 2] / np.maximum(s.wo[:, 2], 1e-9))[:, None]])
    np.savez(tmp_path / "cosbug.npz", samples=cos_bug)
    res = v.check_samples(tmp_path / "cosbug.npz", "roughconductor", alpha=0.3, params={"R0": 0.9})
    assert not res.passed and "cos θi instead of cos θo" in "\n".join(res.messages())
    from brdflab.math import warps

    d = warps.square_to_cosine_hemisphere(rng.random((5_000, 2)))
    np.savetxt(tmp_path / "cos.txt", np.column_stack([d, d[:, 2] / np.pi]))
    assert v.check_samples(tmp_path / "cos.txt", "cosine_hemisphere").passed
    assert not v.check_samples(tmp_path / "cos.txt", "uniform_hemisphere").passed


@pytest.mark.parametrize(("text", "message"), [
    ("0 0 1 0 0 1 0.3\n0 0 1 0 0 1\n", "bad.txt:2: 6 columns, but line 1 has 7"),
    ("# c\n0 0 1 0 0 x\x07yz 0.3\n", "bad.txt:2: 'x\\x07yz' is not a number"),
    ("0 0 1 0 0 1 0.3 1\n", "bad.txt:1: 8 columns; expected 6, 7 or 10"),
    ("nan 0 1 0 0 1\n", "bad.txt:1: wi is not finite"),
    ("# only a comment\n", "bad.txt: no samples")])
def test_bad_sample_files_exit_2_with_file_and_line(tmp_path, capsys, text, message):
    p = tmp_path / "bad.txt"
    p.write_text(text)
    assert main(["chi2", "--samples", str(p), "--against", "beckmann", "--alpha", "0.1"]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_samples_count_is_deprecated_but_works(tmp_path, capsys):
    out = tmp_path / "r"
    assert main(["chi2", "--warp", "cosine_hemisphere", "--samples", "5000", "-o", str(out)]) == 0
    assert "deprecated; use '-n/--count N'" in capsys.readouterr().err
    assert main(["chi2", "--warp", "cosine_hemisphere", "-n", "5000", "-o", str(out)]) == 0
    assert main(["chi2", "--against", "beckmann", "-n", "5000"]) == 2
    assert main(["chi2", "--samples", str(tmp_path / "missing.txt"), "--against", "beckmann"]) == 2
    assert "not found" in capsys.readouterr().err


# -- the example plugin from the command line -------------------------------------------------------------
def test_cli_chi2_and_validate_with_the_example_plugin(tmp_path, capsys):
    from brdflab import plugins

    try:
        args = ["--plugin", str(EXAMPLE), "--theta", "40", "-n", "20000"]
        assert main(["chi2", *args, "--bsdf", "phong", "--param", "exponent=20", "-o", str(tmp_path / "a")]) == 0
        assert main(["chi2", *args, "--bsdf", "phong_broken", "--param", "exponent=20",
                     "-o", str(tmp_path / "b")]) == 1
        assert "FAIL" in capsys.readouterr().out
        assert main(["validate", "--plugin", str(EXAMPLE), "--bsdf", "phong", "--param", "exponent=50",
                     "--theta", "40", "--samples", "20000", "-o", str(tmp_path / "v")]) == 0
    finally:
        for n in ("phong", "phong_broken"):
            plugins.unregister_bsdf(n)


def test_example_scene_renders_with_the_plugin(tmp_path):
    from brdflab import plugins

    out = tmp_path / "phong.exr"
    try:
        assert main(["render", str(ROOT / "examples" / "phong_scene.xml"), "--plugin", str(EXAMPLE), "--spp", "2",
                     "--workers", "1", "--quiet", "-o", str(out)]) == 0
        import brdflab as bl

        img = bl.read_exr(out)
        assert img.shape == (120, 160, 3) and np.isfinite(img).all() and img.mean() > 0
    finally:
        for n in ("phong", "phong_broken"):
            plugins.unregister_bsdf(n)
