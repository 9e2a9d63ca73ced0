"""Environment emitter: course lookup conventions, importance sampling vs pdf, and 2-D distributions."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from brdflab.emitter.environment import EnvironmentEmitter
from brdflab.errors import BrdflabError
from brdflab.imageio import read_exr, write_exr
from brdflab.judges.material import chi2 as c2
from brdflab.math.distribution import Distribution1D, Distribution2D
from tests.conftest import SHARED


def test_distribution1d_frequencies_and_zero_cells():
    w = np.array([0.0, 1.0, 3.0, 0.0, 6.0])
    d = Distribution1D(w)
    idx, x, p = d.sample(np.random.default_rng(0).random(200_000))
    counts = np.bincount(idx, minlength=5)
    assert counts[0] == 0 and counts[3] == 0
    assert stats.chisquare(counts[[1, 2, 4]], 200_000 * w[[1, 2, 4]] / 10).pvalue > 0.01
    assert np.all((x >= idx) & (x < idx + 1))
    np.testing.assert_allclose(p, w[idx] / 10)


def test_distribution2d_matches_its_pdf():
    rng = np.random.default_rng(1)
    w = rng.random((6, 9)) ** 3
    w[2] = 0.0  # an empty row
    d = Distribution2D(w)
    pts, p = d.sample(rng.random((300_000, 2)))
    np.testing.assert_allclose(p, d.pdf(pts))
    counts, _, _ = np.histogram2d(pts[:, 1], pts[:, 0], bins=[np.arange(7), np.arange(10)])
    assert counts[2].sum() == 0
    exp = 300_000 * w / w.sum()
    ok = exp > 0
    assert stats.chisquare(counts[ok], exp[ok]).pvalue > 0.01
    assert d.density.sum() == pytest.approx(1.0)


def test_distribution_all_zero_is_uniform():
    d = Distribution2D(np.zeros((3, 4)))
    np.testing.assert_allclose(d.density, 1 / 12)


def _dirs(*vs):
    v = np.array(vs, dtype=float)
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _map_with_marks(w=64, h=32):
    img = np.full((h, w, 3), 1.0, np.float32)
    img[:, 0] = [255, 0, 0]          # column 0  ← +X
    img[:, w // 2] = [0, 255, 0]     # column W/2 ← −X
    img[:, 3 * w // 4] = [0, 0, 255]  # column 3W/4 ← +Z
    img[:, w // 4] = [255, 255, 0]   # column W/4 ← −Z
    return img


def test_lookup_orientation():
    img = _map_with_marks()
    env = EnvironmentEmitter(img, np.array([2.0, 2.0, 2.0]))
    horizon = _dirs([1, 0, 0], [-1, 0, 0], [0, 0, 1], [0, 0, -1])
    L = env.eval(horizon)
    # /255 and the radiance multiplier; texel (c, r) sits at the integer point (c, r).
    np.testing.assert_allclose(L[0], [2, 0, 0], atol=1e-9)
    np.testing.assert_allclose(L[1], [0, 2, 0], atol=1e-9)
    np.testing.assert_allclose(L[2], [0, 0, 2], atol=1e-9)
    np.testing.assert_allclose(L[3], [2, 2, 0], atol=1e-9)


def test_up_reads_the_bottom_rows():
    """θ = 1.5π/H (near +Y) gives y = H − 1.5: the two bottom rows; θ = π − 0.5π/H gives y = 0.5: the top rows."""
    h = 16
    img = np.zeros((h, 32, 3), np.float32)
    img[-2:] = 255.0  # two bottom rows bright
    img[:2] = 51.0  # two top rows dimmer
    env = EnvironmentEmitter(img, np.ones(3))
    t = 1.5 * np.pi / h
    up = env.eval(_dirs([np.sin(t), np.cos(t), 0]))
    t2 = 0.5 * np.pi / h  # y = 0.5: rows 0 and 1
    down = env.eval(_dirs([np.sin(t2), -np.cos(t2), 0]))
    np.testing.assert_allclose(up[0], 1.0, atol=1e-9)
    np.testing.assert_allclose(down[0], 0.2, atol=1e-9)


def test_missing_map_is_an_error_and_constant_without_filename(tmp_path):
    from brdflab.scene.loader import load_scene
    from tests.conftest import CAMERA, write_scene

    p = write_scene(tmp_path, '<integrator type="direct_ems"/>' + CAMERA
                    + '<emitter type="environment"><string name="filename" value="nope.exr"/></emitter>')
    with pytest.raises(BrdflabError, match="environment map 'nope.exr' not found"):
        load_scene(p)
    env = EnvironmentEmitter(None, np.array([0.5, 1.0, 2.0]))
    np.testing.assert_allclose(env.eval(_dirs([0, 1, 0], [1, 0, 0])), [[0.5, 1, 2]] * 2)
    assert env.pdf(_dirs([0, 1, 0]))[0] == pytest.approx(1 / (4 * np.pi))


def _chi2_env(env, pdf=None, n=200_000, seed=0, group=1):
    """Chi-square with sphere bins aligned to the map's cells (groups of ``group``² cells).

    The correct density times sin θ is constant on each cell, so Gauss–Legendre gives exact expected
    counts; a density with the wrong Jacobian is not constant there and is caught.
    """
    pdf = pdf or env.pdf
    r = env.sample(np.zeros((n, 3)), np.random.default_rng(seed).random((n, 3)))
    x, y, _ = env._to_xy(r.wi[r.pdf > 0])
    h, w = env.h, env.w
    col = np.clip(np.floor(x).astype(int), 0, w - 1) // group
    row = np.clip(np.floor(y).astype(int), 0, h - 1) // group
    nb_r, nb_c = -(-h // group), -(-w // group)
    obs = np.bincount(row * nb_c + col, minlength=nb_r * nb_c).astype(float)
    # Cell (r, c) ↔ θ ∈ [π(1 − (r+1)/H), π(1 − r/H)], φ ∈ [2π(1 − (c+1)/W), 2π(1 − c/W)].
    gx, gw = np.polynomial.legendre.leggauss(3)
    rr, cc = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
    t0, t1 = np.pi * (1 - (rr + 1) / h), np.pi * (1 - rr / h)
    p0, p1 = 2 * np.pi * (1 - (cc + 1) / w), 2 * np.pi * (1 - cc / w)
    exp_cells = np.zeros((h, w))
    for i in range(3):
        for j in range(3):
            th = 0.5 * (t1 - t0) * gx[i] + 0.5 * (t0 + t1)
            ph = 0.5 * (p1 - p0) * gx[j] + 0.5 * (p0 + p1)
            d = np.stack([np.sin(th) * np.cos(ph), np.cos(th), np.sin(th) * np.sin(ph)], -1).reshape(-1, 3)
            exp_cells += gw[i] * gw[j] * (pdf(d) * np.sin(th).ravel()).reshape(h, w)
    exp_cells *= 0.25 * (t1 - t0) * (p1 - p0) * n
    expected = np.bincount(((rr // group) * nb_c + cc // group).ravel(), exp_cells.ravel(), minlength=nb_r * nb_c)
    stat, dof, pval = c2.pearson(obs, expected)
    return c2.Chi2Result("env", {}, stat, dof, pval, integral=float(expected.sum() / n))


def _synthetic_map(seed=0, w=48, h=24):
    rng = np.random.default_rng(seed)
    img = (rng.random((h, w, 3)) ** 4 * 255).astype(np.float32)
    img[h // 3, w // 5] = [5e4, 4e4, 3e4]  # a small sun
    img[:2] = 0.0  # dark rows
    return img


def test_sampling_matches_pdf():
    env = EnvironmentEmitter(_synthetic_map(), np.ones(3))
    r = _chi2_env(env)
    assert r.passed, r.p_value
    assert r.integral == pytest.approx(1.0, abs=2e-3)


def test_pdf_without_sin_jacobian_is_rejected():
    env = EnvironmentEmitter(_synthetic_map(), np.ones(3))

    def wrong(d):
        st = np.sqrt(np.maximum(0, 1 - d[:, 1] ** 2))
        return env.pdf(d) * st * (np.pi / 2)

    assert not _chi2_env(env, wrong).passed


def test_estimator_is_unbiased():
    """E[L/p] over importance samples equals ∫ L dω by quadrature over a fine (θ, φ) grid."""
    env = EnvironmentEmitter(_synthetic_map(3), np.ones(3))
    r = env.sample(np.zeros((400_000, 3)), np.random.default_rng(2).random((400_000, 3)))
    est = r.radiance[:, 1] / r.pdf
    th = (np.arange(1200) + 0.5) / 1200 * np.pi
    ph = (np.arange(2400) + 0.5) / 2400 * 2 * np.pi
    T, P = np.meshgrid(th, ph, indexing="ij")
    d = np.stack([np.sin(T) * np.cos(P), np.cos(T), np.sin(T) * np.sin(P)], -1).reshape(-1, 3)
    quad = (env.eval(d)[:, 1] * np.sin(T).ravel()).sum() * (np.pi / 1200) * (2 * np.pi / 2400)
    assert abs(est.mean() - quad) < 4 * est.std() / np.sqrt(len(est)) + 1e-4 * quad


def test_user_envmap_sampling():
    p = SHARED / "assignment-3/bunny_env/envmap.exr"
    if not p.exists():
        pytest.skip("user scenes not available")
    env = EnvironmentEmitter(read_exr(p), np.full(3, 200.0))
    r = _chi2_env(env, n=300_000, seed=4, group=8)
    assert r.passed, r.p_value


def test_half_float_exr_roundtrip(tmp_path):
    import OpenEXR

    img = _synthetic_map().astype(np.float16)
    OpenEXR.File({"compression": OpenEXR.PIZ_COMPRESSION, "type": OpenEXR.scanlineimage},
                 {"RGB": img}).write(str(tmp_path / "h.exr"))
    np.testing.assert_allclose(read_exr(tmp_path / "h.exr"), img.astype(np.float32))
    write_exr(tmp_path / "f.exr", img.astype(np.float32))


def _spec_lookup(img: np.ndarray, radiance: np.ndarray, w: np.ndarray) -> np.ndarray:
    """§9.3 transcribed, one direction at a time in plain Python: φ = atan2(z, x) wrapped to [0, 2π),
    θ = arccos y, x = (1 − φ/2π) W, y = (1 − θ/π) H, texel (c, r) at the integer point, indices wrapping
    modulo W and H, bilinear blend / 255 × radiance."""
    import math

    h, wd = img.shape[:2]
    out = []
    for dx, dy, dz in w:
        phi = math.atan2(dz, dx) % (2 * math.pi)
        theta = math.acos(max(-1.0, min(1.0, dy)))
        x, y = (1 - phi / (2 * math.pi)) * wd, (1 - theta / math.pi) * h
        ix, iy = math.floor(x), math.floor(y)
        fx, fy = x - ix, y - iy
        texel = [[img[(iy + b) % h, (ix + a) % wd].astype(np.float64) for a in (0, 1)] for b in (0, 1)]
        blend = ((1 - fx) * (1 - fy) * texel[0][0] + fx * (1 - fy) * texel[0][1] + (1 - fx) * fy * texel[1][0]
                 + fx * fy * texel[1][1])
        out.append(radiance * blend / 255)
    return np.array(out)


def test_lookup_is_the_spec_everywhere():
    """Bilinear lookup at random directions and near every seam (φ = 0 column wrap, the top and bottom rows,
    the poles) equals the spec's formula (a map with distinct texels, so a shifted index or clip shows)."""
    rng = np.random.default_rng(151)
    h, wd = 6, 10
    img = (rng.random((h, wd, 3)) * 255).astype(np.float32)
    radiance = np.array([1.5, 2.0, 0.5])
    env = EnvironmentEmitter(img, radiance)
    dirs = rng.normal(size=(300, 3))
    eps = 1e-3
    seams = [[1, 0, eps], [1, 0, -eps], [1, 0, 0], [np.sin(eps), np.cos(eps), 0], [np.sin(eps), -np.cos(eps), 0],
             [np.sin(0.6 / h * np.pi), np.cos(0.6 / h * np.pi), 0.1], [0.3, -np.cos(0.4 / h * np.pi), 0.2],
             [-1, 0.05, 0.01], [0.2, 0.99, -0.3]]
    dirs = np.concatenate([dirs, seams])
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    np.testing.assert_allclose(env.eval(dirs), _spec_lookup(img, radiance, dirs), rtol=1e-9, atol=1e-12)


def test_environment_map_memory_estimate(tmp_path, monkeypatch):
    """The map's memory (≈ 160 bytes per texel) is checked before it is read: a 64×32 map needs 320 KiB,
    refused under a 256 KiB limit with the file named; a 64×8 map (80 KiB) loads."""
    from brdflab.errors import SceneError
    from brdflab.imageio import write_exr
    from brdflab.scene.loader import load_scene
    from tests.conftest import CAMERA, write_scene

    monkeypatch.setenv("BRDFLAB_MEMORY_LIMIT_GB", str(256 / 2**20))
    for w, h, ok in ((64, 32, False), (64, 8, True)):
        write_exr(tmp_path / f"sky{h}.exr", np.ones((h, w, 3), np.float32))
        path = write_scene(tmp_path, f'<integrator type="direct_ems"/>{CAMERA}<emitter type="environment">'
                           f'<string name="filename" value="sky{h}.exr"/></emitter>', name=f"s{h}.xml")
        if ok:
            assert load_scene(path).environment is not None
        else:
            with pytest.raises(SceneError, match=r"s32\.xml:\d+.*64×32 environment map"):
                load_scene(path)


def test_rotate_is_ignored_and_bad_texels_are_zeroed(tmp_path):
    """§9.3: ``rotate`` is read by no code, so a scene's rotate does not turn the map; negative and
    non-finite texels are set to 0 with a warning (each kind on its own)."""
    from brdflab.imageio import write_exr
    from brdflab.scene.loader import load_scene
    from tests.conftest import CAMERA, write_scene

    rng = np.random.default_rng(4)
    img = (rng.random((6, 10, 3)) * 255).astype(np.float32)
    write_exr(tmp_path / "sky.exr", img)
    dirs = _dirs(*rng.normal(size=(50, 3)))
    evals = []
    for rot in ("", '<float name="rotate" value="90"/>'):
        path = write_scene(tmp_path, f'<integrator type="direct_ems"/>{CAMERA}<emitter type="environment">'
                           f'<string name="filename" value="sky.exr"/>{rot}</emitter>')
        evals.append(load_scene(path).environment.eval(dirs))
    np.testing.assert_array_equal(evals[0], evals[1])
    for bad in (-5.0, np.nan, np.inf):
        b = img.copy()
        b[2, 3] = bad
        with pytest.warns(UserWarning, match="negative or non-finite"):
            env = EnvironmentEmitter(b, np.ones(3))
        assert env.image[2, 3].tolist() == [0.0, 0.0, 0.0] and np.all(np.isfinite(env.image))


def test_sampling_density_follows_the_bilinear_luminance():
    """Importance sampling ∝ luminance (spec §9.3 leaves the choice open; brdflab's is documented): at the
    centre of every texel cell the pdf is proportional to the luminance of the bilinear lookup there (the
    mean of the cell's four corner texels, wrapping like the lookup), so a wrong neighbour shows."""
    rng = np.random.default_rng(12)
    h, w = 6, 8
    img = (rng.random((h, w, 3)) * 255 + 1).astype(np.float32)
    env = EnvironmentEmitter(img, np.array([2.0, 2.0, 2.0]))  # the weights are the map's own luminance
    x, y = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    d, _ = env._from_xy(x.ravel(), y.ravel())
    lum = env.eval(d) @ np.array([0.212671, 0.715160, 0.072169])
    ratio = env.pdf(d) / lum
    np.testing.assert_allclose(ratio, ratio[0], rtol=1e-9)
