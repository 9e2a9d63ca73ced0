"""The path tracers ``path``, ``path_nee``, ``path_mis`` against closed forms (spec §13.2.6–8).

(a) An integrating sphere: the inside of a closed diffuse sphere (radius R, albedo a). On an ideal sphere the
    form factor from any point to a patch is the patch's share of the total area, so the radiosity is uniform
    and solves B = a (E_direct + E_light + B) in closed form (Goral et al. 1984; the integrating-sphere
    equation):

    * a point light of intensity I at the centre: E_direct = I/R² everywhere, so L = a I / (π R² (1 − a)),
      the L_e/(1 − a) of the white furnace (path_nee, path_mis; BSDF sampling cannot find a point light);
    * an emitting polar cap of radiance L_e covering a fraction f of the area (the rest diffuse): L =
      a f L_e / (1 − a (1 − f)) (all three).

    Computed here from the mesh's own triangle areas, without brdflab. The tessellation (48 × 96) moves the
    answer by less than the 0.5 % tolerance (measured at 1.5 M samples per estimator: +0.17 % ± 0.03 % with the
    point light — the inscribed facets are nearer to it — and +0.1 % ± 0.04 % with the cap). With a = 0.8 the
    direct part is a fifth of the answer (furnace A) and paths run long, so Russian roulette is active on
    most of the estimate. ``maxDepth`` truncates the Neumann series at a known term.
(b) A convex diffuse sphere (albedo 0.5) in a constant environment of radiance 1 (``scenes/envlit``): every
    sphere pixel is exactly 0.5 for every estimator (a double-counted environment would give 1.0).
(c) Negative controls: roulette survivors not divided by the survival probability (the student bug of spec
    §13.2.7–8) must fail (a); the roulette itself is checked as an estimator of the throughput.

Each comparison is a t-test of the image mean over independent renders against the closed form, less the
tolerance; a check passes at p > 0.001 (false alarms: that rate per test, by construction of the t-test on
independent replicates).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

import brdflab as bl
from brdflab.integrator import wavefront
from brdflab.scene.shapes import uv_sphere, write_obj
from tests.conftest import ROOT

A, LE, INTENSITY = 0.8, 2.0, 3.0
TOL = 5e-3
CAMERA = """<camera type="perspective"><transform name="toWorld"><lookat origin="0,0,0" target="1,0,0" up="0,1,0"/>
</transform><float name="fov" value="40"/><integer name="width" value="16"/><integer name="height" value="12"/>
</camera>"""


@pytest.fixture(scope="module")
def spheres(tmp_path_factory):
    """(point-lit scene, cap-lit scene, cap fraction f) of the integrating sphere (module docstring)."""
    out = tmp_path_factory.mktemp("integrating_sphere")
    v, f, _, _ = uv_sphere((0.0, 0.0, 0.0), 1.0, 48, 96)
    f = f[:, ::-1]  # inward normals: the diffuse walls and the emitting cap face the centre
    centroid = v[f].mean(axis=1)
    cap = centroid[:, 1] > np.cos(np.radians(30.0))
    area = 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
    write_obj(out / "all.obj", v, f)
    write_obj(out / "walls.obj", v, f[~cap])
    write_obj(out / "cap.obj", v, f[cap])
    white = f'<bsdf type="diffuse"><color name="albedo" value="{A},{A},{A}"/></bsdf>'
    point = out / "point.xml"
    point.write_text(f'<scene><integrator type="path_nee"/>{CAMERA}<mesh type="obj"><string name="filename" '
                     f'value="all.obj"/>{white}</mesh><emitter type="pointlight"><point name="position" value="0,0,0"/>'
                     f'<color name="radiance" value="{INTENSITY},{INTENSITY},{INTENSITY}"/></emitter></scene>')
    capped = out / "cap.xml"
    capped.write_text(f'<scene><integrator type="path"/>{CAMERA}<mesh type="obj"><string name="filename" '
                      f'value="walls.obj"/>{white}</mesh><mesh type="obj"><string name="filename" value="cap.obj"/>'
                      f'<emitter type="area"><color name="radiance" value="{LE},{LE},{LE}"/></emitter></mesh></scene>')
    return point, capped, float(area[cap].sum() / area.sum())


def image_means(path, integrator: str, spp: int, reps: int, seed: int, **props) -> np.ndarray:
    """Mean pixel value of ``reps`` independent renders (distinct seeds)."""
    scene = bl.load_scene(path, integrator=integrator)
    for k, v in props.items():
        setattr(scene.integrator, k, v)
    return np.array([bl.render(scene, spp=spp, seed=seed + r, workers=1).astype(np.float64).mean()
                     for r in range(reps)])


def p_value(means: np.ndarray, expected: float, tol: float = TOL) -> float:
    """Two-sided t-test p-value of the replicate means against ``expected``, less a relative tolerance."""
    se = means.std(ddof=1) / np.sqrt(len(means))
    t = max(abs(means.mean() - expected) - tol * expected, 0.0) / se
    return float(2 * stats.t.sf(t, len(means) - 1))


@pytest.mark.parametrize("integrator", ["path_nee", "path_mis"])
def test_point_lit_integrating_sphere(spheres, integrator):
    """L = a I / (π R² (1 − a)) for a point light at the centre."""
    expected = A * INTENSITY / (np.pi * (1 - A))
    means = image_means(spheres[0], integrator, 128, 6, seed=11)
    assert p_value(means, expected) > 1e-3, (means.mean() / expected, means)


@pytest.mark.parametrize("integrator,rr_depth", [("path", 3), ("path_nee", 1), ("path_mis", 3)])
def test_cap_lit_integrating_sphere(spheres, integrator, rr_depth):
    """L = a f L_e / (1 − a (1 − f)) for an emitting cap (all three estimators; roulette from vertex 1 or 3)."""
    f = spheres[2]
    expected = A * f * LE / (1 - A * (1 - f))
    means = image_means(spheres[1], integrator, 128, 6, seed=23, rr_depth=rr_depth)
    assert p_value(means, expected) > 1e-3, (means.mean() / expected, means)


@pytest.mark.parametrize("max_depth,terms", [(1, 0), (2, 1), (3, 2)])
def test_max_depth_truncates_the_series(spheres, max_depth, terms):
    """maxDepth = D keeps the paths of ≤ D segments: L = (a I/π R²) Σ_{j<D−1} a^j (0 for D = 1: the camera sees
    no emitter)."""
    expected = A * INTENSITY / np.pi * sum(A**j for j in range(terms))
    means = image_means(spheres[0], "path_nee", 32, 4, seed=31, max_depth=max_depth)
    if terms == 0:
        assert np.all(means == 0.0)
    else:
        assert p_value(means, expected) > 1e-3, (means.mean() / expected, means)


def test_uncompensated_roulette_is_rejected(spheres, monkeypatch):
    """Negative control: survivors kept at their throughput (not divided by s) darken the sphere."""
    def biased(beta, xi):
        s = np.minimum(beta.max(axis=1), wavefront.MAX_SURVIVAL)
        keep = np.flatnonzero(xi < s)
        return keep, np.asfortranarray(beta[keep])

    monkeypatch.setattr(wavefront, "roulette", biased)
    f = spheres[2]
    expected = A * f * LE / (1 - A * (1 - f))
    means = image_means(spheres[1], "path_mis", 64, 4, seed=41)
    assert p_value(means, expected) < 1e-6, (means.mean() / expected, means)


def test_roulette_is_unbiased_for_the_throughput():
    """E[1{ξ < s} β/s] = β for throughputs above, at and below the 0.95 cap; the uncompensated version is
    rejected."""
    rng = np.random.default_rng(7)
    n = 200_000
    beta = np.asfortranarray(np.repeat([[0.02, 0.01, 0.03], [0.5, 0.2, 0.1], [3.0, 1.0, 0.5]], n, axis=0))
    keep, out = wavefront.roulette(beta, rng.random(len(beta)))
    est = np.zeros_like(beta)
    est[keep] = out
    for k in range(3):
        rows = slice(k * n, (k + 1) * n)
        mean, se = est[rows].mean(axis=0), est[rows].std(axis=0, ddof=1) / np.sqrt(n)
        z = np.abs(mean - beta[k * n]) / se
        assert np.all(2 * stats.norm.sf(z) > 1e-4), (k, mean, beta[k * n])
    # Without the division the mean is s·β: rejected for the paths that roulette can end (s < 1).
    low = slice(0, n)
    plain = np.zeros(n)
    plain[keep[keep < n]] = beta[keep[keep < n], 0]
    z = abs(plain.mean() - beta[0, 0]) / (plain.std(ddof=1) / np.sqrt(n))
    assert 2 * stats.norm.sf(z) < 1e-6, (plain.mean(), beta[low][0])


@pytest.mark.parametrize("integrator", ["path", "path_nee", "path_mis"])
def test_white_furnace_in_a_constant_environment(integrator):
    """A convex diffuse sphere (0.5) in a constant environment (1): the sphere's interior pixels are 0.5 whatever
    the estimator (the environment is an emitter for NEE and MIS: counted once, not twice)."""
    scene = bl.load_scene(ROOT / "scenes" / "envlit" / "envlit_furnace.xml", integrator=integrator, width=32,
                          height=32)
    x, y = np.meshgrid(np.arange(32) + 0.5, np.arange(32) + 0.5)
    on = scene.geometry.intersect(*scene.camera.generate_rays(x.ravel(), y.ravel())[:2]).valid.reshape(32, 32)
    interior = on.copy()
    for dy in range(-3, 4):  # the filter (radius 2) mixes edge pixels with the background
        for dx in range(-3, 4):
            interior &= np.roll(on, (dy, dx), axis=(0, 1))
    assert interior.sum() > 20
    means = np.array([bl.render(scene, spp=16, seed=s, workers=1).astype(np.float64)[interior].mean()
                      for s in range(4)])
    assert p_value(means, 0.5, tol=1e-3) > 1e-3, means


@pytest.mark.parametrize("integrator", ["path", "path_nee", "path_mis"])
def test_error_falls_like_one_over_spp(spheres, integrator):
    """The pixel variance on the walls of the cap-lit sphere (every pixel has the same expectation) falls 4× from
    16 to 64 spp: MSE ∝ 1/spp, the convergence of an unbiased estimator with finite variance. Measured ratios
    3.7–4.3 (3 trials each; the tessellation's small fixed pixel-to-pixel spread pulls it below 4); the bounds
    [3, 5.3] reject an error falling like 1/√spp (ratio 2) or 1/spp² (16)."""
    scene = bl.load_scene(spheres[1], integrator=integrator)
    var = {}
    for spp in (16, 64):
        px = [bl.render(scene, spp=spp, seed=100 * spp + r, workers=1).astype(np.float64).mean(axis=2).ravel()
              for r in range(4)]
        var[spp] = np.concatenate(px).var(ddof=1)
    assert 3.0 < var[16] / var[64] < 5.3, var
