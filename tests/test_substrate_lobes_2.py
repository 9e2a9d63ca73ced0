"""The substrate's single lobes (``roughsubstrate/specular``, ``roughsubstrate/diffuse``, used by the validation
harness) against the mpmath references of tests/test_golden.py: each lobe's pdf is its own density (p_mf, or
cos θ_o/π) — not the mixture — its samples carry that pdf and the weight f cos θ_o / p, and the named-lobe
route of the battery selects it."""

from __future__ import annotations

import numpy as np
import pytest

from brdflab.bsdf.roughsubstrate import RoughSubstrate
from brdflab.judges.material.battery import make_named_bsdf
from tests.test_golden import (
    ETA_EXT,
    ETA_INT,
    KD,
    M,
    _tol,
    assert_close,
    direction_grid,
    ref_mf_pdf,
    ref_substrate,
    vec,
)

ALPHA = 0.3


def _pair(lobe: str) -> RoughSubstrate:
    return RoughSubstrate(np.array(KD), ALPHA, intIOR=ETA_INT, extIOR=ETA_EXT, lobe=lobe)


def test_lobe_pdfs_by_hand():
    wi, wo = direction_grid(ALPHA)
    up = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    spec, diff = _pair("specular"), _pair("diffuse")
    ref_p = [float(ref_mf_pdf(vec(a), vec(b), M(ALPHA))) for a, b in zip(wi, wo, strict=True)]
    assert_close(spec.pdf(wi, wo), ref_p, _tol(ALPHA, wi, wo), "specular lobe pdf")
    assert_close(spec.eval_pdf(wi, wo)[1], ref_p, _tol(ALPHA, wi, wo), "specular lobe eval_pdf")
    cos_pdf = np.where(up, np.maximum(wo[:, 2], 0) / np.pi, 0.0)
    assert_close(np.where(wi[:, 2] > 0, diff.pdf(wi, wo), 0.0), cos_pdf, 1e-12, "diffuse lobe pdf")
    # Both lobes together are the full f.
    ref_f = [ref_substrate(vec(a), vec(b), M(ALPHA), KD) for a, b in zip(wi, wo, strict=True)]
    assert_close(spec.eval(wi, wo) + diff.eval(wi, wo), ref_f, _tol(ALPHA, wi, wo), "specular + diffuse = f")


@pytest.mark.parametrize("lobe", ["specular", "diffuse", "both"])
def test_lobe_samples_carry_their_pdf_and_weight(lobe):
    b = _pair(lobe)
    rng = np.random.default_rng(17)
    n = 4000
    wi = np.tile([np.sin(0.6), 0.0, np.cos(0.6)], (n, 1))
    s = b.sample(wi, rng.random((n, 3)))
    ok = s.pdf > 0
    assert ok.mean() > 0.5
    np.testing.assert_allclose(s.pdf[ok], b.pdf(wi[ok], s.wo[ok]), rtol=1e-9)
    w = b.eval(wi[ok], s.wo[ok]) * (s.wo[ok, 2] / s.pdf[ok])[:, None]
    np.testing.assert_allclose(s.weight[ok], w, rtol=1e-9, atol=1e-300)
    if lobe == "diffuse":
        assert np.allclose(s.pdf[ok], s.wo[ok, 2] / np.pi)
    if lobe == "specular":  # every sample is a Beckmann reflection: its half vector is inside the lobe
        h = (wi[ok] + s.wo[ok]) / np.linalg.norm(wi[ok] + s.wo[ok], axis=1)[:, None]
        assert np.median(np.degrees(np.arccos(h[:, 2]))) < 25


def test_named_lobe_route():
    for lobe in ("specular", "diffuse"):
        b = make_named_bsdf(f"roughsubstrate/{lobe}", ALPHA, {"kd": np.array(KD)})
        assert b.lobe == lobe
        wi, wo = direction_grid(ALPHA)
        np.testing.assert_allclose(b.eval(wi, wo), _pair(lobe).eval(wi, wo), rtol=1e-12, atol=1e-300)
