"""The validation harness: chi-square on every sampler, the planted Jacobian bug, consistency, furnace,
stability, and the CLI with its HTML report."""

from __future__ import annotations

import numpy as np
import pytest

from brdflab.bsdf.diffuse import Diffuse
from brdflab.bsdf.roughconductor import RoughConductor
from brdflab.bsdf.roughsubstrate import RoughSubstrate
from brdflab.cli.main import main
from brdflab.judges.material import chi2 as c2
from brdflab.judges.material import consistency, furnace, stability
from brdflab.judges.material.battery import ALPHAS, THETAS, NoJacobianConductor, plan, run_battery, run_chi2

N = 40_000


def test_chi2_battery_all_samplers():
    """Every warp, BSDF and substrate lobe over the α × θ grid passes at Šidák-corrected 0.01."""
    tests = plan(alphas=(1e-3, 0.05, 0.3, 1.0), thetas=(0.0, 60.0, 89.0))
    thr = c2.sidak(0.01, len(tests))
    res = run_chi2(tests, N, thr)
    bad = [(r.name, r.params, r.p_value) for r in res if not r.passed]
    assert not bad, bad
    names = {r.name for r in res}
    assert {"roughconductor", "roughsubstrate", "roughsubstrate/specular", "roughsubstrate/diffuse", "diffuse",
            "beckmann", "cosine_hemisphere", "uniform_triangle", "uniform_disk"} <= names


def test_full_grid_is_planned():
    tests = plan()
    assert sum(1 for t in tests if t[1] == "roughconductor") == len(ALPHAS) * len(THETAS)


@pytest.mark.parametrize("theta", [0.0, 30.0, 60.0])
def test_planted_jacobian_bug_is_rejected(theta):
    r = c2.bsdf_test("bug", NoJacobianConductor(0.5, 0.3), theta, N, seed=1)
    assert not r.passed and r.p_value < 1e-6


def test_wrong_lobe_probability_is_rejected():
    """A substrate that samples the specular lobe twice as often as its pdf says must fail."""
    class Skewed(RoughSubstrate):
        def _p_specular(self, cos_i):
            return np.minimum(1.0, 2 * super()._p_specular(cos_i)) if getattr(self, "_sampling", False) \
                else super()._p_specular(cos_i)

        def sample(self, wi, u, uv=None):
            self._sampling = True
            spec = u[:, 2] < self._p_specular(wi[:, 2])
            self._sampling = False
            u = u.copy()
            u[:, 2] = np.where(spec, 0.0, 1.0)
            return super().sample(wi, u, uv)

    r = c2.bsdf_test("skewed", Skewed(0.5, 0.05), 70.0, 200_000, seed=2)
    assert not r.passed


def test_cosine_warp_with_uniform_pdf_is_rejected():
    from brdflab.math import warps

    r = c2.warp_test("wrong", warps.square_to_cosine_hemisphere, warps.square_to_uniform_hemisphere_pdf, N)
    assert not r.passed


@pytest.mark.parametrize("bsdf", [Diffuse(0.7), RoughConductor(np.array([1.0, 0.7, 0.3]), 0.2),
                                  RoughConductor(0.9, 1e-3), RoughSubstrate(np.array([0.2, 0.4, 0.8]), 0.05),
                                  RoughSubstrate(0.5, 1.0)])
@pytest.mark.parametrize("theta", [0.0, 45.0, 85.0])
def test_consistency(bsdf, theta):
    r = consistency.check_bsdf(type(bsdf).__name__, bsdf, theta, n=50_000)
    assert r.max_weight_error <= 1e-5
    assert r.pdf_integral <= 1 + 1e-3
    assert abs(r.pdf_integral - r.valid_fraction) < 0.01
    assert r.max_reciprocity_error <= 1e-9
    assert r.negative_or_nonfinite == 0


def test_weight_check_detects_wrong_cosine():
    """The student bug (cos θ_i instead of cos θ_o in the weight) is caught by the consistency check."""
    class WrongCos(RoughConductor):
        def sample(self, wi, u, uv=None):
            r = super().sample(wi, u, uv)
            fix = np.where(r.wo[:, 2] > 0, wi[:, 2] / np.where(r.wo[:, 2] > 0, r.wo[:, 2], 1.0), 0.0)
            return r._replace(weight=r.weight * fix[:, None])

    assert consistency.check_bsdf("wrong", WrongCos(0.5, 0.3), 60.0, n=20_000).max_weight_error > 1e-3


@pytest.mark.parametrize("alpha", [0.05, 0.5, 1.0])
def test_furnace(alpha):
    for name, make in (("c", lambda a: RoughConductor(1.0, a)), ("s", lambda a: RoughSubstrate(1.0, a))):
        for p in furnace.albedo_curve(name, make, alpha, [0.0, 40.0, 80.0], n=40_000):
            assert p.passed, p
    # Energy is lost at high roughness by the single-scattering model, not created.
    assert furnace.albedo_quadrature(RoughConductor(1.0, 1.0), 0.0, 1.0) < 0.6


def test_furnace_detects_energy_gain():
    class TooBright(RoughConductor):
        def eval(self, wi, wo, uv=None):
            return 1.3 * super().eval(wi, wo, uv)

    p = furnace.albedo_curve("bright", lambda a: TooBright(1.0, a), 0.05, [0.0], n=20_000)[0]
    assert not p.passed


def test_stability():
    rows = stability.run()
    assert len(rows) > 100
    assert all(r.passed for r in rows), [r for r in rows if not r.passed][:5]


def test_cli_chi2_and_validate_reports(tmp_path, capsys):
    out = tmp_path / "r"
    assert main(["chi2", "--bsdf", "roughconductor", "--alpha", "0.1", "--theta", "30", "--samples", "20000",
                 "-o", str(out)]) == 0
    text = (out / "index.html").read_text()
    assert "roughconductor" in text and "pass" in text and "data:image/png;base64" in text
    assert main(["chi2", "--warp", "beckmann", "--alpha", "0.01", "--samples", "20000", "-o", str(tmp_path / "w")]) == 0
    capsys.readouterr()
    with pytest.raises(SystemExit) as exc:  # a usage error (argparse): exit status 2, one line
        main(["chi2", "--bsdf", "roughconductor", "--alpha", "-1"])
    assert exc.value.code == 2
    assert "--alpha: must be a finite number ≥ 1e-06, got -1" in capsys.readouterr().err


def test_battery_small_full_run(tmp_path):
    from brdflab.pages.validation import write_validation_report

    bat = run_battery(n=20_000, bsdfs=["roughconductor"], warp_names=["beckmann"], alphas=(0.1,), thetas=(30.0,),
                      furnace_alphas=(0.1, 1.0), furnace_thetas=(0.0, 60.0, 85.0))
    assert bat.passed, bat.failures()
    assert bat.negative_control and all(not r.passed for r in bat.negative_control)
    path = write_validation_report(bat, tmp_path)
    assert "albedo.png" in {p.name for p in tmp_path.iterdir()} and path.exists()
