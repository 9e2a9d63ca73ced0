"""The compiled engine's glue kernels — the integrators' scatters into the camera samples' radiance
(``set_rows``, ``accumulate``), the light chooser's CDF inversion and the shading points' material index —
give the NumPy code's values to the bit, with negative controls."""

from __future__ import annotations

import numpy as np
import pytest

from brdflab import kernels
from brdflab.emitter.area import DiscreteChooser, invert_cdf
from brdflab.integrator import common
from tests.conftest import ROOT


def _rows(rng, n=5000, m=3000):
    idx = np.sort(rng.choice(n, m, replace=False)).astype(np.int64)
    vals = [np.asfortranarray(rng.normal(size=(m, 3)) * rng.choice([1e-150, 1e-3, 1.0, 1e150], size=(m, 1)))
            for _ in range(2)]
    L = np.asfortranarray(rng.random((n, 3)))
    return L, idx, vals


@pytest.mark.parametrize("scaled", [False, True])
def test_accumulate_and_set_rows_kernels_are_bit_identical(scaled):
    rng = np.random.default_rng(41)
    L, idx, (a, b) = _rows(rng)
    scale = rng.random(len(idx)) * 3 if scaled else None
    out = {}
    for eng in kernels.ENGINES:
        with kernels.use_engine(eng):
            acc, put = L.copy(order="F"), L.copy(order="F")
            common.accumulate(acc, idx, a, b, scale)
            common.set_rows(put, idx, a)
            out[eng] = acc, put
    for x, y in zip(out["numpy"], out["numba"], strict=True):
        np.testing.assert_array_equal(x, y)
    untouched = np.setdiff1d(np.arange(len(L)), idx)
    np.testing.assert_array_equal(out["numba"][0][untouched], L[untouched])
    np.testing.assert_array_equal(out["numba"][1][idx], a)
    # Negative controls: the products rounded in another order, a·(b·s), or one input one ulp off, must show.
    other = L.copy(order="F")
    k = kernels.load("direct")
    if scaled:
        k.accumulate(other, idx, a, np.asfortranarray(b * scale[:, None]), np.ones(len(idx)), True)
    else:
        b1 = b.copy(order="F")
        r = np.argmax(np.abs(a[:, 1] * b[:, 1]))  # a row where the product outweighs L
        b1[r, 1] = np.nextafter(b1[r, 1], np.inf)
        k.accumulate(other, idx, a, b1, np.zeros(0), False)
    assert not np.array_equal(other, out["numpy"][0])


def test_short_cdf_choice_kernel_is_bit_identical():
    """Counting CDF entries ≤ u in one pass gives invert_cdf's indices, at the CDF's own values, 0, the
    largest float below 1, and for weights with zeros (an outcome that must never be chosen)."""
    rng = np.random.default_rng(42)
    for weights in ([1.0], [3.0, 1.0], [0.5, 0.0, 2.0, 1e-12, 4.0, 0.0, 1.0, 7.0]):
        ch = DiscreteChooser(np.array(weights))
        assert ch.alias is None
        u = np.concatenate([rng.random(20000), ch.cdf, np.nextafter(ch.cdf, 0), [0.0, np.nextafter(1.0, 0)]])
        with kernels.use_engine("numba"):
            got = ch.sample(u)
        np.testing.assert_array_equal(got, invert_cdf(ch.cdf, u))
        assert np.all(np.asarray(weights)[got] > 0)
        if len(weights) > 1:  # negative control: a binary search with side="right" on the whole CDF is not it
            assert not np.array_equal(np.searchsorted(ch.cdf, u, side="left"), got)
    big = DiscreteChooser(np.arange(1.0, 20.0))  # an alias table: the NumPy path in both engines
    with kernels.use_engine("numba"):
        np.testing.assert_array_equal(big.sample(u[:100]), big.alias.sample(u[:100]))


def test_shading_points_carry_the_material_within_its_family():
    """A scene whose family has members with different constants: the compiled shading points' member index
    is the NumPy path's (mesh → member) at every point, and not all equal."""
    from brdflab.api import load_scene

    sc = load_scene(ROOT / "scenes/veach/veach_mis.xml", width=64, height=48)
    tab = common.scene_tables(sc)
    assert tab.bsdf_families.any_tables and tab.tri_member is not None
    rng = np.random.default_rng(43)
    o, d, tmax = sc.camera.generate_rays(rng.random(20000) * 64, rng.random(20000) * 48)
    got = {}
    for eng in kernels.ENGINES:
        with kernels.use_engine(eng):
            got[eng] = common.trace_camera(sc, o, d, tmax)[1].member
    np.testing.assert_array_equal(got["numba"], got["numpy"])
    assert len(np.unique(got["numba"])) > 1


@pytest.mark.parametrize("m", [0, 1, 777, 65536])
def test_output_columns_are_staggered_and_disjoint(m):
    """kernels.buffers.columns: every column contiguous, starting at its own offset modulo 4 KiB (192 bytes
    apart), and no two arrays share memory (each keeps the values written to it)."""
    from brdflab.kernels.buffers import PAGE, STEP, columns

    arrs = columns(m, [3, 3, None, 2, None])
    assert [a.shape for a in arrs] == [(m, 3), (m, 3), (m,), (m, 2), (m,)]
    cols = [a[:, j] if a.ndim == 2 else a for a in arrs for j in range(a.shape[1] if a.ndim == 2 else 1)]
    starts = [c.__array_interface__["data"][0] for c in cols]
    assert [s % PAGE for s in starts] == [(STEP * q) % PAGE for q in range(len(cols))]
    assert all(c.strides == (8,) for c in cols)
    for q, c in enumerate(cols):
        c[:] = q
    for q, c in enumerate(cols):
        assert np.all(c == q)
    ints = columns(m, [None], np.int64)[0]
    assert ints.dtype == np.int64 and ints.shape == (m,)
