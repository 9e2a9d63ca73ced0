"""``fit`` of the models of issue 45: GGX or Beckmann (a fixed string parameter), anisotropic α_u/α_v and the
conductor's η/k (``free``), on synthetic data from a known model; a negative control (an isotropic model on
anisotropic data is flagged), isotropic tables give α_u ≈ α_v, and the refusals of ``free``."""

from __future__ import annotations

import json

import numpy as np
import pytest

import brdflab as bl
from brdflab.bsdf.measured import tabulate, write_merl
from brdflab.cli.main import main
from brdflab.errors import BrdflabError
from brdflab.fitting_data import noisy

STRIDE = (8, 10, 20)
FREE = "alpha_u,alpha_v,eta,k"


@pytest.fixture(scope="module")
def gold():
    """Anisotropic GGX with the η/k of gold: the truth of the synthetic data."""
    return bl.RoughConductor(distribution="ggx", alpha_u=0.15, alpha_v=0.3, material="Au")


@pytest.fixture(scope="module")
def gold_fit(gold):
    return bl.fit(noisy(gold, 0.05, seed=45), fixed={"distribution": "ggx"}, free=FREE, stride=STRIDE)


def test_anisotropic_ggx_gold_is_recovered_within_its_standard_errors(gold, gold_fit):
    """Each of the 8 fitted values lies within 3 of its reported standard errors of the truth (5 % noise). The
    errors' calibration is measured by ``benchmarks/fit_coverage.py`` (docs/benchmarks.md): 40 independent
    noise streams; with errors as reported, a value beyond 3 SE has probability 0.3 % (2 % for any of 8)."""
    res = gold_fit
    truth = {"alpha_u": 0.15, "alpha_v": 0.3, "eta": gold.eta, "k": gold.k}
    for k, v in truth.items():
        se = np.asarray(res.uncertainty[k])
        assert np.all(se > 0) and np.all(np.abs(np.asarray(res.params[k]) - v) < 3 * se), (k, res.params[k], v, se)
    assert res.params["distribution"] == "ggx" and res.phi_h == (0.0, 30.0, 60.0, 90.0)
    assert res.relative_error < 0.05 and not any("poor fit" in n or "anisotropic" in n for n in res.notes)
    # η and k trade off: their correlation is reported (and named in the notes when strong)
    lab, rho = res.correlation["labels"], np.asarray(res.correlation["matrix"])
    r_eta_k = [rho[lab.index(f"eta[{c}]"), lab.index(f"k[{c}]")] for c in "rgb"]
    assert max(abs(r) for r in r_eta_k) > 0.9, r_eta_k
    assert any("eta[" in n and "k[" in n and "correlated" in n for n in res.notes)


def test_an_isotropic_model_on_anisotropic_data_is_flagged(gold_fit):
    """Negative control: the same data (α_u = 0.15, α_v = 0.3) fitted with one α leave a residual many times
    the anisotropic fit's and a note that the data change with φ_h."""
    strong = bl.RoughConductor(distribution="ggx", alpha_u=0.08, alpha_v=0.5, material="Au")
    fixed = {"distribution": "ggx", "material": "Au"}
    iso = bl.fit(noisy(strong, 0.05, seed=46), fixed=fixed, free="alpha", stride=STRIDE)
    aniso = bl.fit(noisy(strong, 0.05, seed=46), fixed=fixed, free="alpha_u,alpha_v", stride=STRIDE)
    assert iso.rms > 3 * aniso.rms, (iso.rms, aniso.rms)
    assert any("anisotropic" in n for n in iso.notes), iso.notes
    assert any("poor fit" in n for n in iso.notes), (iso.relative_error, iso.notes)
    assert not any("anisotropic" in n or "poor fit" in n for n in aniso.notes), aniso.notes
    assert "NOTE:" in iso.summary() and "NOTE:" not in iso.summary(notes=False)


def test_a_beckmann_model_on_ggx_data_fits_worse_than_ggx(gold):
    """The distribution is a fixed choice: GGX data are fitted better by GGX than by Beckmann."""
    data = bl.RoughConductor(distribution="ggx", alpha=0.2, material="Cu")
    ggx = bl.fit(noisy(data, 0.02, seed=47), fixed={"distribution": "ggx", "material": "Cu"}, free="alpha",
                 stride=STRIDE)
    beck = bl.fit(noisy(data, 0.02, seed=47), fixed={"distribution": "beckmann", "material": "Cu"}, free="alpha",
                  stride=STRIDE)
    assert ggx.params["alpha"] == pytest.approx(0.2, rel=0.02)
    assert beck.rms > 2 * ggx.rms


def test_an_isotropic_table_gives_equal_alpha_u_and_alpha_v():
    """A measured (MERL) table is isotropic: an anisotropic fit of it finds α_u ≈ α_v, here for a table of a
    model (within 3 standard errors) and of a different material (roughsubstrate: a poor fit, still α_u ≈ α_v,
    as the table has no φ_h to tell them apart)."""
    rng = np.random.default_rng(48)
    table = tabulate(bl.RoughConductor(distribution="ggx", alpha=0.25, R0=[0.9, 0.7, 0.5]))
    res = bl.fit(table * rng.lognormal(0.0, 0.05, table.shape), "roughconductor",
                 fix=["distribution=ggx"], free=["R0", "alpha_u", "alpha_v"], stride=(6, 8, 15))
    au, av = res.params["alpha_u"], res.params["alpha_v"]
    se = np.hypot(res.uncertainty["alpha_u"], res.uncertainty["alpha_v"])
    assert abs(au - av) < 3 * se and au == pytest.approx(0.25, rel=0.02), (au, av, se)
    other = bl.fit(tabulate(bl.RoughSubstrate(kd=[0.5, 0.3, 0.2], alpha=0.2)), "roughconductor",
                   free=["R0", "alpha_u", "alpha_v"], stride=STRIDE)
    assert other.params["alpha_u"] == pytest.approx(other.params["alpha_v"], rel=1e-3), other.params


@pytest.mark.parametrize("free, message", [
    ("alpha_x", "no parameter 'alpha_x'"),
    ("distribution", "only float and colour"),
    ("R0,alpha,eta,k", "alternatives"),  # Schlick's R0 and η: the model refuses both
    ("alpha,alpha_u,alpha_v", "'alpha' does not change"),
    (",", "free names no parameter"),
])
def test_free_parameters_that_cannot_be_fitted_are_refused(gold, free, message):
    with pytest.raises(BrdflabError, match=message):
        bl.fit(gold, free=free, stride=STRIDE)


def test_a_parameter_both_fixed_and_free_is_refused(gold):
    with pytest.raises(BrdflabError, match="both fixed and free"):
        bl.fit(gold, fixed={"alpha_u": 0.1}, free="alpha_u", stride=STRIDE)


def test_the_cli_fits_alpha_u_alpha_v_and_the_page_shows_them(tmp_path, capsys):
    """``--free`` and ``--fix distribution=ggx`` on a MERL file; the page lists the new parameters, their
    standard errors and the correlations; a bad ``--free`` is one line and exit 2 (η and k: the tests above)."""
    path = tmp_path / "cu.binary"
    write_merl(path, tabulate(bl.RoughConductor(distribution="ggx", alpha=0.2, material="Cu")))
    out = tmp_path / "fit"
    assert main(["fit", str(path), "--fix", "distribution=ggx", "--fix", "material=Cu", "--free", "alpha_u",
                 "--free", "alpha_v", "--effort", "quick", "-o", str(out), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["params"]["alpha_u"] == pytest.approx(0.2, rel=1e-3) and d["params"]["alpha_v"] == pytest.approx(
        0.2, rel=1e-3)
    assert d["correlation"]["labels"] == ["alpha_u", "alpha_v"] and d["phi_h"] == [0, 30, 60, 90]
    page = (out / "fit.html").read_text()
    for word in ("alpha_u", "alpha_v", "material", "Cu", "Correlations of the fitted values"):
        assert word in page, word
    assert main(["fit", str(path), "--free", "nonsense", "--effort", "quick", "-o", str(tmp_path / "g")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no parameter 'nonsense'" in err[0]
