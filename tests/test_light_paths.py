"""Every light path under every estimator: closed forms and estimator agreement on the generated light scenes.

Scenes (``scenes/lights/``, written by ``scenes/generate.py``): a faceted triangle-mesh sphere light (non-quad,
non-planar: the per-triangle path); a planar hexagon fan plus a smooth-normal sphere light (the fused
area-light set, interpolated light normals); a triangle light plus a point light plus a constant environment
(emitter selection matters, a delta light under MIS), each under ``uniform`` and ``power`` selection.

(a) Closed forms at points of the diffuse floor half (ρ = 0.5, L = ρ/π · E), computed here from the OBJ files
    without brdflab: Lambert's polygon formula E = L/2 Σ_k β_k (n·γ_k) for every flat emitting triangle that
    faces the point (a convex faceted sphere: exactly its visible faces), the inverse-square law I cos θ/r² of
    the point light, and the constant environment's π L minus what the triangle light blocks of it (Lambert's
    formula again). The smooth sphere light has no closed form: its irradiance is integrated here over its
    surface (barycentric midpoint rule) with the shading-normal emission rule of spec §9.1.
(b) ``direct_ems``, ``direct_mats`` (without the point light, which it cannot see) and ``direct_mis`` agree
    block by block over independent renders (:mod:`brdflab.judges.estimators.agreement`: Welch t-tests, Šidák over
    blocks and pairs; measured false-alarm rate 0 of 40 runs at the 0.01 level), and a planted bug (selection
    probability forgotten) is rejected.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
from scipy import stats

from brdflab.judges.estimators import agreement as ag
from brdflab.scene.loader import load_scene
from tests.conftest import ROOT, write_scene

LIGHTS = ROOT / "scenes" / "lights"
MESHES = LIGHTS / "meshes"
UP = np.array([0.0, 1.0, 0.0])
RHO = 0.5
#: Floor points (diffuse half) where the closed forms are checked; nothing but the lights is above them.
POINTS = [np.array([-0.5, 0.0, 0.3]), np.array([-1.5, 0.0, -1.0]), np.array([-0.3, 0.0, 1.5])]


def read_obj(name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """(positions, triangles, vertex normals per position or None) of a generated OBJ (f p, p//n, p/t/n)."""
    v, vn, faces, fn = [], [], [], []
    for line in (MESHES / name).read_text().splitlines():
        tok = line.split()
        if not tok:
            continue
        if tok[0] == "v":
            v.append([float(x) for x in tok[1:4]])
        elif tok[0] == "vn":
            vn.append([float(x) for x in tok[1:4]])
        elif tok[0] == "f":
            parts = [t.split("/") for t in tok[1:4]]
            faces.append([int(p[0]) - 1 for p in parts])
            if len(parts[0]) == 3:
                fn.append([int(p[2]) - 1 for p in parts])
    n = None
    if vn:
        n = np.zeros((len(v), 3))
        for f, g in zip(faces, fn, strict=True):
            n[f] = np.array(vn)[g]
    return np.array(v), np.array(faces), n


def lambert(x: np.ndarray, n: np.ndarray, poly: np.ndarray) -> float:
    """∫ cos θ dω over a planar polygon seen from x (normal n), all above the horizon (Lambert 1760)."""
    r = poly - x
    r /= np.linalg.norm(r, axis=1)[:, None]
    total = 0.0
    for k in range(len(r)):
        a, b = r[k], r[(k + 1) % len(r)]
        c = np.cross(a, b)
        total += np.arctan2(np.linalg.norm(c), a @ b) * (n @ (c / np.linalg.norm(c)))
    return abs(total) / 2


def facing(x: np.ndarray, tri: np.ndarray) -> bool:
    """True when the flat triangle's winding normal faces x (one-sided emission toward x)."""
    nrm = np.cross(tri[1] - tri[0], tri[2] - tri[0])
    return bool(nrm @ (x - tri.mean(axis=0)) > 0)


def flat_light(x: np.ndarray, name: str) -> float:
    """∫ cos dω over the faces of a flat (or convex faceted) light that face x."""
    v, f, _ = read_obj(name)
    return sum(lambert(x, UP, v[t]) for t in f if facing(x, v[t]))


def smooth_light(x: np.ndarray, name: str, n_sub: int = 12) -> float:
    """∫ cos θ_x cos θ_y / r² dA over the smooth light's surface where its interpolated normal faces x
    (spec §9.1), by the midpoint rule on n_sub² sub-triangles of every triangle (converged to 1e-5 at
    n_sub = 8)."""
    v, f, vn = read_obj(name)
    i, j = np.meshgrid(np.arange(n_sub), np.arange(n_sub), indexing="ij")
    up = np.stack([(i + 1 / 3) / n_sub, (j + 1 / 3) / n_sub], -1)[i + j < n_sub]  # upright sub-triangles
    down = np.stack([(i + 2 / 3) / n_sub, (j + 2 / 3) / n_sub], -1)[i + j < n_sub - 1]  # inverted ones
    b1, b2 = np.concatenate([up, down]).T
    p0, p1, p2 = (v[f[:, k]][:, None, :] for k in range(3))
    n0, n1, n2 = (vn[f[:, k]][:, None, :] for k in range(3))
    cross = np.cross(p1 - p0, p2 - p0)[:, 0]
    area = 0.5 * np.linalg.norm(cross, axis=1)
    ng = cross / (2 * area[:, None])
    y = p0 + b1[:, None] * (p1 - p0) + b2[:, None] * (p2 - p0)  # (triangles, points, 3)
    ns = n0 + b1[:, None] * (n1 - n0) + b2[:, None] * (n2 - n0)
    ns /= np.linalg.norm(ns, axis=2)[..., None]
    d = x - y
    r2 = np.sum(d * d, axis=2)
    w = d / np.sqrt(r2)[..., None]
    lit = np.sum(ns * w, axis=2) > 0
    g = np.abs(np.einsum("tpk,tk->tp", w, ng)) * np.maximum(-(w @ UP), 0.0) / r2
    return float(np.sum(np.where(lit, g, 0.0) * area[:, None]) / len(b1))


@functools.cache
def closed_form_at(scene: str, j: int, with_point: bool) -> np.ndarray:
    """:func:`closed_form` at ``POINTS[j]`` (cached: the smooth light's quadrature takes a while)."""
    return closed_form(scene, POINTS[j], with_point)


def closed_form(scene: str, x: np.ndarray, with_point: bool) -> np.ndarray:
    """Expected outgoing radiance (RGB) at floor point x looking straight down (L = ρ/π · E)."""
    if scene == "sphere_light":
        e = np.array([6.0, 5.0, 4.0]) * flat_light(x, "faceted_sphere.obj")
    elif scene == "polygon_lights":
        e = np.array([5.0, 5.0, 6.0]) * flat_light(x, "hexagon.obj")
        e = e + np.array([12.0, 9.0, 6.0]) * smooth_light(x, "smooth_sphere.obj")
    else:
        tri = flat_light(x, "triangle.obj")
        e = np.array([9.0, 8.0, 7.0]) * tri
        v, _, _ = read_obj("triangle.obj")
        e = e + np.array([0.25, 0.3, 0.4]) * (np.pi - lambert(x, UP, v))  # the light blocks the sky behind it
        if with_point:
            d = np.array([0.8, 1.6, 0.6]) - x
            r2 = d @ d
            e = e + np.array([3.0, 3.0, 2.5]) * (d @ UP) / np.sqrt(r2) / r2
    return RHO / np.pi * e


CASES = [(s, sel) for s, sels in (("sphere_light", ("uniform",)), ("polygon_lights", ("uniform", "power")),
                                  ("mixed_lights", ("uniform", "power"))) for sel in sels]


@pytest.mark.parametrize("name, selection", CASES)
def test_estimators_match_closed_forms(name, selection):
    """Each estimator's mean at three floor points equals the closed form (z-test, Šidák over the 36
    values per case: 3 points × 4 estimators × RGB; the smooth light's quadrature adds 0.3 %).

    ``direct_whitted`` (one sample of every emitter) sees the same lights as emitter sampling."""
    n = 25_000
    zs = []
    for integ in ("direct_ems", "direct_mats", "direct_mis", "direct_whitted"):
        s = load_scene(LIGHTS / f"{name}_mis.xml", integ)
        s.set_emitter_selection(selection)
        for j, x in enumerate(POINTS):
            o = np.tile(x + [0.0, 0.01, 0.0], (n, 1))
            d = np.tile(-UP, (n, 1))
            rng = np.random.default_rng(ag._seed(name, selection, integ, j))
            L = s.integrator.li(s, o, d, np.full(n, 1.0), rng)
            ref = closed_form_at(name, j, integ != "direct_mats")
            se = L.std(axis=0) / np.sqrt(n)
            tol = 3e-3 * ref if name == "polygon_lights" else 0.0
            z = np.maximum(np.abs(L.mean(axis=0) - ref) - tol, 0.0) / se
            zs.append((float(z.max()), integ, j, L.mean(axis=0), ref))
            assert np.all(se > 0) and np.all(ref > 0)
    p_min = 2 * stats.norm.sf(max(z for z, *_ in zs))
    alpha = 1 - (1 - 0.01) ** (1 / (3 * len(zs)))
    assert p_min > alpha, max(zs, key=lambda t: t[0])



def test_closed_forms_have_power():
    """The closed forms tell the light terms apart: the point light and the environment are each more than
    5 % of the mixed scene's radiance, and the smooth sphere more than 5 % of the polygon scene's."""
    for j, x in enumerate(POINTS):
        full = closed_form_at("mixed_lights", j, True)
        assert np.all(full / closed_form_at("mixed_lights", j, False) > 1.05)
        sky = RHO / np.pi * 0.25 * (np.pi - lambert(x, UP, read_obj("triangle.obj")[0]))
        assert sky / full[0] > 0.05
        hexagon = RHO / np.pi * 5.0 * flat_light(x, "hexagon.obj")
        assert 1 - hexagon / closed_form_at("polygon_lights", j, True)[0] > 0.05


def test_point_light_under_mis_is_the_closed_form(tmp_path):
    """A point light alone: direct_mis gives exactly direct_ems (MIS weight 1, BSDF samples find nothing),
    ρ/π · I cos θ / r² at every point."""
    body = ('<integrator type="direct_mis"/><camera type="perspective"><integer name="width" value="4"/>'
            '<integer name="height" value="4"/></camera>'
            '<mesh type="obj"><string name="filename" value="floor.obj"/><bsdf type="diffuse">'
            '<color name="albedo" value="0.5,0.5,0.5"/></bsdf></mesh>'
            '<emitter type="pointlight"><point name="position" value="0.3,2,0.1"/>'
            '<color name="radiance" value="10,8,6"/></emitter>')
    path = write_scene(tmp_path, body, {"floor.obj": (MESHES / "floor_left.obj").read_text()})
    pts = np.array([[-0.5, 0.0, 0.3], [-2.0, 0.0, -1.0], [-0.1, 0.0, 2.0]])
    n = len(pts)
    for integ in ("direct_mis", "direct_ems"):
        s = load_scene(path, integ)
        L = s.integrator.li(s, pts + [0, 0.01, 0], np.tile(-UP, (n, 1)), np.full(n, 1.0), np.random.default_rng(0))
        d = np.array([0.3, 2.0, 0.1]) - pts
        r2 = np.sum(d * d, axis=1)
        ref = 0.5 / np.pi * np.array([10.0, 8.0, 6.0]) * (d[:, 1] / np.sqrt(r2) / r2)[:, None]
        np.testing.assert_allclose(L, ref, rtol=1e-6, err_msg=integ)


@pytest.mark.parametrize("name, selection", [("sphere_light", "uniform"), ("polygon_lights", "power"),
                                             ("mixed_lights", "power")])
def test_estimators_agree(name, selection):
    """Image agreement (``brdflab validate`` runs the other selection rules too)."""
    r = ag.estimator_agreement(LIGHTS / f"{name}_mis.xml", selection=selection, reps=8)
    assert r.passed, (r.p_value, r.worst, r.means)
    assert r.tests > 30  # the check has data


@pytest.mark.parametrize("name", ["mixed_lights", "polygon_lights"])
def test_agreement_rejects_a_forgotten_selection_probability(name):
    """Negative control: light samples divided by p_ω instead of p_sel·p_ω (emitters still chosen by p_sel);
    per-emitter sampling (mixed) and the fused area-light set (polygon)."""
    r = ag.estimator_agreement(LIGHTS / f"{name}_mis.xml", prepare=ag.forget_selection_probability, reps=12,
                               estimators=("direct_ems", "direct_mats"))
    assert not r.passed and r.p_value < 1e-3, (name, r.p_value, r.worst)


@pytest.mark.parametrize("name, bound", [("sphere_light", 0.01), ("polygon_lights", 0.015)])
def test_converges_to_reference(name, bound):
    """The small light scenes against their references (references/, 4096 spp): image mean within the bound
    at 256 spp (4σ of the seed-to-seed spread of the mean, measured: σ ≈ 0.35 % and 0.75 % at 64 spp; the
    small bright lights make these images noisier than the bundled ones), and relMSE falls with spp."""
    from brdflab.imageio import read_exr
    from brdflab.pages.metrics import compare
    from brdflab.renderer import render

    ref = read_exr(ROOT / "references" / f"{name}.exr")
    images = {}
    render(load_scene(LIGHTS / f"{name}_mis.xml"), spp=256, seed=31, workers=1,
           on_pass=lambda spp, t, film: images.__setitem__(spp, film.image()))
    e16, e256 = compare(images[16], ref), compare(images[256], ref)
    assert e256.relmse <= 0.3 * e16.relmse, (e16.relmse, e256.relmse)
    assert abs(e256.bias) < bound, e256.bias


def test_power_selection_probabilities():
    """Power-proportional selection (spec §8, brdflab's normalisation): area lights lum(L_e)·A·π, point
    lights lum(I)·4π, the environment lum(radiance)·4π, divided by their sum."""
    s = load_scene(LIGHTS / "mixed_lights_mis.xml")
    s.set_emitter_selection("power")
    lum = np.array([0.212671, 0.715160, 0.072169])
    v, f, _ = read_obj("triangle.obj")
    area = 0.5 * np.linalg.norm(np.cross(v[f[0, 1]] - v[f[0, 0]], v[f[0, 2]] - v[f[0, 0]]))
    power = {"pointlight": lum @ [3.0, 3.0, 2.5] * 4 * np.pi, "environment": lum @ [0.25, 0.3, 0.4] * 4 * np.pi,
             "area": lum @ [9.0, 8.0, 7.0] * area * np.pi}
    expected = np.array([power[e.type_name] for e in s.emitters])
    np.testing.assert_allclose(s.emitter_pmf, expected / expected.sum(), rtol=1e-12)
    np.testing.assert_allclose(s.emitter_cdf, np.cumsum(expected / expected.sum()), rtol=1e-12)
    s.set_emitter_selection("uniform")
    np.testing.assert_array_equal(s.emitter_pmf, np.full(3, 1 / 3))


def test_point_light_sample_near_and_at_the_light():
    """I/r² at distances below 1 too (no cut-off), pdf 1, direction toward the light; 0 at the light itself."""
    from brdflab.emitter.point import PointLight

    em = PointLight(np.array([0.0, 0.5, 0.0]), np.array([2.0, 1.0, 0.5]))
    ref = np.array([[0.0, 0.0, 0.0], [0.3, 0.5, 0.0], [0.0, 0.5, 0.0]])
    r = em.sample(ref, np.zeros((3, 3)))
    np.testing.assert_allclose(r.radiance[:2], np.array([[2.0, 1.0, 0.5]]) / np.array([[0.25], [0.09]]), rtol=1e-14)
    np.testing.assert_array_equal(r.radiance[2], 0.0)
    np.testing.assert_allclose(r.wi[:2], [[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]], atol=1e-15)
    np.testing.assert_array_equal(r.pdf, 1.0)
    np.testing.assert_allclose(r.dist[:2], [0.5, 0.3], rtol=1e-15)


#: A 2 × 2 quad light at height 2 facing down (winding normal −y), uv (0, 0) … (1, 1) over x, z ∈ [−1, 1].
CHECKER_LIGHT_OBJ = """v -1 2 -1
v 1 2 -1
v 1 2 1
v -1 2 1
vt 0 0
vt 1 0
vt 1 1
vt 0 1
f 1/1 2/2 3/3 4/4
"""


def test_textured_area_light_is_the_closed_form(tmp_path):
    """A checker-textured quad light (spec §9.1, checker of §12: 0.9 where ⌊2u⌋ ≡ ⌊2v⌋ mod 2, else 0.1, times
    ``scale``): the per-triangle textured path gives, under every estimator, ρ/π Σ_cells L_cell ∫_cell cos dω
    (Lambert's formula per checker cell); light samples that miss the front side carry no radiance."""
    body = ('<integrator type="direct_ems"/><camera type="perspective"><integer name="width" value="4"/>'
            '<integer name="height" value="4"/></camera>'
            '<mesh type="obj"><string name="filename" value="floor.obj"/><bsdf type="diffuse">'
            '<color name="albedo" value="0.5,0.5,0.5"/></bsdf></mesh>'
            '<mesh type="obj"><string name="filename" value="light.obj"/><emitter type="area">'
            '<texture type="checker" name="radiance"><integer name="scalex" value="2"/>'
            '<integer name="scaley" value="2"/></texture><float name="scale" value="10"/></emitter></mesh>')
    path = write_scene(tmp_path, body, {"floor.obj": (MESHES / "floor_left.obj").read_text(),
                                        "light.obj": CHECKER_LIGHT_OBJ})
    cells = [(-1, 0, -1, 0, 9.0), (0, 1, 0, 1, 9.0), (-1, 0, 0, 1, 1.0), (0, 1, -1, 0, 1.0)]  # x0 x1 z0 z1 L
    pts = [np.array([-0.5, 0.0, 0.3]), np.array([-1.5, 0.0, -1.0])]
    n = 40_000
    zs = []
    for integ in ("direct_ems", "direct_mats", "direct_mis", "direct_whitted"):
        s = load_scene(path, integ)
        assert not s.emitters[0].radiance.constant
        for j, x in enumerate(pts):
            ref = RHO / np.pi * sum(le * lambert(x, UP, np.array([[x0, 2, z0], [x1, 2, z0], [x1, 2, z1], [x0, 2, z1]]))
                                    for x0, x1, z0, z1, le in cells)
            rng = np.random.default_rng(ag._seed("checker", integ, j))
            L = s.integrator.li(s, np.tile(x + [0.0, 0.01, 0.0], (n, 1)), np.tile(-UP, (n, 1)), np.full(n, 1.0), rng)
            se = L.std(axis=0) / np.sqrt(n)
            assert np.all(se > 0)
            zs.append((float(np.max(np.abs(L.mean(axis=0) - ref) / se)), integ, j, L.mean(axis=0), ref))
    alpha = 1 - (1 - 0.01) ** (1 / (3 * len(zs)))
    assert 2 * stats.norm.sf(max(z for z, *_ in zs)) > alpha, max(zs, key=lambda t: t[0])
    # Seen from above (behind the one-sided light) every sample is invalid: pdf 0 and radiance 0.
    light = s.emitters[0]
    r = light.sample(np.tile([0.2, 3.0, 0.1], (500, 1)), np.random.default_rng(3).random((500, 3)))
    assert not r.pdf.any() and not r.radiance.any()


@pytest.mark.parametrize("name", ["sphere_light", "polygon_lights", "mixed_lights"])
def test_camera_rays_that_hit_a_light_see_its_radiance(name):
    """A camera ray that hits the front of an area light returns L_e under every estimator (spec §8), for
    whichever index the light has in the emitter list (0 for the only light; after point/environment)."""
    mesh, le = {"sphere_light": ("faceted_sphere.obj", [6.0, 5.0, 4.0]),
                "polygon_lights": ("hexagon.obj", [5.0, 5.0, 6.0]),
                "mixed_lights": ("triangle.obj", [9.0, 8.0, 7.0])}[name]
    v, f, _ = read_obj(mesh)
    centres = v[f].mean(axis=1)
    normals = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    o = centres + 0.05 * normals  # just in front of each face, looking back at it
    d = -normals
    for integ in ("direct_ems", "direct_mats", "direct_mis"):
        s = load_scene(LIGHTS / f"{name}_mis.xml", integ)
        L = s.integrator.li(s, o, d, np.full(len(o), np.inf), np.random.default_rng(5))
        assert np.all(L >= np.array(le) - 1e-9), (integ, L.min(axis=0))
        assert np.all(L.mean(axis=0) < 1.05 * np.array(le) + 0.5)


MIRRORED_LIGHT_OBJ = """v -1 2 -1
v -1 2 1
v 1 2 1
v 1 2 -1
vn 0 -1 0
f 1//1 2//1 3//1 4//1
"""


def _tilted_mirrored_light(deg: float = 25.0) -> tuple[str, np.ndarray]:
    """The quad light turned by ``deg`` about the x axis through (0, 2, 0), winding up, every vn down-ish."""
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    rot = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    quad = np.array([[-1, 0, -1], [-1, 0, 1], [1, 0, 1], [1, 0, -1]], float) @ rot.T + [0, 2, 0]
    n = rot @ [0.0, -1.0, 0.0]
    text = "".join(f"v {x:.17g} {y:.17g} {z:.17g}\n" for x, y, z in quad) + f"vn {n[0]:.17g} {n[1]:.17g} {n[2]:.17g}\n"
    return text + "f 1//1 2//1 3//1 4//1\n", quad


TILTED_LIGHT_OBJ, TILTED_QUAD = _tilted_mirrored_light()


@pytest.mark.parametrize("obj", [CHECKER_LIGHT_OBJ, MIRRORED_LIGHT_OBJ, TILTED_LIGHT_OBJ],
                         ids=["winding-down", "vn-down-winding-up", "tilted-vn-down-winding-up"])
def test_light_facing_by_vertex_normals(tmp_path, obj):
    """A quad light emits toward its shading normal (spec §9.1): with the winding normal pointing down, or
    with the winding up and every vertex normal down (a light mirrored by its toWorld, as in the course's
    table scene), the floor below receives L·∫cos dω (Lambert) under every estimator."""
    body = ('<integrator type="direct_ems"/><camera type="perspective"><integer name="width" value="4"/>'
            '<integer name="height" value="4"/></camera>'
            '<mesh type="obj"><string name="filename" value="floor.obj"/><bsdf type="diffuse">'
            '<color name="albedo" value="0.5,0.5,0.5"/></bsdf></mesh>'
            '<mesh type="obj"><string name="filename" value="light.obj"/><emitter type="area">'
            '<color name="radiance" value="5,4,3"/></emitter></mesh>')
    path = write_scene(tmp_path, body, {"floor.obj": (MESHES / "floor_left.obj").read_text(), "light.obj": obj})
    x = np.array([-0.5, 0.0, 0.3])
    quad = TILTED_QUAD if obj == TILTED_LIGHT_OBJ else np.array([[-1, 2, -1], [1, 2, -1], [1, 2, 1], [-1, 2, 1]], float)
    ref = RHO / np.pi * np.array([5.0, 4.0, 3.0]) * lambert(x, UP, quad)
    n = 20_000
    zs = []
    for integ in ("direct_ems", "direct_mats", "direct_mis"):
        s = load_scene(path, integ)
        rng = np.random.default_rng(ag._seed("facing", integ, obj))
        L = s.integrator.li(s, np.tile(x + [0.0, 0.01, 0.0], (n, 1)), np.tile(-UP, (n, 1)), np.full(n, 1.0), rng)
        zs.append(float(np.max(np.abs(L.mean(axis=0) - ref) / (L.std(axis=0) / np.sqrt(n)))))
    assert 2 * stats.norm.sf(max(zs)) > 1 - (1 - 0.01) ** (1 / 9), zs


@pytest.mark.parametrize("integ", ["direct_ems", "direct_mats", "direct_mis", "direct_whitted"])
def test_batches_of_zero_and_one_ray(integ):
    """Every integrator takes a batch of no rays; a batch of one ray gives that ray's value in a larger
    batch with the same stream (the uniforms are drawn per camera ray, so the first ray's are the same;
    ``direct_whitted`` draws one block per emitter, so it gets a scene with one light)."""
    s = load_scene(LIGHTS / ("sphere_light_mis.xml" if integ == "direct_whitted" else "mixed_lights_mis.xml"), integ)
    empty = s.integrator.li(s, np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), np.random.default_rng(1))
    assert empty.shape == (0, 3)
    rng = np.random.default_rng(2)
    o = np.concatenate([POINTS[:1], rng.uniform([-2, 0, -2], [0, 0, 2], (63, 3))]) + 0.01 * UP
    d = np.tile(-UP, (64, 1))
    lit = 0
    for seed in range(6):
        many = s.integrator.li(s, o, d, np.full(64, 1.0), np.random.default_rng(seed))
        one = s.integrator.li(s, o[:1], d[:1], np.full(1, 1.0), np.random.default_rng(seed))
        np.testing.assert_array_equal(one, many[:1])
        lit += bool(one.max() > 0)
    assert lit >= 1


def test_mis_parts_add_up_to_the_estimate():
    """direct_mis's weight-image parts (``parts = "emitter"`` / ``"bsdf"``) use the same random numbers, so with
    one seed they add up to the estimate minus the camera-visible emission (a shading point's light term
    plus its BSDF term)."""
    from brdflab.integrator.direct_mis import DirectMIS

    s = load_scene(LIGHTS / "mixed_lights_mis.xml", "direct_mis")
    rng = np.random.default_rng(9)
    n = 2000
    o = rng.uniform([-2, 0, -2], [2, 0, 2], (n, 3)) + 0.01 * UP
    d = np.tile(-UP, (n, 1))
    out = {}
    for parts in ("both", "emitter", "bsdf"):
        integ = DirectMIS()
        integ.parts = parts
        out[parts] = integ.li(s, o, d, np.full(n, 1.0), np.random.default_rng(21))
    assert out["emitter"].max() > 0 and out["bsdf"].max() > 0
    np.testing.assert_allclose(out["emitter"] + out["bsdf"], out["both"], rtol=1e-12, atol=1e-15)


def _quad(z: float, x0: float, x1: float, flip: bool = False):
    from brdflab.scene.obj import Mesh

    p = np.array([[x0, -1.0, z], [x1, -1.0, z], [x1, 1.0, z], [x0, 1.0, z]])
    f = np.array([[0, 2, 1], [0, 3, 2]] if flip else [[0, 1, 2], [0, 2, 3]])
    return Mesh(p, f, None, None, "<quad>")


@pytest.mark.parametrize("second_scene", [True, False])
def test_trace_to_lights_is_the_closest_hit_where_that_is_a_light(monkeypatch, second_scene):
    """Geometry.trace_to_lights (light triangles first, then an occlusion query) returns exactly the closest
    hit's record where that hit is a light triangle and −1 everywhere else: rays that miss, rays stopped by an
    occluder in front of a light, rays that hit a non-light first. Each case must occur (the test has data)."""
    import brdflab.scene.geometry as geometry
    from brdflab.scene.geometry import Geometry

    if not second_scene:  # more light triangles than a second scene is built for: the closest-hit query
        monkeypatch.setattr(geometry, "LIGHT_SCENE_MAX", 1)
    # Floor (z = 0) under a light quad (z = 2, x in [-1, 1]) half covered by an occluder (z = 1, x in [0, 2])
    # and a second, larger light (z = 3).
    g = Geometry([_quad(0.0, -3, 3), _quad(2.0, -1, 1, True), _quad(1.0, 0, 2, True), _quad(3.0, -3, 3, True)])
    tri_emitter = np.array([-1, -1, 0, 0, -1, -1, 1, 1, -1])
    rng = np.random.default_rng(27)
    n = 20000
    o = np.column_stack([rng.uniform(-2, 2, n), rng.uniform(-0.5, 0.5, n), np.full(n, 0.01)]).astype(np.float32)
    d = rng.normal(size=(n, 3))
    d[:, 2] = np.abs(d[:, 2]) * np.where(rng.random(n) < 0.9, 1, -1)  # a tenth go down into the floor
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    ref, got = g.trace(o, d), g.trace_to_lights(o, d, tri_emitter)
    light = tri_emitter[ref.prim] >= 0
    assert np.array_equal(got.prim >= 0, light)
    assert np.array_equal(got.prim[light], ref.prim[light])
    for a in ("u", "v", "t"):
        assert np.array_equal(getattr(got, a)[light], getattr(ref, a)[light]), a
    blocked = ref.valid & ~light
    assert light.sum() > 1000 and (~ref.valid).sum() > 1000 and blocked.sum() > 1000
    assert (tri_emitter[ref.prim[blocked]] == -1).all() and (ref.prim[blocked] >= 4).any()  # the occluder
    assert (g._light_scene(tri_emitter)[1] is g) is not second_scene
    if not second_scene:
        return
    # Negative control: without the occlusion query, the light behind the occluder would count.
    unblocked = g._light_scene(tri_emitter)[1].run(o, d.astype(np.float32), output=1)["primID"] >= 0
    assert (unblocked & ~light).sum() > 100
    # A new light table rebuilds the light scene; none at all finds nothing.
    only_top = np.array([-1, -1, -1, -1, -1, -1, 0, 0, -1])
    assert np.array_equal(g.trace_to_lights(o, d, only_top).prim >= 0, only_top[g.trace(o, d).prim] >= 0)
    assert (g.trace_to_lights(o, d, np.full(9, -1)).prim == -1).all()


@pytest.mark.parametrize("scene, integrator", [("veach/veach_mis.xml", "direct_mats"),
                                               ("cbox/cbox_spheres.xml", "direct_mis")])
def test_images_through_trace_to_lights_are_the_closest_hit_images(monkeypatch, scene, integrator):
    """The BSDF rays' two-query path gives the image of the closest-hit path, to the bit."""
    import brdflab as bl
    from brdflab.scene.geometry import Geometry

    s = load_scene(ROOT / "scenes" / scene, integrator=integrator, width=64, height=48)
    fast = bl.render(s, spp=4, seed=5, workers=1)
    monkeypatch.setattr(Geometry, "trace_to_lights", lambda self, o, d, tri_emitter: self.trace(o, d))
    assert np.array_equal(fast, bl.render(s, spp=4, seed=5, workers=1)) and fast.max() > 0
