"""Splat weights and the render merge against values computed by hand.

(a) A few samples of different values splatted into an empty film: every pixel is Σ w L / Σ w with
    w = F(|x − q_x|)·F(|y − q_y|), q = s − ½ and F the tabulated filter (entry ⌊32|d|/r⌋ of f at i·r/32),
    written out here for the tent and Gaussian filters — through the separable and the direct splat, the
    generic (non power-of-two) path, and a tile film merged into a whole one. Distinct values and
    off-centre positions in x and y make a swapped axis, a lost ½ offset or a transposed image visible
    (constant values, as in tests/test_camera_film.py, cannot show them).
(b) A render with a box filter (one sample, one pixel, weight 1) and an integrator whose per-sample value is
    a known function of the pixel plus uniform noise: each pixel is then the mean of its spp samples, so
    the image's mean is the function and its variance 1/(12 spp) — a pass dropped or counted twice in the
    merge, or a tile put in the wrong place, changes one of them.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from brdflab.film import Film, Filter
from brdflab.kernels import load
from tests.conftest import write_scene


def _tent(d: np.ndarray) -> np.ndarray:
    d = np.abs(d)
    return np.where(d < 1, 1.0 - np.floor(32 * d) / 32, 0.0)


def _gauss(d: np.ndarray, r: float = 2.0, s: float = 0.5) -> np.ndarray:
    i = np.floor(np.abs(d) * 32 / r)
    x = i * r / 32
    return np.where(i < 32, np.maximum(0.0, np.exp(-x * x / (2 * s * s)) - math.exp(-r * r / (2 * s * s))), 0.0)


def _expected(w: int, h: int, samples, f) -> np.ndarray:
    num, den = np.zeros((h, w, 3)), np.zeros((h, w))
    for sx, sy, v in samples:
        wx = f(np.arange(w) - (sx - 0.5))
        wy = f(np.arange(h) - (sy - 0.5))
        ww = wy[:, None] * wx[None, :]
        num += ww[..., None] * np.asarray(v)
        den += ww
    return np.where(den[..., None] > 0, num / np.where(den > 0, den, 1.0)[..., None], 0.0)


SAMPLES = [(2.8, 1.6, (1.0, 2.0, 3.0)), (3.45, 1.51, (4.0, 0.0, 1.0)), (6.1, 3.35, (0.5, 0.25, 8.0)),
           (6.53, 4.2, (2.0, 2.0, 0.0)), (0.2, 5.9, (7.0, 1.0, 1.0))]
# (no position at a table-bin edge: the phase tables evaluate a sample at its phase centre, which differs
# from the exact tap only where 32·frac(q)/r is an integer, a set of measure zero for jittered samples)


def _splat(film: Film, how: str, samples) -> None:
    sx = np.array([s[0] for s in samples])
    sy = np.array([s[1] for s in samples])
    v = np.array([s[2] for s in samples], dtype=float)
    if how == "rows kernel":  # the compiled separable pass, which the cost model picks from 4 samples a pixel
        load("film").splat_film(film, sx, sy, v, rows=True)
        return
    getattr(film, how)(sx, sy, v)


@pytest.mark.parametrize("how", ["splat", "_splat_direct", "_splat_separable", "rows kernel"])
@pytest.mark.parametrize(("kind", "f"), [("tent", _tent), ("gaussian", _gauss)])
def test_splat_weights_by_hand(how, kind, f):
    film = Film(9, 7, Filter(kind))
    _splat(film, how, SAMPLES)
    np.testing.assert_allclose(film.image(), _expected(9, 7, SAMPLES, f), rtol=1e-6, atol=1e-7)
    # The tent weights of the first sample, written out: x taps 2, 3 at |d| = 0.3, 0.7; y taps 1, 2 at 0.1, 0.9.
    one = Film(9, 7, Filter(kind))
    _splat(one, how, SAMPLES[:1])
    b = one.border
    wsum = one.data[3, b:b + 7, b:b + 9]
    if kind == "tent":
        assert wsum[1, 2] == pytest.approx((1 - 9 / 32) * (1 - 3 / 32))
        assert wsum[2, 3] == pytest.approx((1 - 22 / 32) * (1 - 28 / 32))
        assert wsum[1, 3] == pytest.approx((1 - 22 / 32) * (1 - 3 / 32))
        assert np.count_nonzero(wsum) == 4


@pytest.mark.parametrize("how", ["splat", "_splat_direct", "_splat_separable", "rows kernel"])
@pytest.mark.parametrize("radius", [1.5, 1.6])
def test_generic_radius_splat_by_hand(how, radius):
    """Gaussians of radius 1.5 (32/r not an integer: the direct 2-D path without phase tables) and 1.6 (20
    phases, not a power of two: the general phase split)."""
    filt = Filter("gaussian", radius=radius, stddev=0.4)
    assert (filt.phases, filt.phase_bits) == ((0, None) if radius == 1.5 else (20, None))
    if how in ("_splat_separable", "rows kernel") and not filt.phases:
        return
    film = Film(9, 7, filt)
    _splat(film, how, SAMPLES)
    np.testing.assert_allclose(film.image(), _expected(9, 7, SAMPLES, lambda d: _gauss(d, radius, 0.4)),
                               rtol=1e-6, atol=1e-7)


def test_tile_film_merges_at_its_offset():
    """Samples of a tile (x0 = 4, y0 = 2, 4 × 3 pixels) splatted into a tile film and added into the whole film:
    the hand image of those samples, including their filter tails outside the tile."""
    inside = [s for s in SAMPLES if 4 <= s[0] < 8 and 2 <= s[1] < 5]
    assert len(inside) == 2
    tile = Film(9, 7, Filter("tent"), 4, 2, 4, 3)
    _splat(tile, "splat", inside)
    whole = Film(9, 7, Filter("tent"))
    whole.add(tile)
    np.testing.assert_allclose(whole.image(), _expected(9, 7, inside, _tent), rtol=1e-6, atol=1e-7)


# -- (b) the render merge ----------------------------------------------------------------------------------
W, H = 40, 18  # wider than tall: a transposed or shifted image cannot match; 2 to 6 tiles per pass


class _PixelNoise:
    """Integrator: L = (column + 1, row + 1, 1)/10 + U(0, 1) · (1, 1, 1), the pixel recovered from the ray."""

    needs_emitters = False

    def __init__(self, cam):
        self.cam = cam

    def li(self, scene, o, d, tmax, rng):
        # Inverse of the perspective mapping (identity camera): d ∝ ((1 − 2u)T, (1 − 2v)T/a, 1).
        t = math.tan(math.radians(self.cam.fov) / 2)
        a = self.cam.width / self.cam.height
        u = (1 - d[:, 0] / d[:, 2] / t) / 2
        v = (1 - d[:, 1] / d[:, 2] * a / t) / 2
        col, row = np.floor(u * self.cam.width), np.floor(v * self.cam.height)
        base = np.stack([col + 1, row + 1, np.ones_like(col)], axis=1) / 10
        return base + rng.random((len(d), 1))


@pytest.mark.parametrize(("progressive", "workers"), [(False, 1), (True, 1), (True, 2)])
def test_render_merge_mean_and_variance(tmp_path, progressive, workers):
    from brdflab.renderer import render
    from brdflab.scene.loader import load_scene

    body = ('<integrator type="normals"/><camera type="perspective"><float name="fov" value="40"/>'
            f'<integer name="width" value="{W}"/><integer name="height" value="{H}"/><rfilter type="box"/></camera>')
    scene = load_scene(write_scene(tmp_path, body))
    scene.integrator = _PixelNoise(scene.camera)
    spp = 48
    passes = []
    img, st = render(scene, spp=spp, seed=5, workers=workers,  # 2: forked workers, tiles via shared slots
                     on_pass=(lambda s, t, film: passes.append(s)) if progressive else None)
    from brdflab.renderer import tiles_for

    if progressive:
        assert len(passes) >= 3 and passes[-1] == spp  # several passes were merged
    assert len(tiles_for(W, H, 16 if progressive else spp)) >= 2  # and several tiles per pass
    yy, xx = np.mgrid[0:H, 0:W]
    truth = np.stack([xx + 1, yy + 1, np.ones_like(xx)], -1) / 10 + 0.5
    resid = img - truth
    n = resid.size
    # Each pixel: the mean of spp uniform draws: mean 0, variance 1/(12 spp) (exactly, the box filter).
    var = 1 / (12 * spp)
    z = resid.mean() / math.sqrt(var / (W * H))  # channels share their noise: W·H independent means
    assert abs(z) < 4, z
    chi = float((resid[..., 0] ** 2).sum() / var)
    lo, hi = stats.chi2.ppf(1e-4, W * H), stats.chi2.isf(1e-4, W * H)
    assert lo < chi < hi, (chi, lo, hi, n)
    assert np.allclose(resid[..., 0], resid[..., 2], atol=1e-5)  # the same noise in every channel


# -- filters and edges ------------------------------------------------------------------------------------
def _mitchell(x: np.ndarray, r: float = 2.0, b: float = 1 / 3, c: float = 1 / 3) -> np.ndarray:
    """Mitchell–Netravali (1988) in |2x/r|, written out per piece."""
    t = np.abs(2 * x / r)
    inner = ((12 - 9 * b - 6 * c) * t**3 + (-18 + 12 * b + 6 * c) * t**2 + (6 - 2 * b)) / 6
    outer = ((-b - 6 * c) * t**3 + (6 * b + 30 * c) * t**2 + (-12 * b - 48 * c) * t + (8 * b + 24 * c)) / 6
    return np.where(t < 1, inner, np.where(t < 2, outer, 0.0))


@pytest.mark.parametrize(("r", "b", "c"), [(2.0, 1 / 3, 1 / 3), (1.5, 0.0, 0.5), (3.0, 1.0, 0.0)])
def test_mitchell_table_by_hand(r, b, c):
    f = Filter("mitchell", r, b=b, c=c) if (r, b, c) != (2.0, 1 / 3, 1 / 3) else Filter("mitchell")
    x = r * np.arange(32) / 32
    np.testing.assert_allclose(f.table[:32], _mitchell(x, r, b, c), rtol=1e-12, atol=1e-15)
    assert f.table[32] == 0 and f.radius == r
    # Known values of the default (B = C = 1/3): f(0) = (6 − 2/3)/6 = 8/9, f(r/2) = 1/18 at |2x/r| = 1.
    if (b, c) == (1 / 3, 1 / 3):
        assert f.table[0] == pytest.approx(8 / 9) and f.table[16] == pytest.approx(1 / 18)


def test_rfilters_from_the_scene(tmp_path):
    from brdflab.scene.loader import load_scene

    cases = {'<rfilter type="gaussian"><float name="radius" value="1.5"/><float name="stddev" value="0.3"/></rfilter>':
             ("gaussian", 1.5), '<rfilter type="gaussian"/>': ("gaussian", 2.0),
             '<rfilter type="mitchell"><float name="radius" value="3"/><float name="B" value="1"/>'
             '<float name="C" value="0"/></rfilter>': ("mitchell", 3.0),
             '<rfilter type="tent"/>': ("tent", 1.0), '<rfilter type="box"/>': ("box", 0.5)}
    for xml, (kind, radius) in cases.items():
        body = ('<integrator type="normals"/><camera type="perspective"><integer name="width" value="4"/>'
                f'<integer name="height" value="4"/>{xml}</camera>')
        f = load_scene(write_scene(tmp_path, body)).filter
        assert (f.kind, f.radius) == (kind, radius)
        if kind == "gaussian" and radius == 1.5:
            np.testing.assert_allclose(f.table[:32], _gauss(np.arange(32) * 1.5 / 32, 1.5, 0.3), rtol=1e-12)
        if kind == "mitchell":
            np.testing.assert_allclose(f.table[:32], _mitchell(np.arange(32) * 3 / 32, 3.0, 1.0, 0.0), atol=1e-15)


def test_tiles_at_the_image_edges_merge_with_their_tails():
    """Tiles on the right and bottom edges (their films' borders reach past the image): the whole film
    equals the splat of all samples into one film."""
    rng = np.random.default_rng(4)
    sx, sy = rng.random(3000) * 13, rng.random(3000) * 9
    v = rng.random((3000, 3))
    whole = Film(13, 9, Filter())
    whole.splat(sx, sy, v)
    merged = Film(13, 9, Filter())
    for x0, y0, w, h in ((0, 0, 8, 8), (8, 0, 5, 8), (0, 8, 8, 1), (8, 8, 5, 1)):
        m = (sx >= x0) & (sx < x0 + w) & (sy >= y0) & (sy < y0 + h)
        tile = Film(13, 9, Filter(), x0, y0, w, h)
        tile.splat(sx[m], sy[m], v[m])
        merged.add(tile)
    np.testing.assert_allclose(merged.image(), whole.image(), rtol=1e-12)
    np.testing.assert_allclose(merged.data, whole.data, rtol=1e-12, atol=1e-12)


def test_camera_pixel_limit_is_inclusive(tmp_path):
    from brdflab.errors import SceneError
    from brdflab.film import Camera
    from brdflab.scene.properties import PropertyList

    def cam(w, h):
        p = PropertyList("camera")
        p.set("width", "integer", w)
        p.set("height", "integer", h)
        return Camera.from_properties(p)

    assert cam(8000, 8000).width == 8000 and cam(1, 64_000_000).height == 64_000_000  # exactly the limit
    for w, h in ((8000, 8001), (1, 64_000_001)):
        with pytest.raises(SceneError, match="too large"):
            cam(w, h)
