"""Camera rays (Nori's conventions), the mirror scale, filters and splatting."""

from __future__ import annotations

import numpy as np
import pytest

from brdflab.film import Camera, Film, Filter
from brdflab.math import transform as tf


def _cam(ops=None, w=200, h=100, fov=90.0):
    m = np.eye(4)
    for op in ops or []:
        m = op @ m
    return Camera(w, h, fov, 1e-4, 1e4, tf.Transform(m))


def test_centre_and_corners():
    cam = _cam([tf.lookat(np.zeros(3), np.array([0, 0, 5.0]), np.array([0, 1.0, 0]))], w=200, h=100, fov=90)
    o, d, _ = cam.generate_rays(np.array([100.0, 0.0, 200.0, 0.0]), np.array([50.0, 0.0, 0.0, 100.0]))
    np.testing.assert_allclose(d[0], [0, 0, 1], atol=1e-12)
    # Horizontal fov 90°: the left image edge at the centre row is 45° toward camera +x (= l = up × d).
    d_left = cam.generate_rays(np.array([0.0]), np.array([50.0]))[1][0]
    np.testing.assert_allclose(d_left, np.array([1, 0, 1]) / np.sqrt(2), atol=1e-12)
    # Top-left corner: x = T, y = T/a with T = 1, a = 2.
    np.testing.assert_allclose(d[1], np.array([1, 0.5, 1]) / np.linalg.norm([1, 0.5, 1]), atol=1e-12)
    np.testing.assert_allclose(d[2], np.array([-1, 0.5, 1]) / np.linalg.norm([1, 0.5, 1]), atol=1e-12)
    np.testing.assert_allclose(d[3], np.array([1, -0.5, 1]) / np.linalg.norm([1, 0.5, 1]), atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0)


def test_mirror_scale_flips_left_right():
    look = tf.lookat(np.zeros(3), np.array([0, 0, 5.0]), np.array([0, 1.0, 0]))
    plain = _cam([look])
    mirrored = _cam([tf.scale(np.array([-1.0, 1, 1])), look])
    px, py = np.array([10.0]), np.array([50.0])
    d1 = plain.generate_rays(px, py)[1][0]
    d2 = mirrored.generate_rays(px, py)[1][0]
    np.testing.assert_allclose(d2, [-d1[0], d1[1], d1[2]], atol=1e-12)


def test_gaussian_filter_table():
    f = Filter()
    assert f.radius == 2 and len(f.table) == 33 and f.table[-1] == 0
    assert f.weights(np.array([0.0]))[0] == pytest.approx(1 - np.exp(-8))
    # Piecewise constant in bins of r/32 = 1/16 pixel.
    assert f.weights(np.array([0.06]))[0] == f.weights(np.array([0.0]))[0]
    assert f.weights(np.array([2.5]))[0] == 0


def test_splat_normalises_by_weight_sum():
    f = Filter()
    film = Film(8, 6, f)
    rng = np.random.default_rng(1)
    n = 5000
    sx, sy = rng.random(n) * 8, rng.random(n) * 6
    film.splat(sx, sy, np.full((n, 3), 2.5))
    np.testing.assert_allclose(film.image(), 2.5, rtol=1e-12)


def test_tile_films_add_up_to_whole_film():
    f = Filter()
    rng = np.random.default_rng(2)
    sx, sy = rng.random(4000) * 16, rng.random(4000) * 12
    vals = rng.random((4000, 3))
    whole = Film(16, 12, f)
    whole.splat(sx, sy, vals)
    merged = Film(16, 12, f)
    for x0, y0 in ((0, 0), (8, 0), (0, 6), (8, 6)):
        m = (sx >= x0) & (sx < x0 + 8) & (sy >= y0) & (sy < y0 + 6)
        tile = Film(16, 12, f, x0, y0, 8, 6)
        tile.splat(sx[m], sy[m], vals[m])
        merged.add(tile)
    np.testing.assert_allclose(merged.image(), whole.image(), rtol=1e-12)


@pytest.mark.parametrize("kind", ["gaussian", "mitchell", "tent", "box"])
def test_power_of_two_phase_split_matches_the_general_one(kind):
    """The shift-and-mask tap computation (2^k phases) gives the taps and phases of the general one,
    including samples on pixel centres and tile edges."""
    f = Filter(kind)
    assert f.phase_bits is not None
    film = Film(200, 100, f, 40, 30, 32, 32)
    s = np.concatenate([40 + np.random.default_rng(0).random(50_000) * 32,
                        [40.0, 40.5, 41.0, 55.5, 56.0, np.nextafter(72.0, 0.0)]])
    fast = film._taps(s, film.x0, film.bw)
    f.phase_bits = None
    slow = film._taps(s, film.x0, film.bw)
    for a, b in zip(fast, slow, strict=True):
        np.testing.assert_array_equal(a, b)
