"""``chi2 --samples FILE --against-emitter SCENE[:INDEX]`` (brdflab/judges/samples/light_samples.py): brdflab's own
light samples pass; each planted student bug fails with its named hint."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import stats

from brdflab.cli.main import main
from brdflab.judges.lights.samplers import emitter_triangles, reference_points
from brdflab.judges.samples import light_samples as ES
from brdflab.scene.loader import load_scene
from tests.conftest import ROOT

POLY = ROOT / "scenes" / "lights" / "polygon_lights_mis.xml"  # 0: hexagon (6 triangles), 1: smooth sphere
SPHERE = ROOT / "scenes" / "lights" / "sphere_light_mis.xml"  # 0: faceted sphere, unequal triangles


@pytest.fixture(scope="module")
def poly():
    return load_scene(POLY)


@pytest.fixture(scope="module")
def sphere():
    return load_scene(SPHERE)


def student(scene, index: int, n: int, seed: int, uniform_tri=False, warp_bug=False, measure=1) -> np.ndarray:
    """A student's light sampler of a flat-shaded mesh light (written independently of brdflab's): a
    triangle by area (or, buggy, uniformly), a point by the square-to-triangle warp (or a wrong one)."""
    em = scene.emitters[index]
    tri = emitter_triangles(em)
    area = em.geometry.tri_area[em.tris]
    rng = np.random.default_rng(seed)
    p, _ = reference_points(scene, seed=seed)
    x = p[rng.integers(0, len(p), n)]
    k = rng.integers(0, len(tri), n) if uniform_tri else rng.choice(len(tri), n, p=area / area.sum())
    u1, u2 = rng.random(n), rng.random(n)
    b1, b2 = (u1, u2 * (1 - u1)) if warp_bug else (1 - np.sqrt(u1), u2 * np.sqrt(u1))
    y = tri[k, 0] + b1[:, None] * (tri[k, 1] - tri[k, 0]) + b2[:, None] * (tri[k, 2] - tri[k, 0])
    nrm = np.cross(tri[k, 1] - tri[k, 0], tri[k, 2] - tri[k, 0])
    nrm /= np.linalg.norm(nrm, axis=1)[:, None]
    v = x - y
    r2 = np.sum(v * v, axis=1)
    cos = np.sum(nrm * v, axis=1) / np.sqrt(r2)
    p_a = 1.0 / (len(tri) * area[k]) if uniform_tri else np.full(n, 1.0 / area.sum())
    pdf = np.where(cos > 0, p_a * r2 / np.abs(cos), 0.0) if measure else p_a
    return np.column_stack([x, y, nrm, pdf, np.full(n, measure)])


def _check(tmp_path, arr, scene, index, name="s.npy"):
    np.save(tmp_path / name, arr)
    return ES.check_emitter_samples(tmp_path / name, scene, index)


def _failed(res) -> dict:
    return {c.name: c.hint for c in res.checks if not c.passed}


@pytest.mark.parametrize("index", [None, 1])
def test_own_samples_pass(tmp_path, poly, index):
    res = _check(tmp_path, ES.own_samples(poly, index, 8000, seed=3), poly, index)
    assert res.passed, res.messages()
    assert {c.name for c in res.checks} == {"points on the emitter", "normals", "self-consistency", "pdf",
                                            "distribution", "radiance"}


def test_student_sampler_passes_in_either_measure(tmp_path, sphere):
    assert _check(tmp_path, student(sphere, 0, 8000, 1), sphere, 0).passed
    assert _check(tmp_path, student(sphere, 0, 8000, 2, measure=0), sphere, 0).passed


def test_area_pdf_flagged_as_solid_angle(tmp_path, poly):
    a = ES.own_samples(poly, None, 6000, seed=4)
    v = a[:, 0:3] - a[:, 3:6]
    r2 = np.sum(v * v, axis=1)
    cos = np.abs(np.sum(a[:, 6:9] * v, axis=1)) / np.sqrt(r2)
    a[:, 9] = a[:, 9] * cos / r2  # p_A (selection included), still flagged 1
    bad = _failed(_check(tmp_path, a, poly, None))
    assert set(bad) == {"self-consistency", "pdf"} and "area measure but flagged as solid angle" in bad["pdf"]


def test_missing_selection_probability(tmp_path, poly):
    a = ES.own_samples(poly, None, 6000, seed=5)
    a[:, 9] /= np.asarray(poly.emitter_pmf)[0]  # uniform over 2 emitters: p_sel = 1/2 forgotten
    bad = _failed(_check(tmp_path, a, poly, None))
    assert set(bad) == {"self-consistency", "pdf"} and "missing emitter-selection probability" in bad["pdf"]


def test_uniform_triangle_selection(tmp_path, sphere):
    """Triangles chosen uniformly *with* the pdf that goes with it, 1/(K·A_k), is a correct sampler of another
    method than brdflab's: it passes, saying so. Chosen uniformly but claiming brdflab's 1/A is the bug."""
    fair = student(sphere, 0, 8000, 6, uniform_tri=True)
    res = _check(tmp_path, fair, sphere, 0)
    assert res.passed, res.messages()
    assert any("different sampling method than brdflab's (self-consistent)" in c.summary for c in res.checks)
    em = sphere.emitters[0]
    claimed = fair.copy()
    v = claimed[:, 0:3] - claimed[:, 3:6]
    r2 = np.sum(v * v, axis=1)
    cos = np.sum(claimed[:, 6:9] * v, axis=1) / np.sqrt(r2)
    claimed[:, 9] = np.where(cos > 0, r2 / np.abs(cos) / em.area, 0.0)  # brdflab's pdf, but uniform triangles
    bad = _failed(_check(tmp_path, claimed, sphere, 0))
    assert set(bad) == {"self-consistency", "distribution"}, bad
    assert "chosen uniformly, not by area" in bad["distribution"]


def test_wrong_triangle_warp(tmp_path, poly):
    bad = _failed(_check(tmp_path, student(poly, 0, 8000, 7, warp_bug=True), poly, 0))
    assert set(bad) == {"self-consistency", "distribution"} and "square-to-triangle warp" in bad["distribution"]


def test_points_off_the_light_and_flipped_normals(tmp_path, poly):
    a = student(poly, 0, 3000, 8)
    b = a.copy()
    b[:, 3:6] += 0.01 * b[:, 6:9]  # lifted off the light's plane
    bad = _failed(_check(tmp_path, b, poly, 0))
    assert "points on the emitter" in bad and "off it" in next(c.summary for c in _check(tmp_path, b, poly, 0).checks)
    c = a.copy()
    c[:, 6:9] *= -1
    bad = _failed(_check(tmp_path, c, poly, 0))
    assert set(bad) == {"normals"} and "other way" in bad["normals"]


def test_radiance_divided_by_pdf(tmp_path, poly):
    a = ES.own_samples(poly, 0, 3000, seed=9)
    ok = a[:, 9] > 0
    a[ok, 11:14] /= a[ok, 9][:, None]
    bad = _failed(_check(tmp_path, a, poly, 0))
    assert set(bad) == {"radiance"} and "divided by the pdf" in bad["radiance"]


def test_chi_square_false_alarm_rate(poly):
    """Correct samples fail the distribution test at most at the binomial bound of its 1 % level (40 files)."""
    fails = sum(not ES.check_emitter_samples(ES.EmitterSamples("m", *_cols(student(poly, 0, 1500, 100 + t))),
                                             poly, 0).passed for t in range(40))
    assert fails <= stats.binom.isf(0.01, 40, 0.01), fails


def _cols(a):
    return a[:, 0:3], a[:, 3:6], a[:, 6:9], a[:, 9], a[:, 10] == 1, None, np.arange(len(a))


def test_cli_exit_codes(tmp_path, capsys):
    good, bad = tmp_path / "good.txt", tmp_path / "bad.txt"
    sc = load_scene(POLY)
    np.savetxt(good, ES.own_samples(sc, 0, 3000, seed=11), header="x y n pdf measure L")
    a = ES.own_samples(sc, 0, 3000, seed=12)
    a[:, 9] *= 2.0
    np.savetxt(bad, a)
    assert main(["chi2", "--samples", str(good), "--against-emitter", f"{POLY}:0", "-o", str(tmp_path / "r1")]) == 0
    assert "ALL PASSED" in capsys.readouterr().out
    d = json.loads((tmp_path / "r1" / "emitter_samples.json").read_text())
    assert d["passed"] and d["samples"] == 3000
    assert main(["chi2", "--samples", str(bad), "--against-emitter", f"{POLY}:0", "-o", str(tmp_path / "r2")]) == 1
    assert "FAIL pdf" in capsys.readouterr().out
    (tmp_path / "m.txt").write_text("# header\n0 0 0  0 1 0  0 -1 0  0.5 2\n")
    assert main(["chi2", "--samples", str(tmp_path / "m.txt"), "--against-emitter", str(POLY),
                 "-o", str(tmp_path / "r3")]) == 2
    err = capsys.readouterr().err
    assert "m.txt:2" in err and "measure" in err and "Traceback" not in err
    assert main(["chi2", "--samples", str(good), "--against-emitter", f"{POLY}:7", "-o", str(tmp_path / "r4")]) == 2
    assert "out of range" in capsys.readouterr().err
    assert not (tmp_path / "r3").exists() and not (tmp_path / "r4").exists()


def test_docstring_examples_run():
    import doctest

    assert doctest.testmod(ES).failed == 0


def test_a_correct_sampler_of_another_method_passes(tmp_path, poly):
    """Triangles chosen ∝ area² (not ∝ area) and points by a non-uniform warp within them, each with the exact
    pdf that goes with it: a correct light sampler that is not brdflab's passes (issue 29's rule:
    judge samples against their own pdf), in either measure."""
    em = poly.emitters[0]
    tri = emitter_triangles(em)
    area = em.geometry.tri_area[em.tris]
    rng = np.random.default_rng(17)
    p, _ = reference_points(poly, seed=17)
    n = 8000
    x = p[rng.integers(0, len(p), n)]
    q = area**2 / np.sum(area**2)
    k = rng.choice(len(tri), n, p=q)
    u1, u2 = rng.random(n), rng.random(n)
    # b₁ = 1 − u₁^(1/3) has density 3(1 − b₁)²; b₂ uniform on [0, 1 − b₁]: jointly 3(1 − b₁) over the reference
    # triangle (∫ = 1), and a world area element is 2 A_k db₁ db₂
    b1 = 1.0 - np.cbrt(u1)
    b2 = u2 * (1.0 - b1)
    dens_ref = 3.0 * (1.0 - b1)  # density over (b₁, b₂) ∈ reference triangle of area ½: ∫ 3(1 − b₁) = 1
    y = tri[k, 0] + b1[:, None] * (tri[k, 1] - tri[k, 0]) + b2[:, None] * (tri[k, 2] - tri[k, 0])
    nrm = np.cross(tri[k, 1] - tri[k, 0], tri[k, 2] - tri[k, 0])
    nrm /= np.linalg.norm(nrm, axis=1)[:, None]
    p_a = q[k] * dens_ref / (2.0 * area[k])  # dA_world = 2 A_k d(b₁, b₂)
    v = x - y
    r2 = np.sum(v * v, axis=1)
    cos = np.sum(nrm * v, axis=1) / np.sqrt(r2)
    for measure in (0, 1):
        pdf = np.where(cos > 0, p_a * r2 / np.abs(cos), 0.0) if measure else p_a
        res = _check(tmp_path, np.column_stack([x, y, nrm, pdf, np.full(n, measure)]), poly, 0)
        assert res.passed, res.messages()
        assert any("different sampling method than brdflab's" in c.summary for c in res.checks)
    # and the same sampler claiming brdflab's pdf (uniform by area) is rejected by its own points
    wrong = np.column_stack([x, y, nrm, np.full(n, 1.0 / area.sum()), np.zeros(n)])
    assert "self-consistency" in _failed(_check(tmp_path, wrong, poly, 0))
