"""``chi2 --samples FILE --against dielectric|roughdielectric``: a student's transmitted samples (ω_o below the
surface) judged on their own terms; correct files pass, broken ones fail naming the problem."""

from __future__ import annotations

import numpy as np
import pytest

import brdflab as bl
from brdflab.judges.material import transmission_controls as tc
from brdflab.judges.samples.bsdf_checks import check_samples


def _file(path, bsdf, thetas=(30.0, 150.0), n=20_000, seed=0, weights=None, pdf=None):
    rng = np.random.default_rng(seed)
    rows = []
    for th in thetas:
        t = np.radians(th)
        wi = np.tile([np.sin(t), 0.0, np.cos(t)], (n, 1))
        s = bsdf.sample(wi, rng.random((n, 3)))
        ok = (s.pdf > 0)[:, None]
        w = s.weight if weights is None else weights(wi, s)
        p = s.pdf if pdf is None else pdf(wi, s)
        rows.append(np.column_stack([wi, np.where(ok, s.wo, 0.0), p, w]))
    np.savetxt(path, np.concatenate(rows), fmt="%.9g")
    return path


def test_dielectric_file_passes_in_either_convention(tmp_path):
    g = bl.Dielectric(1.5, 1.0)
    r = check_samples(_file(tmp_path / "a.txt", g), "dielectric", params={"intIOR": 1.5, "extIOR": 1.0})
    assert r.passed, r.messages()

    def course(wi, s):  # spec §10.4: the weight of a refraction is η_t/η_i
        refr = (s.wo[:, 2] * wi[:, 2] < 0)[:, None]
        return np.where(refr, np.where(wi[:, 2:] >= 0, 1.5, 1 / 1.5), 1.0) * np.ones((1, 3))

    r = check_samples(_file(tmp_path / "b.txt", g, weights=course), "dielectric", params={"intIOR": 1.5, "extIOR": 1.0})
    assert r.passed and "course" in "\n".join(r.messages())


@pytest.mark.parametrize("bad", [tc.InvertedEtaDielectric, tc.WrongCosineDielectric])
def test_broken_dielectric_files_fail(tmp_path, bad):
    path = _file(tmp_path / "bad.txt", bad(1.5, 1.0), thetas=(150.0, 160.0))
    r = check_samples(path, "dielectric", params={"intIOR": 1.5, "extIOR": 1.0})
    assert not r.passed


def test_dielectric_file_with_wrong_iors_fails(tmp_path):
    path = _file(tmp_path / "c.txt", bl.Dielectric(1.33, 1.0))
    assert not check_samples(path, "dielectric", params={"intIOR": 1.5, "extIOR": 1.0}).passed


def test_rough_dielectric_file_with_transmission_passes(tmp_path):
    g = bl.RoughDielectric(0.2, 1.5, 1.0)
    r = check_samples(_file(tmp_path / "r.txt", g), "roughdielectric", alpha=0.2, params={"intIOR": 1.5, "extIOR": 1.0})
    assert r.passed, r.messages()


@pytest.mark.filterwarnings("ignore:.*creates energy")  # the parameter hints try ka above 1
def test_rough_dielectric_file_without_jacobian_fails(tmp_path):
    """The student's pdf column (and weights) without the transmitted half-vector Jacobian: rejected."""
    bad = tc.NoJacobianRoughDielectric(0.2, 1.5, 1.0)
    r = check_samples(_file(tmp_path / "j.txt", bad), "roughdielectric", alpha=0.2,
                      params={"intIOR": 1.5, "extIOR": 1.0})
    assert not r.passed


def test_mirror_file(tmp_path):
    r = check_samples(_file(tmp_path / "m.txt", bl.Mirror(), thetas=(0.0, 45.0)), "mirror")
    assert r.passed, r.messages()
