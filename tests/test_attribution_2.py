"""Where and what, second line of defence (issue 40): the finding turns the fit into a sentence, respects the
coefficients' signs (a sign-blind reading turned 'B in excess' into 'the deficit follows all direct light'),
names only causes the scene's integrator can produce, and recognises a constant offset. Synthetic data, so the
truth is known; the render-level cases are in tests/test_attribution.py."""

from __future__ import annotations

import numpy as np

from brdflab.stats import attribution as A

YY, XX = np.mgrid[0:48, 0:48]
E = 1.0 + np.sin(XX / 7.0) + 0.5 * (YY / 48.0)
B = 0.3 + 0.3 * np.cos(YY / 5.0) * (XX / 48.0)
MASK = np.ones(E.shape, bool)


def _fit(d, seed=3):
    rng = np.random.default_rng(seed)
    return A.fit_cells(d + 0.01 * rng.standard_normal(d.shape), [E, B], ["E", "B"], MASK, 4)


def test_opposite_signs_are_the_mis_weight_signature():
    f = _fit(-0.3 * E + 0.3 * B)
    for sign in (-1, 1):
        text = A.interpret(f, sign, "direct_mis")
        assert "emitter-sampled light is short" in text and "BSDF-sampled light is in excess" in text, text
        assert "MIS weights" in text and "all direct light" not in text, text


def test_a_dominant_part_is_named_with_its_fit():
    """The issue's case: d ≈ −0.01·E − 1.85·B read 'nothing definite'."""
    f = _fit(-0.01 * E - 1.85 * B)
    text = A.interpret(f, -1, "direct_mis")
    assert "follows BSDF-sampled light" in text and "d ≈" in text and "·B" in text, text


def test_only_causes_the_integrator_can_produce():
    f = _fit(-0.3 * E)
    assert "follows emitter-sampled light" in A.interpret(f, -1, "direct_mis")
    mats = A.interpret(f, -1, "direct_mats")
    assert "samples only BSDFs" in mats and "light sampling" not in mats.split(":", 1)[0], mats
    path = A.interpret(f, -1, "path")
    assert "samples only BSDFs" in path, path
    ems = A.interpret(_fit(-0.3 * B), -1, "direct_ems")
    assert "light sampling" in ems and "BSDF-sampled" not in ems, ems


def _aux(material):
    return A.AuxImages(material=material, emitter_part=np.where(material >= 0, E, 0.0),
                       bsdf_part=np.where(material >= 0, B, 0.0), per_emitter=np.zeros((0,) + E.shape),
                       emitter_ids=[], material_labels=["m"], emitter_labels=[])


def test_a_constant_offset_is_recognised():
    """Radiance initialised to ε: the same +1e-4 lit or dark ('nothing definite' before)."""
    material = np.where(XX < 12, -1, 0)  # a band of background (misses)
    aux = _aux(material)
    rng = np.random.default_rng(5)
    d = 1e-4 + 2e-5 * rng.standard_normal(E.shape)
    text = A.offset_finding(d, aux, MASK, +1, 4)
    assert "a constant excess of +0.0001" in text and "unlit pixels too" in text, text
    assert A.offset_finding(2e-5 * rng.standard_normal(E.shape), aux, MASK, +1, 4) == ""  # no offset: silent
    assert A.offset_finding(-0.3 * aux.emitter_part + 1e-3 * rng.standard_normal(E.shape), aux, MASK, -1, 4) == ""


def test_fit_cells_by_hand():
    """Fit (1) recomputed by hand: weighted least squares over the cell means, HC3 standard errors, Student's t
    with cells − regressors degrees of freedom (mutations of the df and of the se = 0 branch survived)."""
    from scipy import stats

    rng = np.random.default_rng(11)
    d = -0.3 * E + 0.1 * B + 0.02 * rng.standard_normal(E.shape)
    mask = MASK.copy()
    mask[:5, :7] = False  # uneven cell counts: the weights matter
    f = A.fit_cells(d, [E, B], ["E", "B"], mask, 4)
    (y, e, b), cnt = A.cell_means([d, E, B], mask, 4)
    keep = cnt > 0
    w = np.sqrt(cnt[keep])
    X = np.stack([e[keep], b[keep]], axis=1) * w[:, None]
    yw = y[keep] * w
    beta, *_ = np.linalg.lstsq(X, yw, rcond=None)
    inv = np.linalg.inv(X.T @ X)
    r = yw - X @ beta
    h = np.einsum("ij,jk,ik->i", X, inv, X)
    cov = inv @ (X.T * (r / (1 - h)) ** 2) @ X @ inv
    se = np.sqrt(np.diag(cov))
    p = 2 * stats.t.sf(np.abs(beta / se), keep.sum() - 2)
    np.testing.assert_allclose(f.coef, beta, rtol=1e-10)
    np.testing.assert_allclose(f.se, se, rtol=1e-8)
    np.testing.assert_allclose(f.p, p, rtol=1e-6)
    assert f.cells == keep.sum()


def test_one_emitters_own_light_is_all_the_direct_light():
    """With one emitter its own light is E + B (mutated to E − B, the emitter fit read the wrong image)."""
    from tests.conftest import ROOT

    aux = A.render_aux(ROOT / "scenes/cbox/cbox_diffuse.xml", 2, 3, (32, 24), 1)
    assert aux.per_emitter.shape == (1, 24, 32)
    np.testing.assert_allclose(aux.per_emitter[0], aux.emitter_part + aux.bsdf_part, rtol=1e-12, atol=0)
    assert (aux.bsdf_part > 0).any()
