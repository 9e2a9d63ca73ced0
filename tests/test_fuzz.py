"""Property-based and fuzz tests (hypothesis): loaders never fail with anything but a clean BrdflabError,
and the math helpers keep their invariants."""

from __future__ import annotations

import warnings

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from brdflab.errors import BrdflabError
from brdflab.math import transform as tf
from brdflab.math import warps
from brdflab.math.frame import NormalFrames, dot, frame_from_normal, normalize, to_local, to_world
from brdflab.scene.loader import load_scene
from brdflab.scene.obj import load_obj
from tests.conftest import CAMERA, QUAD_OBJ

VALID_SCENE = ("<scene>\n<integrator type=\"direct_ems\"/>\n" + CAMERA + "\n"
               "<sampler type=\"independent\"><integer name=\"sampleCount\" value=\"4\"/></sampler>\n"
               "<mesh type=\"obj\"><string name=\"filename\" value=\"q.obj\"/>\n"
               "<transform name=\"toWorld\"><scale value=\"2,1,2\"/><translate value=\"0,0.1,0\"/></transform>\n"
               "<bsdf type=\"diffuse\"><texture type=\"checker\" name=\"albedo\">"
               "<integer name=\"scalex\" value=\"4\"/></texture></bsdf></mesh>\n"
               "<emitter type=\"pointlight\"><point name=\"position\" value=\"0,2,0\"/>"
               "<color name=\"radiance\" value=\"5 5 5\"/></emitter>\n</scene>\n")
ALPHABET = st.sampled_from(list("<>/=\"' \n0123456789.-+,eEabcdefghijklmnopqrstuvwxyz_") + ["nan", "inf"])


def _mutate(text: str, data) -> str:
    for _ in range(data.draw(st.integers(1, 4))):
        i = data.draw(st.integers(0, len(text)))
        op = data.draw(st.sampled_from(["insert", "delete", "replace", "duplicate"]))
        s = data.draw(ALPHABET)
        if op == "insert":
            text = text[:i] + s + text[i:]
        elif op == "delete":
            text = text[:i] + text[i + data.draw(st.integers(1, 8)):]
        elif op == "replace":
            text = text[:i] + s + text[i + 1:]
        else:
            j = data.draw(st.integers(i, min(len(text), i + 40)))
            text = text[:j] + text[i:j] + text[j:]
    return text


FUZZ = settings(max_examples=1000, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


@FUZZ
@given(st.data())
def test_scene_mutations_give_clean_errors(tmp_path_factory, data):
    d = tmp_path_factory.getbasetemp() / "fuzz_scene"
    d.mkdir(exist_ok=True)
    (d / "q.obj").write_text(QUAD_OBJ)
    (d / "s.xml").write_text(_mutate(VALID_SCENE, data))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            load_scene(d / "s.xml")
        except BrdflabError as exc:
            assert exc.file is not None and str(exc)


@FUZZ
@given(st.data())
def test_obj_mutations_give_clean_errors(tmp_path_factory, data):
    d = tmp_path_factory.getbasetemp() / "fuzz_obj"
    d.mkdir(exist_ok=True)
    base = QUAD_OBJ + "vn 0 1 0\n" if data.draw(st.booleans()) else QUAD_OBJ
    (d / "m.obj").write_text(_mutate(base, data))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            m = load_obj(d / "m.obj")
        except BrdflabError as exc:
            assert exc.file is not None
            return
    assert np.isfinite(m.positions).all()
    assert m.faces.min() >= 0 and m.faces.max() < len(m.positions)


finite = st.floats(-10, 10, allow_nan=False)
vec3 = st.tuples(finite, finite, finite).map(np.array)


@settings(max_examples=200, deadline=None)
@given(vec3, st.tuples(finite, finite, finite).filter(lambda v: min(map(abs, v)) > 0.1).map(np.array),
       st.floats(-360, 360), vec3.filter(lambda v: np.linalg.norm(v) > 0.1))
def test_transforms_invert(t, s, angle, axis):
    axis = axis / np.linalg.norm(axis)
    m = tf.Transform(tf.translate(t) @ tf.rotate(angle, axis) @ tf.scale(s))
    p = np.array([[0.3, -1.2, 2.0], [1.0, 0.0, 0.0]])
    back = tf.Transform(m.inverse).apply_points(m.apply_points(p))
    np.testing.assert_allclose(back, p, atol=1e-8)
    # Normals stay perpendicular to transformed tangent vectors.
    n, v = np.array([[0.0, 0.0, 1.0]]), np.array([[1.0, 0.0, 0.0]])
    assert abs(dot(m.apply_normals(n), m.apply_vectors(v))[0]) < 1e-8


@settings(max_examples=300, deadline=None)
@given(vec3.filter(lambda v: np.linalg.norm(v) > 1e-3))
def test_frames_orthonormal(n):
    n = normalize(n[None, :])
    s, t = frame_from_normal(n)
    for a in (s, t):
        assert abs(dot(a, a)[0] - 1) < 1e-12
        assert abs(dot(a, n)[0]) < 1e-12
    assert abs(dot(s, t)[0]) < 1e-12
    w = np.array([[0.2, -0.5, 0.7]])
    np.testing.assert_allclose(to_world(to_local(w, s, t, n), s, t, n), w, atol=1e-12)
    # The implicit frames of the render path are the same frames.
    fr = NormalFrames(n)
    np.testing.assert_allclose(fr.to_local(w), to_local(w, s, t, n), atol=1e-12)
    np.testing.assert_allclose(fr.to_local(w, negate=True), -to_local(w, s, t, n), atol=1e-12)
    np.testing.assert_allclose(fr.to_world(w), to_world(w, s, t, n), atol=1e-12)
    np.testing.assert_allclose(fr.take(np.array([0])).to_world(fr.to_local(w)), w, atol=1e-12)


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(st.floats(0, 1, exclude_max=True), st.floats(0, 1, exclude_max=True)), min_size=1,
                max_size=50), st.floats(1e-3, 1.0))
def test_warps_map_into_domains_with_positive_pdf(us, alpha):
    u = np.array(us)
    for sample, pdf, check in (
        (warps.square_to_uniform_sphere, warps.square_to_uniform_sphere_pdf, lambda w: True),
        (warps.square_to_uniform_hemisphere, warps.square_to_uniform_hemisphere_pdf, lambda w: (w[:, 2] >= 0).all()),
        (warps.square_to_cosine_hemisphere, warps.square_to_cosine_hemisphere_pdf, lambda w: (w[:, 2] >= 0).all()),
    ):
        w = sample(u)
        np.testing.assert_allclose(np.linalg.norm(w, axis=1), 1.0, atol=1e-12)
        assert check(w)
        assert (pdf(w)[w[:, 2] > 0] > 0).all()
    b = warps.square_to_uniform_triangle(u)
    assert (warps.square_to_uniform_triangle_pdf(b) == 2).all()
    d = warps.square_to_uniform_disk(u)
    assert (warps.square_to_uniform_disk_pdf(d) > 0).all()
    h = warps.square_to_beckmann(u, alpha)
    np.testing.assert_allclose(np.linalg.norm(h, axis=1), 1.0, atol=1e-12)
    assert (h[:, 2] > 0).all()


def test_beckmann_warp_closed_end_is_finite():
    """ξ1 = 1 (allowed by stratified or low-discrepancy points) must not produce NaN."""
    u = np.array([[1.0, 0.3], [0.0, 0.0], [np.nextafter(1.0, 0.0), 0.9]])
    for alpha in (1e-4, 0.1, 1.0):
        h = warps.square_to_beckmann(u, alpha)
        assert np.isfinite(h).all()
        np.testing.assert_allclose(np.linalg.norm(h, axis=1), 1.0, atol=1e-12)
        assert abs(h[0, 2]) < 1e-12  # horizon
