"""The compiled engine (brdflab.kernels) against the NumPy specification, which it must reproduce to 1e-12.

Every kernel is run on random and extreme inputs (grazing and below-horizon directions, normal incidence,
α from 1e-3 to 1, total internal reflection, textures, material families with per-point constants, each
roughsubstrate lobe) through both engines; a deliberately perturbed kernel must fail the same comparison
(negative control). Whole render units (float64 tile films) of bundled scenes with every integrator and
light kind agree too, and the samplers pass their chi-square test through both engines.
"""

from __future__ import annotations

import os
import subprocess
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest

from brdflab import Diffuse, RoughConductor, RoughSubstrate, kernels
from brdflab.bsdf.family import BSDFFamily
from brdflab.film import Film, Filter
from brdflab.texture import CheckerTexture

ROOT = Path(__file__).resolve().parent.parent
RTOL = 1e-12
pytestmark = pytest.mark.skipif(not kernels._numba_available(), reason="numba is not installed")


def agree(a, b, rtol: float = RTOL) -> None:
    """Arrays (or tuples of arrays) equal to ``rtol`` relative; zeros, infs and NaNs in the same places."""
    a = a if isinstance(a, tuple) else (a,)
    b = b if isinstance(b, tuple) else (b,)
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
        assert x.shape == y.shape
        np.testing.assert_array_equal(x == 0, y == 0)
        np.testing.assert_allclose(x, y, rtol=rtol, atol=0, equal_nan=True)


def directions(rng: np.random.Generator, n: int) -> np.ndarray:
    """Random unit vectors with extremes mixed in: grazing (cos θ = ±1e-8, 1e-4), normal incidence, the
    horizon and exact opposites of the first rows."""
    v = rng.normal(size=(n, 3))
    k = n // 8
    v[:k, 2] = rng.choice([1e-8, -1e-8, 1e-4, 0.0], size=k) * np.hypot(v[:k, 0], v[:k, 1])
    v[k:k + 4] = [[0, 0, 1], [0, 0, -1], [1, 0, 0], [0, 1, 1e-12]]
    return v / np.linalg.norm(v, axis=1)[:, None]


def materials() -> dict[str, object]:
    chk = CheckerTexture(4, 3)
    fam_c = BSDFFamily([RoughConductor(R0=[0.9, 0.6, 0.2], alpha=0.02), RoughConductor(R0=0.3, alpha=0.4)])
    fam_g = BSDFFamily([RoughConductor(R0=0.9, alpha=0.02, distribution="ggx", alpha_v=0.3),
                        RoughConductor(R0=0.3, alpha=0.4, distribution="ggx", alpha_v=0.3)])
    fam_s = BSDFFamily([RoughSubstrate(kd=[0.7, 0.2, 0.1], alpha=0.05), RoughSubstrate(kd=0.2, alpha=0.6)])
    fam_d = BSDFFamily([Diffuse([0.8, 0.1, 0.1]), Diffuse(0.5)])
    return {
        "diffuse": Diffuse([0.7, 0.5, 0.2]),
        "diffuse/checker": Diffuse(chk),
        "diffuse/family": (fam_d, 2),
        "conductor/α=1e-3": RoughConductor(R0=[0.95, 0.64, 0.54], alpha=1e-3),
        "conductor/α=0.1": RoughConductor(alpha=0.1),
        "conductor/α=1": RoughConductor(R0=0.04, alpha=1.0),
        "conductor/textured": RoughConductor(R0=chk, alpha=chk),
        "conductor/family": (fam_c, 2),
        "conductor/ggx visible": RoughConductor(R0=[0.9, 0.6, 0.2], alpha=0.2, distribution="ggx"),
        "conductor/ggx α=1e-3": RoughConductor(alpha=1e-3, distribution="ggx"),
        "conductor/ggx anisotropic η,k": RoughConductor(distribution="ggx", alpha_u=0.05, alpha_v=0.6,
                                                       eta=[0.2, 0.92, 1.1], k=[3.9, 2.45, 2.14]),
        "conductor/ggx D cos": RoughConductor(alpha=chk, distribution="ggx", sample_visible=False, material="Au"),
        "conductor/beckmann anisotropic": RoughConductor(R0=chk, alpha=0.3, alpha_v=0.02),
        "conductor/beckmann η,k": RoughConductor(alpha=0.3, material="Cu"),
        "conductor/beckmann visible": RoughConductor(R0=[0.9, 0.6, 0.2], alpha=0.2, sample_visible=True),
        "conductor/beckmann visible α=1e-3": RoughConductor(alpha=1e-3, sample_visible=True),
        "conductor/beckmann visible anisotropic η,k": RoughConductor(alpha_u=0.05, alpha_v=0.8, sample_visible=True,
                                                                    material="Au"),
        "conductor/ggx family": (fam_g, 2),
        "substrate/α=1e-3": RoughSubstrate(kd=[0.6, 0.3, 0.2], alpha=1e-3),
        "substrate/α=0.3": RoughSubstrate(alpha=0.3, intIOR=1.33),
        "substrate/TIR": RoughSubstrate(alpha=0.2, intIOR=1.0, extIOR=1.6),
        "substrate/equal-IOR": RoughSubstrate(alpha=0.2, intIOR=1.5, extIOR=1.5),
        "substrate/specular": RoughSubstrate(alpha=0.1, lobe="specular"),
        "substrate/diffuse": RoughSubstrate(alpha=0.1, lobe="diffuse"),
        "substrate/textured": RoughSubstrate(kd=chk, alpha=chk),
        "substrate/family": (fam_s, 2),
    }


MATERIALS = materials()


def bound(name: str, n: int, rng: np.random.Generator):
    m = MATERIALS[name]
    if isinstance(m, tuple):  # a family: each point with a random member's constants
        fam, k = m
        return fam.bind(rng.integers(0, k, n))
    return m


@pytest.mark.parametrize("name", list(MATERIALS))
def test_bsdf_kernels_match_numpy(name):
    rng = np.random.default_rng(zlib.crc32(name.encode()))  # str hash() differs per process
    n = 4000
    m = bound(name, n, rng)
    assert kernels.for_object(m, "bsdf") is not None
    wi, wo = directions(rng, n), directions(rng, n)
    wi[n // 2:, 2] = np.abs(wi[n // 2:, 2])  # half the queries from above
    u = rng.random((n, 3))
    u[:8, 0] = [0.0, 1.0, 1 - 1e-16, 1e-300, 0.5, 0.999999, 0.0, 1.0]
    uv = rng.random((n, 2)) * 3 - 1
    for method, arg in (("eval", wo), ("pdf", wo), ("eval_pdf", wo), ("sample", u)):
        with kernels.use_engine("numpy"):
            ref = getattr(m, method)(wi, arg, uv)
        with kernels.use_engine("numba"):
            got = getattr(m, method)(wi, arg, uv)
        agree(tuple(got) if method == "sample" else got, tuple(ref) if method == "sample" else ref)


def test_sampled_directions_exercise_both_lobes_and_failures():
    """The sample comparison above is not vacuous: specular and diffuse picks, failed samples (weight 0)
    and live ones all occur."""
    rng = np.random.default_rng(5)
    m = RoughSubstrate(alpha=0.1, intIOR=1.5)
    wi = directions(rng, 4000)
    wi[:, 2] = np.abs(wi[:, 2])
    s = m.sample(wi, rng.random((4000, 3)))
    ok = s.weight[:, 0] > 0
    assert 100 < ok.sum() < 4000 and (s.pdf > 50).sum() > 20


def test_negative_control_perturbed_kernel_fails(monkeypatch):
    """A kernel off by one part in 1e10 is caught by the comparison of the test above."""
    mod = kernels.load("bsdf")
    real = mod.eval_bsdf
    monkeypatch.setattr(mod, "eval_bsdf", lambda *a, **k: real(*a, **k) * (1 + 1e-10))
    rng = np.random.default_rng(3)
    m = RoughConductor(alpha=0.2)
    wi, wo = directions(rng, 500), directions(rng, 500)
    wi[:, 2] = np.abs(wi[:, 2])
    with kernels.use_engine("numpy"):
        ref = m.eval(wi, wo)
    with pytest.raises(AssertionError):
        agree(m.eval(wi, wo), ref)


def test_subclasses_and_plugins_take_the_numpy_path():
    """A user's subclass of a built-in does not inherit its kernel: its own overrides are what runs."""

    class Brighter(RoughConductor):
        def eval(self, wi, wo, uv=None):
            return 2.0 * super().eval(wi, wo, uv)

    assert kernels.for_object(Brighter(), "bsdf") is None
    assert kernels.for_object(RoughConductor(), "bsdf") is not None
    with kernels.use_engine("numpy"):
        assert kernels.for_object(RoughConductor(), "bsdf") is None
    wi = np.array([[0.0, 0.0, 1.0]])
    np.testing.assert_array_equal(Brighter(alpha=0.3).eval(wi, wi), 2.0 * RoughConductor(alpha=0.3).eval(wi, wi))


@pytest.mark.parametrize("filt", [Filter("gaussian"), Filter("tent"), Filter("box"), Filter("mitchell", 2.0),
                                  Filter("gaussian", radius=4 / 3, stddev=0.4), Filter("gaussian", radius=1.5)],
                         ids=lambda f: f"{f.kind}{f.radius:.3g}")
def test_splat_kernel_matches_numpy(filt):
    """Power-of-two phase counts, 24 phases (radius 4/3) and an untabulated radius (NumPy on both)."""
    rng = np.random.default_rng(11)
    for n in (50, 20000):  # the NumPy code's direct and separable passes
        sx = rng.random(n) * 40 + 3
        sy = rng.random(n) * 30 + 5
        sx[:4] = [3.0, 43.0, 3.5, 42.999999]
        vals = rng.random((n, 3)) * rng.choice([1e-3, 1.0, 1e3], size=(n, 1))
        films = []
        for eng in ("numpy", "numba"):
            film = Film(64, 48, filt, x0=3, y0=5, w=40, h=30)
            film.data += 0.25  # a film that already holds samples
            with kernels.use_engine(eng):
                film.splat(sx, sy, vals)
            films.append(film.data)
        agree(films[1], films[0])
        if not filt.phases:
            continue
        kf = kernels.load("film")
        if filt.kind == "gaussian" and filt.radius == 2.0:  # 16 phases, 4 taps: separable from 4 samples a pixel
            assert kf.separable(n, Film(64, 48, filt, x0=3, y0=5, w=40, h=30)) == (n == 20000)
        for rows in (False, True):  # both compiled passes, whichever the cost model picks
            film = Film(64, 48, filt, x0=3, y0=5, w=40, h=30)
            film.data += 0.25
            kf.splat_film(film, sx, sy, vals, rows=rows)
            agree(film.data, films[0])


def _unit_films(scene_path: str, **kw) -> list[np.ndarray]:
    from brdflab.api import load_scene
    from brdflab.workers import _render_unit

    scene = load_scene(ROOT / scene_path, width=48, height=36, **kw)
    out = []
    for eng in ("numpy", "numba"):
        with kernels.use_engine(eng):
            film, n, dropped = _render_unit(scene, 0, 0, (8, 6, 24, 20), 4, 1234)
        out.append(film.data.copy())
    return out


@pytest.mark.parametrize("scene,integrator", [
    ("scenes/cbox/cbox_substrate.xml", "direct_mis"),
    ("scenes/cbox/cbox_spheres.xml", "direct_ems"),
    ("scenes/veach/veach_mats.xml", "direct_mats"),
    ("scenes/envlit/envlit_mis.xml", "direct_mis"),
    ("scenes/checker/checker_point.xml", "direct_ems"),
    ("scenes/lights/mixed_lights_mis.xml", "direct_mis"),
])
def test_render_units_agree_between_engines(scene, integrator):
    numpy_film, numba_film = _unit_films(scene, integrator=integrator)
    assert numpy_film[3].sum() > 0 and np.abs(numpy_film[:3]).sum() > 0
    agree(numba_film, numpy_film)


@pytest.mark.parametrize("engine", kernels.ENGINES)
@pytest.mark.parametrize("bsdf", ["roughconductor", "roughsubstrate", "diffuse"])
def test_samplers_pass_chi_square_through_both_engines(engine, bsdf):
    from brdflab.judges.material.chi2 import bsdf_test

    m = {"roughconductor": RoughConductor(alpha=0.2), "roughsubstrate": RoughSubstrate(alpha=0.2),
         "diffuse": Diffuse(0.5)}[bsdf]
    with kernels.use_engine(engine):
        r = bsdf_test(bsdf, m, 40.0, 60000, seed=7)
    assert r.passed, r


@pytest.mark.parametrize("engine", kernels.ENGINES)
def test_white_furnace_passes_through_both_engines(engine):
    """Quadrature and Monte Carlo albedo agree (and stay ≤ 1) through either engine; both engines' albedos
    agree with each other to 1e-12 (same quadrature nodes and samples)."""
    from brdflab.judges.material.furnace import furnace_test

    m = RoughSubstrate(kd=0.8, alpha=0.3)
    with kernels.use_engine(engine):
        r = furnace_test(m, thetas=(0.0, 70.0), samples=20000, seed=4)
    with kernels.use_engine("numpy" if engine == "numba" else "numba"):
        other = furnace_test(m, thetas=(0.0, 70.0), samples=20000, seed=4)
    assert r.passed, r
    agree(np.array([(p.quadrature, p.monte_carlo) for p in r]), np.array([(p.quadrature, p.monte_carlo)
                                                                          for p in other]))


def test_second_process_loads_the_kernels_from_the_disk_cache():
    """cache=True: after one process has compiled the kernels, the next one compiles nothing."""
    code = ("import numpy as np; from brdflab import kernels, RoughSubstrate; from brdflab.film import Film, Filter; "
            "w = np.tile([0.0, 0.6, 0.8], (4, 1)); RoughSubstrate().sample(w, np.full((4, 3), 0.3)); "
            "Film(8, 8, Filter()).splat(np.full(2, 3.0), np.full(2, 3.0), np.ones((2, 3))); "
            "print(kernels.costs()['compile'])")
    env = {**os.environ, "BRDFLAB_AOT": "0", "BRDFLAB_ENGINE": "numba"}  # the JIT and its disk cache
    runs = []
    for _ in range(2):  # the session's kernel build compiled through the JIT and left its cache: usually one run
        runs.append(subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, env=env))
        if runs[-1].returncode != 0 or float(runs[-1].stdout) == 0.0:
            break
    assert all(r.returncode == 0 for r in runs), runs[-1].stderr
    assert float(runs[-1].stdout) == 0.0, [r.stdout for r in runs]


def test_engine_switch_on_the_command_line(tmp_path):
    env = dict(os.environ, BRDFLAB_ENGINE="fortran")
    p = subprocess.run([sys.executable, "-m", "brdflab.cli.main", "render", "scenes/cbox/cbox_diffuse.xml"],
                       cwd=ROOT, env=env, capture_output=True, text=True)
    assert p.returncode == 2 and "BRDFLAB_ENGINE must be one of numba, numpy" in p.stderr
    assert "Traceback" not in p.stderr and not list(tmp_path.iterdir())
    code = "import os, sys; from brdflab.cli.main import main; from brdflab import kernels; " \
           "main(['--engine', 'numpy', 'render', '--help']) if False else None; " \
           "import argparse; from brdflab.cli.main import build_parser; " \
           "a = build_parser().parse_args(['render', '--engine', 'numpy', 'x.xml']); print(a.engine)"
    p = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert p.stdout.strip() == "numpy", p.stderr


def test_missing_numba_falls_back_by_default_and_is_an_error_when_asked_for(tmp_path):
    """Without numba and without a prebuilt module: the NumPy engine, quietly (no build is started), and a
    usage error when the compiled engine is asked for by name; with a prebuilt module, no numba is needed."""
    code = ("import sys; from brdflab import kernels; kernels._numba_ok = False\n"
            "print(kernels.engine(), kernels.for_object(kernels, 'bsdf'))\n"
            "kernels.set_engine('numba')\n"
            "try:\n    kernels.engine()\nexcept kernels.BrdflabError as e:\n    print(e)\n")
    env = {**os.environ, "BRDFLAB_KERNEL_CACHE": str(tmp_path)}
    env.pop("BRDFLAB_ENGINE", None)
    p = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True)
    assert p.stdout.splitlines()[0] == "numpy None" and p.stderr == "", p.stderr
    assert "needs the numba package" in p.stdout.splitlines()[1]
    assert list(tmp_path.iterdir()) == []
    env.pop("BRDFLAB_KERNEL_CACHE")
    if "BRDFLAB_KERNEL_CACHE" in os.environ:  # the session's own cache (a mutation run sets one)
        env["BRDFLAB_KERNEL_CACHE"] = os.environ["BRDFLAB_KERNEL_CACHE"]
    p = subprocess.run([sys.executable, "-c", code.split("kernels.set_engine")[0] + "print(kernels.backend())"],
                       cwd=ROOT, env=env, capture_output=True, text=True)
    if kernels.backend() == "aot":  # the session's build
        assert p.stdout.split()[0] == "numba" and p.stdout.split()[-1] == "aot", p.stdout + p.stderr


def test_cluster_tasks_compute_with_the_clients_engine(monkeypatch):
    from brdflab import cluster_tasks

    seen = []
    monkeypatch.setattr(cluster_tasks, "_render_batch", lambda *a: seen.append(kernels.engine()))
    cluster_tasks._render_task(None, None, [], 0, "numpy")
    cluster_tasks._render_task(None, None, [], 0, "numba")
    assert seen == ["numpy", "numba"]


def test_numba_is_not_imported_at_start_up():
    code = "import sys, brdflab, brdflab.cli.main; from brdflab.api import load_scene; " \
           "load_scene('scenes/cbox/cbox_diffuse.xml'); print('numba' in sys.modules)"
    p = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert p.stdout.strip() == "False", p.stderr


@pytest.mark.parametrize("scene", ["scenes/cbox/cbox_spheres.xml", "scenes/checker/checker_point.xml",
                                   "scenes/veach/veach_mis.xml", "scenes/envlit/envlit_mis.xml",
                                   "scenes/lights/mixed_lights_mis.xml"])
def test_shading_points_kernel_is_bit_identical(scene):
    """Hit records, frames and ω_i of camera hits (smooth spheres, a checker texture's uvs, families)."""
    from brdflab.api import load_scene
    from brdflab.integrator.common import trace_camera

    sc = load_scene(ROOT / scene, width=80, height=60)
    rng = np.random.default_rng(2)
    o, d, tmax = sc.camera.generate_rays(rng.random(20000) * 80, rng.random(20000) * 60)
    out = {}
    for eng in kernels.ENGINES:
        with kernels.use_engine(eng):
            out[eng] = trace_camera(sc, o, d, tmax)
    (L0, a), (L1, b) = out["numpy"], out["numba"]
    assert len(a.p) > 1000
    np.testing.assert_array_equal(L0, L1)
    for name in ("index", "p", "ng", "ns", "uv", "wi", "member"):
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None), name
        if x is not None:
            np.testing.assert_array_equal(x, y, err_msg=name)
    np.testing.assert_array_equal(a.frames.sign, b.frames.sign)
    np.testing.assert_array_equal(a.frames.a, b.frames.a)
    assert a.groups == b.groups


LIGHT_SCENES = ["scenes/cbox/cbox_spheres.xml", "scenes/veach/veach_mis.xml", "scenes/lights/mixed_lights_mis.xml",
                "scenes/lights/polygon_lights_mis.xml", "scenes/lights/sphere_light_mis.xml"]


@pytest.mark.parametrize("scene", LIGHT_SCENES)
def test_area_light_sampling_kernel_is_bit_identical(scene):
    """Every area light of the scene on its own (parallelograms, triangle lists, smooth sphere lights) and the
    fused light set, from points all around (behind the lights too)."""
    from brdflab.api import load_scene
    from brdflab.emitter.area import AreaEmitter, AreaLightSet

    sc = load_scene(ROOT / scene)
    rng = np.random.default_rng(8)
    lo, hi = sc.geometry.positions.min(axis=0), sc.geometry.positions.max(axis=0)
    ref = lo + rng.random((5000, 3)) * (hi - lo)
    u = rng.random((5000, 3))
    u[:4] = [[0, 0, 0], [1 - 1e-16, 1 - 1e-16, 0.5], [0.5, 0.5, 0.999], [0.3, 0.7, 0.0]]
    lights = [e for e in sc.emitters if isinstance(e, AreaEmitter)]
    assert lights
    if AreaLightSet.applies(sc.emitters) and len(sc.emitters) > 1:
        lights.append(AreaLightSet(sc.emitters, sc.emitter_pmf))
    for em in lights:
        _light_samples_agree(em, ref, u, 100)


def _light_samples_agree(em, ref, u, at_least: int) -> None:
    """The emitter's samples from ``ref`` are the same bits on both engines (at least ``at_least`` valid)."""
    assert kernels.for_object(em, "emitter") is not None
    with kernels.use_engine("numpy"):
        a = em.sample(ref, u)
    b = em.sample(ref, u)
    assert (a.pdf > 0).sum() > at_least
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)


@pytest.mark.parametrize("scene", ["scenes/cbox/cbox_spheres.xml", "scenes/checker/checker_point.xml",
                                   "scenes/veach/veach_mis.xml", "scenes/envlit/envlit_mis.xml",
                                   "scenes/lights/mixed_lights_mis.xml", "scenes/lights/polygon_lights_mis.xml"])
def test_direct_integrator_kernels_are_bit_identical(scene, monkeypatch):
    """The light term's contributions and shadow rays (with and without MIS weights) and the BSDF rays of
    ``direct_mats`` with the emission they find (:mod:`brdflab.kernels.direct`), given the same light and BSDF
    samples: every light kind, occluders, the environment's infinite distance, delta lights, points below the
    horizon, fused light sets (Veach's smooth spheres, polygons) hit on either side."""
    import brdflab.integrator.common as common
    import brdflab.integrator.direct_mats as mats
    import brdflab.scene.geometry as geometry
    from brdflab.api import load_scene
    from brdflab.integrator.direct_mis import mis_weight

    def numpy_only(fn):
        def run(*a, **k):
            with kernels.use_engine("numpy"):
                return fn(*a, **k)
        return run

    for mod, name in ((common, "eval_bsdfs"), (common, "sample_lights"), (mats, "sample_bsdfs")):
        monkeypatch.setattr(mod, name, numpy_only(getattr(mod, name)))
    sc = load_scene(ROOT / scene, width=80, height=60)
    rng = np.random.default_rng(5)
    o, d, tmax = sc.camera.generate_rays(rng.random(20000) * 80, rng.random(20000) * 60)
    with kernels.use_engine("numpy"):
        _, sp = common.trace_camera(sc, o, d, tmax)
    k = common.light_dims(sc)
    u = common.point_uniforms(rng, len(o), sp, k + 3)
    out = {}
    for eng in kernels.ENGINES:
        with kernels.use_engine(eng), np.errstate(all="ignore"):
            lit = common.light_term(sc, sp, u[:, :k])
            weighted = common.light_term(sc, sp, u[:, :k],
                                         lambda ls, pb: np.where(ls.delta, 1.0, mis_weight(ls.pdf, pb, 1.0)))
            out[eng] = (lit, weighted, *mats.bsdf_rays(sc, sp, u[:, k:]))
    a, b = out["numpy"], out["numba"]
    assert kernels.load("direct").T_INF == geometry.T_INF
    assert (a[0] > 0).any(axis=1).sum() > 1000 and len(a[2]) > 1000
    if common.scene_tables(sc).has_emitter_meshes:  # BSDF rays can find area lights (not the point light)
        assert (a[5] > 0).any(axis=1).sum() > 100
    for x, y in zip(a, b, strict=True):
        assert x.dtype == y.dtype
        np.testing.assert_array_equal(x, y)


@pytest.mark.parametrize("to_world", ["none", "axis", "lookat"])
def test_camera_rays_kernel_is_bit_identical(to_world):
    """Camera.unit_rays through both engines gives the same bits: positions, float32 origins, directions,
    tmax; for a camera without transform, an axis-aligned one (zero matrix entries skipped) and a general
    look-at; a changed rounding (one more ulp in c_x) must show (negative control)."""
    from brdflab.film import Camera
    from brdflab.math.transform import Transform, lookat, translate

    xf = {"none": None, "axis": Transform(translate(np.array([0.5, -2.0, 3.0]))),
          "lookat": Transform(lookat(np.array([1.0, 2.0, 3.0]), np.array([0.2, -0.1, 0.4]),
                                     np.array([0.1, 1.0, 0.3])))}[to_world]
    cam = Camera(96, 72, 37.5, 1e-3, 250.0, xf)
    assert kernels.for_object(cam, "film") is not None
    rng = np.random.default_rng(11)
    n = 5000
    jitter = rng.random((2, n))
    jitter[:, :4] = [[0.0, 1 - 2**-53, 0.5, 0.0], [0.0, 0.0, 1 - 2**-53, 0.25]]
    px, py = rng.integers(0, 32, n).astype(np.float64), rng.integers(0, 32, n).astype(np.float64)
    with kernels.use_engine("numpy"):
        ref = cam.unit_rays(jitter.copy(), px, py, 64, 40)
    with kernels.use_engine("numba"):
        got = cam.unit_rays(jitter.copy(), px, py, 64, 40)
    for a, b in zip(got, ref, strict=True):
        assert a.dtype == b.dtype and a.shape == b.shape
        np.testing.assert_array_equal(a, b)
    assert got[2].flags.c_contiguous and got[3].strides[0] == 8  # contiguous columns (kernels.buffers.columns)
    # Negative control: the kernel given a c_x one ulp off differs from the specification.
    from brdflab.kernels import film as kfilm

    coef = np.array([*cam.ray_coefficients(), cam.near, cam.far - cam.near])
    coef[0] = np.nextafter(coef[0], 0)
    out = [np.empty(n), np.empty(n), np.empty((n, 3), np.float32), np.empty((n, 3), order="F"), np.empty(n)]
    xfm = xf if xf is not None else Transform()
    kfilm.camera_rays(jitter.copy(), px, py, 64.0, 40.0, coef, xfm.matrix, xfm.origin(), *out)
    assert not np.array_equal(out[3], ref[3])


@pytest.mark.parametrize("negate", [False, True])
def test_frame_to_local_kernel_is_bit_identical(negate):
    """NormalFrames.to_local through both engines gives the same bits, at the frame's poles (n = ±z and
    n_z → −1, where a = −1/(σ + n_z) is huge) and on random frames; a changed rounding must show."""
    from brdflab.kernels import shading as kshading
    from brdflab.math.frame import NormalFrames

    rng = np.random.default_rng(31)
    n = rng.normal(size=(4000, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    n[:4] = [[0, 0, 1], [0, 0, -1], [1e-9, 0, -np.sqrt(1 - 1e-18)], [0, 1, 0]]
    v = np.asfortranarray(rng.normal(size=(4000, 3)))
    frames = NormalFrames(n)
    with kernels.use_engine("numpy"):
        ref = frames.to_local(v, negate)
    with kernels.use_engine("numba"):
        got = frames.to_local(v, negate)
    np.testing.assert_array_equal(got, ref)
    assert got.flags.f_contiguous and np.isfinite(ref).all()
    out = np.empty_like(ref)  # negative control: a one ulp larger a changes the result
    kshading.frame_to_local(frames.n, frames.sign, np.nextafter(frames.a, np.inf), v, negate,
                            *kshading.tangent_args(frames), False, out)
    assert not np.array_equal(out, ref)


def test_tilted_parallelogram_light_kernel_is_bit_identical(tmp_path):
    """The bundled parallelogram lights are all axis-aligned, so a kernel that mixed up the edges' components
    sampled them right (a mutant survived the scenes above): a light tilted about two axes, both engines."""
    from brdflab.api import load_scene
    from brdflab.emitter.area import AreaEmitter
    from tests.conftest import CAMERA, QUAD_OBJ, write_scene

    body = (CAMERA + '<integrator type="direct_ems"/><mesh type="obj"><string name="filename" value="quad.obj"/>'
            '<transform name="toWorld"><scale value="0.7,1,0.3"/><rotate axis="1,0,0" angle="35"/>'
            '<rotate axis="0,0,1" angle="-50"/><translate value="0.2,1.1,-0.3"/></transform>'
            '<emitter type="area"><color name="radiance" value="3,2,1"/></emitter></mesh>')
    sc = load_scene(write_scene(tmp_path, body, {"quad.obj": QUAD_OBJ}))
    (em,) = [e for e in sc.emitters if isinstance(e, AreaEmitter)]
    rng = np.random.default_rng(9)
    _light_samples_agree(em, rng.uniform(-2, 2, (5000, 3)), rng.random((5000, 3)), 1000)
