"""Chi-square goodness-of-fit tests of sampling routines against their densities, for any lobe shape.

For a sampler of directions with claimed solid-angle density p (a BSDF for one ω_i, or a warp):

1. **Bins from a pilot sample.** A pilot of max(N/4, 2000) directions drawn from the sampler itself on its
   *own* random stream (independent of the observed sample, so the bins cannot adapt to the data they
   test), mixed with 10 % uniform-sphere directions (so regions the sampler never visits still get bins),
   places the bins in spherical coordinates (θ, φ) about the normal: ``n_theta`` strips in θ at the pilot's
   θ quantiles, then in every strip ``n_phi`` bins at the quantiles of the pilot's φ inside that strip.
   Every bin holds about the same probability wherever the lobe is — one lobe, several lobes, a lobe at
   grazing angles, or a very sharp one (α = 10⁻³) — with no assumption about its axis or shape.
2. **Expected counts by integrating p**, never from the pilot: N·∫_bin p dω with dω = sin θ dθ dφ, by
   adaptive tensor Gauss–Legendre quadrature (4- vs 8-point rules; a cell is split 2×2 until the two agree
   within 10⁻³ expected counts or 10⁻⁴ relative, see :func:`integrate_rects`). Before refining, every bin is
   cut into cells no larger than π/24 × 2π/24, at the horizon θ = π/2, and geometrically near θ = 0, so no
   peak hides between the nodes of a wide bin. The summed |8-point − 4-point| differences are reported as
   the integration error.
3. **The failed samples are a category.** Samples with pdf 0 (failed) are counted in one extra bin whose
   expected count is N·(1 − ∫ p dω): the test checks ∫ p dω = the valid fraction as part of the same
   multinomial. ∫ p dω > 1 (beyond 10⁻³ + 3× the integration error) fails on its own.
4. Bins with expected count < 5 are pooled; Pearson's X² = Σ (O − E)²/E with k − 1 degrees of freedom;
   the p-value comes from ``scipy.stats.chi2``. A test with no valid sample or fewer than 4 degrees of
   freedom left fails as blind (a test that cannot fail is a defect).
5. Reject at significance 0.01, Šidák-corrected for the number m of tests: α_m = 1 − (1 − α)^(1/m).

Limitation: a peak of the *claimed* pdf narrower than about 0.5° in a region the sampler never visits can be
missed by the quadrature (then it is invisible to the test, as it is to every bin-based test).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from brdflab.errors import BrdflabError

SIGNIFICANCE = 0.01


@dataclass
class Chi2Result:
    """Outcome of one chi-square test.

    Attributes
    ----------
    name, params
        What was tested (sampler name; parameters such as α, θ, a plugin's parameters).
    statistic, dof, p_value
        Pearson's X², its degrees of freedom (after pooling) and the p-value.
    threshold
        Per-test significance (Šidák-corrected in a battery); the test passes when p > threshold.
    observed, expected
        Histograms (n_theta, n_phi): rows are θ strips about the normal, columns the φ bins of each strip
        (equal-probability bins from the pilot sample, see the module docstring). For point warps, a
        regular grid.
    theta_edges, phi_edges
        Bin edges: (n_theta + 1,) in θ and (n_theta, n_phi + 1) in φ per strip.
    integral, integration_error
        ∫ p dω over the sphere by adaptive quadrature, and its error estimate.
    valid_fraction
        Fraction of samples that did not fail (pdf > 0); must match ``integral``.
    seed, n
        The test's seed (its own stream) and the number of samples.
    fault
        Why the test failed regardless of the p-value (a plugin broke its contract, ∫ p > 1, a blind
        test), or None.
    message
        One-line verdict.
    """

    name: str
    params: dict
    statistic: float
    dof: int
    p_value: float
    threshold: float = SIGNIFICANCE
    observed: np.ndarray = field(default=None, repr=False)
    expected: np.ndarray = field(default=None, repr=False)
    theta_edges: np.ndarray = field(default=None, repr=False)
    integral: float = float("nan")
    valid_fraction: float = float("nan")
    phi_edges: np.ndarray = field(default=None, repr=False)
    seed: int | None = None
    n: int = 0
    integration_error: float = float("nan")
    fault: str | None = None
    message: str = ""

    @property
    def passed(self) -> bool:
        """True when there is no fault and the p-value is above the (corrected) threshold; never for a test
        without data (no samples, no degree of freedom, non-finite counts: see :func:`pearson`)."""
        return (self.fault is None and self.dof > 0 and bool(np.isfinite(self.p_value))
                and bool(self.p_value > self.threshold))

    def summary(self) -> str:
        """One line: verdict, p-value, X²/dof, ∫ p dω vs the valid fraction, and the fault if any."""
        head = f"{'PASS' if self.passed else 'FAIL'} chi2 {self.name}"
        if self.params:
            from brdflab.validate.guard import format_params

            head += f" ({format_params(self.params)})"
        body = (f": p = {self.p_value:.4g} (threshold {self.threshold:.2g}), X² = {self.statistic:.1f}, "
                f"dof {self.dof}, ∫p dω = {self.integral:.4f}, valid {self.valid_fraction:.4f}")
        return head + body + (f"; {self.fault}" if self.fault else "")


def faulted(name: str, params: dict, fault: str, seed: int | None = None, threshold: float = SIGNIFICANCE,
            n: int = 0) -> Chi2Result:
    """A failed :class:`Chi2Result` for a test that could not run (e.g. a plugin broke its contract)."""
    r = Chi2Result(name, dict(params), float("nan"), 0, 0.0, threshold, seed=seed, n=n, fault=fault)
    r.message = r.summary()
    return r


def sidak(alpha: float, m: int) -> float:
    """Per-test significance for m tests at family-wise level α (Šidák)."""
    return 1.0 - (1.0 - alpha) ** (1.0 / max(1, m))


def _frame(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a = axis / np.linalg.norm(axis)
    helper = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    s = np.cross(helper, a)
    s /= np.linalg.norm(s)
    return s, np.cross(a, s)


def to_angles(w: np.ndarray, axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Spherical angles (θ′, φ′ ∈ [0, 2π)) of directions about ``axis`` (for the normal: the usual θ, φ)."""
    if axis[0] == 0 and axis[1] == 0 and axis[2] > 0:
        return np.arccos(np.clip(w[:, 2], -1.0, 1.0)), np.mod(np.arctan2(w[:, 1], w[:, 0]), 2 * np.pi)
    s, t = _frame(axis)
    a = axis / np.linalg.norm(axis)
    z = np.clip(w @ a, -1.0, 1.0)
    theta = np.arccos(z)
    phi = np.mod(np.arctan2(w @ t, w @ s), 2 * np.pi)
    return theta, phi


def from_angles(theta: np.ndarray, phi: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Unit directions for angles about ``axis``."""
    st = np.sin(theta)
    if axis[0] == 0 and axis[1] == 0 and axis[2] > 0:  # the normal: no frame needed
        return np.stack([st * np.cos(phi), st * np.sin(phi), np.cos(theta)], axis=1)
    s, t = _frame(axis)
    a = axis / np.linalg.norm(axis)
    return np.outer(st * np.cos(phi), s) + np.outer(st * np.sin(phi), t) + np.outer(np.cos(theta), a)


def pilot_bins(theta: np.ndarray, phi: np.ndarray, n_theta: int, n_phi: int) -> tuple[np.ndarray, np.ndarray]:
    """Bin edges from pilot angles: θ strips at quantiles, then φ edges at quantiles inside each strip.

    Returns ``theta_edges`` (n_theta + 1,) from 0 to π and ``phi_edges`` (n_theta, n_phi + 1) from 0 to 2π,
    both non-decreasing (a repeated edge is an empty bin of zero width).
    """
    if len(theta) < 2 * n_theta:
        te = np.linspace(0.0, np.pi, n_theta + 1)
    else:
        te = np.quantile(theta, np.linspace(0, 1, n_theta + 1))
    te[0], te[-1] = 0.0, np.pi
    te = np.maximum.accumulate(np.clip(te, 0.0, np.pi))
    strip = np.clip(np.searchsorted(te, theta, side="right") - 1, 0, n_theta - 1)
    pe = np.empty((n_theta, n_phi + 1))
    for i in range(n_theta):
        ph = phi[strip == i]
        pe[i] = np.quantile(ph, np.linspace(0, 1, n_phi + 1)) if len(ph) >= 2 * n_phi \
            else np.linspace(0.0, 2 * np.pi, n_phi + 1)
    pe[:, 0], pe[:, -1] = 0.0, 2 * np.pi
    return te, np.maximum.accumulate(np.clip(pe, 0.0, 2 * np.pi), axis=1)


def theta_edges_from_pilot(theta: np.ndarray, n_theta: int) -> np.ndarray:
    """θ edges at the quantiles of pilot angles, covering [0, π] (see :func:`pilot_bins`)."""
    return pilot_bins(theta, np.zeros(len(theta)), n_theta, 1)[0]


def bin_counts(theta: np.ndarray, phi: np.ndarray, theta_edges: np.ndarray, phi_edges: np.ndarray) -> np.ndarray:
    """Histogram (n_theta, n_phi) of angles in the bins of :func:`pilot_bins`."""
    nt, nph = phi_edges.shape[0], phi_edges.shape[1] - 1
    i = np.clip(np.searchsorted(theta_edges, theta, side="right") - 1, 0, nt - 1)
    # One sorted key per bin: strip index · 10 + φ edge (φ < 2π < 10), so one searchsorted finds both.
    keys = (np.arange(nt)[:, None] * 10.0 + phi_edges[:, :-1]).ravel()
    flat = np.searchsorted(keys, i * 10.0 + np.clip(phi, 0.0, 2 * np.pi), side="right") - 1
    flat = np.clip(flat, i * nph, i * nph + nph - 1)
    return np.bincount(flat, minlength=nt * nph).reshape(nt, nph).astype(float)


def bin_rects(theta_edges: np.ndarray, phi_edges: np.ndarray) -> tuple[np.ndarray, ...]:
    """(θ_a, θ_b, φ_a, φ_b) of every bin, flattened in (strip, φ) order."""
    nph = phi_edges.shape[1] - 1
    ta = np.repeat(theta_edges[:-1], nph)
    tb = np.repeat(theta_edges[1:], nph)
    return ta, tb, phi_edges[:, :-1].ravel(), phi_edges[:, 1:].ravel()


def _gl_rects(func, xa, xb, ya, yb, order, chunk: int = 1 << 20):
    """Tensor Gauss–Legendre integral of ``func(x, y)`` over many rectangles at once (evaluated in chunks)."""
    g, w = np.polynomial.legendre.leggauss(order)
    hx, hy = 0.5 * (xb - xa), 0.5 * (yb - ya)
    ww = np.outer(w, w).ravel()
    out = np.empty(len(xa))
    step = max(1, chunk // (order * order))
    for s in range(0, len(xa), step):
        sl = slice(s, s + step)
        X = np.repeat(hx[sl, None] * g + (0.5 * (xa[sl] + xb[sl]))[:, None], order, axis=1)
        Y = np.tile(hy[sl, None] * g + (0.5 * (ya[sl] + yb[sl]))[:, None], (1, order))
        vals = np.asarray(func(X.ravel(), Y.ravel()), dtype=np.float64).reshape(X.shape)
        out[sl] = (vals * ww).sum(axis=1) * hx[sl] * hy[sl]
    return out


def _expand(counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For per-rectangle piece counts: the source index and the piece number of every piece."""
    src = np.repeat(np.arange(len(counts)), counts)
    return src, np.arange(len(src)) - np.repeat(np.cumsum(counts) - counts, counts)


def _split_cells(xa, xb, ya, yb, owner, max_dx=None, max_dy=None, x_cuts=(), geometric_x=False):
    """Cut rectangles so none straddles an ``x_cuts`` value, (with ``geometric_x``) none spans more than a
    factor 2 in x away from 0, and none is wider than ``max_dx``/``max_dy``. Vectorised; drops empty ones."""
    keep = (xb > xa) & (yb > ya)
    xa, xb, ya, yb, owner = (np.asarray(v)[keep] for v in (xa, xb, ya, yb, owner))
    for c in x_cuts:
        m = (xa < c) & (c < xb)
        xa, xb = np.concatenate([xa, np.full(m.sum(), c)]), np.concatenate([np.where(m, c, xb), xb[m]])
        ya, yb, owner = np.concatenate([ya, ya[m]]), np.concatenate([yb, yb[m]]), np.concatenate([owner, owner[m]])
    if geometric_x:
        ratio = np.where(xa > 0, xb / np.where(xa > 0, xa, 1.0), 1.0)
        k = np.where(ratio > 2, np.ceil(np.log2(np.maximum(ratio, 1.0))), 1).astype(int)
        i, j = _expand(k)
        a, b = xa[i] * ratio[i] ** (j / k[i]), xa[i] * ratio[i] ** ((j + 1) / k[i])
        xa, xb = np.where(j == 0, xa[i], a), np.where(j + 1 == k[i], xb[i], b)
        ya, yb, owner = ya[i], yb[i], owner[i]
    if max_dx or max_dy:
        kx = np.maximum(1, np.ceil((xb - xa) / max_dx)).astype(int) if max_dx else np.ones(len(xa), dtype=int)
        ky = np.maximum(1, np.ceil((yb - ya) / max_dy)).astype(int) if max_dy else np.ones(len(xa), dtype=int)
        i, j = _expand(kx * ky)
        jx, jy = j // ky[i], j % ky[i]
        wx, wy = (xb - xa)[i] / kx[i], (yb - ya)[i] / ky[i]
        xa, xb = xa[i] + jx * wx, np.where(jx + 1 == kx[i], xb[i], xa[i] + (jx + 1) * wx)
        ya, yb = ya[i] + jy * wy, np.where(jy + 1 == ky[i], yb[i], ya[i] + (jy + 1) * wy)
        owner = owner[i]
    return xa, xb, ya, yb, owner


def integrate_rects(func, xa, xb, ya, yb, owner, n_owner: int, n: int = 1, max_depth: int | None = None,
                    max_cells: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Adaptive ∫∫ func(x, y) dx dy over rectangles, summed per ``owner``; returns (integrals, error estimates).

    Each rectangle is integrated with 4- and 8-point tensor Gauss–Legendre rules; where they differ by more
    than 10⁻³ expected counts (for ``n`` samples) and 10⁻⁴ relative, it is split 2×2 and retried, up to
    ``max_depth`` times (at most ``max_cells`` rectangles per level: beyond, the worst are refined and the
    rest accepted). The error estimate per owner is the sum of |8-point − 4-point| over its accepted
    rectangles (the 4-point rule's error: a conservative bound on the 8-point result's). ``max_depth`` and
    ``max_cells`` default to the effort in force (:mod:`brdflab.effort`: 10 and 60 000 at ``normal``).
    """
    from brdflab import effort

    budget = effort.current()
    max_depth = budget.max_depth if max_depth is None else max_depth
    max_cells = budget.max_cells if max_cells is None else max_cells
    total = np.zeros(n_owner)
    err = np.zeros(n_owner)
    for depth in range(max_depth + 1):
        if len(owner) == 0:
            break
        coarse = _gl_rects(func, xa, xb, ya, yb, 4)
        fine = _gl_rects(func, xa, xb, ya, yb, 8)
        diff = np.abs(fine - coarse)
        conv = (diff * n < 1e-3) | (diff <= 1e-4 * np.abs(fine))
        keep = ~conv & (depth < max_depth)
        if keep.sum() > max_cells // 4:  # refine the worst only
            worst = np.argsort(-diff * ~conv)[: max_cells // 4]
            keep = np.zeros_like(keep)
            keep[worst] = True
        done = ~keep
        total += np.bincount(owner[done], fine[done], minlength=n_owner)
        err += np.bincount(owner[done], diff[done], minlength=n_owner)
        xa, xb, ya, yb, owner = xa[keep], xb[keep], ya[keep], yb[keep], owner[keep]
        xm, ym = 0.5 * (xa + xb), 0.5 * (ya + yb)
        xa, xb = np.concatenate([xa, xa, xm, xm]), np.concatenate([xm, xm, xb, xb])
        ya, yb = np.concatenate([ya, ym, ya, ym]), np.concatenate([ym, yb, ym, yb])
        owner = np.tile(owner, 4)
    return total, err


def adaptive_integrate(func, x_edges: np.ndarray, y_edges: np.ndarray, n: int = 1,
                       max_depth: int | None = None, geometric_x: bool = False) -> np.ndarray:
    """∫∫ func(x, y) dx dy over every cell of the grid ``x_edges`` × ``y_edges`` (see :func:`integrate_rects`)."""
    nx, ny = len(x_edges) - 1, len(y_edges) - 1
    ix, iy = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    rects = _split_cells(x_edges[ix.ravel()], x_edges[ix.ravel() + 1], y_edges[iy.ravel()], y_edges[iy.ravel() + 1],
                         np.arange(nx * ny), geometric_x=geometric_x)
    return integrate_rects(func, *rects, nx * ny, n, max_depth)[0].reshape(nx, ny)


#: Largest integration cell before adaptive refinement (θ, φ), see the module docstring.
BASE_CELL = (np.pi / 24, 2 * np.pi / 24)


def sphere_integrand(func: Callable[[np.ndarray], np.ndarray], axis: np.ndarray | None = None):
    """g(θ, φ) = func(ω(θ, φ)) sin θ about ``axis`` (default the normal), for :func:`integrate_rects`."""
    axis = np.array([0.0, 0.0, 1.0]) if axis is None else axis

    def g(theta, phi):
        return np.asarray(func(from_angles(theta, phi, axis)), dtype=np.float64) * np.sin(theta)

    return g


def _graded_cuts(a: float, b: float, h_left: float, h_right: float, max_w: float, cuts=(),
                 geometric_from_zero: bool = False) -> list[float]:
    """Cuts of [a, b]: graded from each end, starting at the neighbouring bin's width and doubling.

    Equal-probability bins are narrow where the pdf is large, so the mass of a wide bin next to a narrow
    one sits against their shared edge: the graded cuts put small cells there (no peak can hide between
    the Gauss nodes of a wide cell). Then no piece is left wider than ``max_w``.
    """
    a, b, h_left, h_right = float(a), float(b), float(h_left), float(h_right)
    out = {a, b, *(c for c in cuts if a < c < b)}
    w = b - a
    for h0, sign, start in ((h_left, 1.0, a), (h_right, -1.0, b)):
        if 0 < h0 < w / 4:
            h = h0
            while h < w / 2:
                out.add(start + sign * h)
                h *= 2.0
    if geometric_from_zero and a > 0 and b / a > 2:
        x = 2 * a
        while x < b:
            out.add(x)
            x *= 2.0
    pts = sorted(out)
    res = [pts[0]]
    for x0, x1 in zip(pts[:-1], pts[1:], strict=True):
        k = int(np.ceil((x1 - x0) / max_w))
        res.extend(x0 + (x1 - x0) * j / k for j in range(1, k))
        res.append(x1)
    return res


def _neighbour_widths(widths: np.ndarray, periodic: bool) -> tuple[np.ndarray, np.ndarray]:
    left = np.roll(widths, 1, axis=-1)
    right = np.roll(widths, -1, axis=-1)
    if not periodic:
        left[..., 0] = 0.0
        right[..., -1] = 0.0
    return left, right


def sphere_cells(theta_edges: np.ndarray, phi_edges: np.ndarray) -> tuple[np.ndarray, ...]:
    """Integration cells (θ_a, θ_b, φ_a, φ_b, owner bin) covering the bins of :func:`pilot_bins`.

    Every bin is cut at the horizon θ = π/2, geometrically away from θ = 0, graded towards narrower
    neighbouring bins (:func:`_graded_cuts`), and into pieces no larger than :data:`BASE_CELL`.
    """
    nt, nph = phi_edges.shape[0], phi_edges.shape[1] - 1
    tw = np.diff(theta_edges)
    tl, tr = _neighbour_widths(tw, periodic=False)
    pw = np.diff(phi_edges, axis=1)
    pl, pr = _neighbour_widths(pw, periodic=True)
    xs = [_graded_cuts(theta_edges[i], theta_edges[i + 1], tl[i], tr[i], BASE_CELL[0], (np.pi / 2,), True)
          if tw[i] > 0 else [] for i in range(nt)]
    xa, xb, ya, yb, ow = [], [], [], [], []
    for i in range(nt):
        x = xs[i]
        for j in range(nph):
            if len(x) < 2 or pw[i, j] <= 0:
                continue
            y = _graded_cuts(phi_edges[i, j], phi_edges[i, j + 1], pl[i, j], pr[i, j], BASE_CELL[1])
            for x0, x1 in zip(x[:-1], x[1:], strict=True):
                xa += [x0] * (len(y) - 1)
                xb += [x1] * (len(y) - 1)
                ya += y[:-1]
                yb += y[1:]
            ow += [i * nph + j] * ((len(x) - 1) * (len(y) - 1))
    return np.array(xa), np.array(xb), np.array(ya), np.array(yb), np.array(ow, dtype=np.int64)


def integrate_sphere_bins(func: Callable[[np.ndarray], np.ndarray], theta_edges: np.ndarray, phi_edges: np.ndarray,
                          n: int = 1, axis: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """∫ func dω over each bin of :func:`pilot_bins` (and its error estimate), both (n_theta, n_phi)."""
    nb = phi_edges.shape[0] * (phi_edges.shape[1] - 1)
    val, err = integrate_rects(sphere_integrand(func, axis), *sphere_cells(theta_edges, phi_edges), nb, n)
    shape = (phi_edges.shape[0], phi_edges.shape[1] - 1)
    return val.reshape(shape), err.reshape(shape)


def integrate_bins(pdf: Callable[[np.ndarray], np.ndarray], axis: np.ndarray, theta_edges: np.ndarray,
                   n_phi: int, n: int = 1) -> np.ndarray:
    """∫ p dω over each (θ′, φ′) bin of a regular φ′ grid about ``axis`` (dω = sin θ′ dθ′ dφ′), adaptively."""
    pe = np.tile(np.linspace(0, 2 * np.pi, n_phi + 1), (len(theta_edges) - 1, 1))
    return integrate_sphere_bins(pdf, theta_edges, pe, n, axis)[0]


def bin_shape(n: int) -> tuple[int, int]:
    """(n_theta, n_phi) for n samples: 20 × 40 from 20 000 samples, fewer bins (≥ 25 expected each) below."""
    k = int(np.clip(n // 25, 8, 800))
    nt = max(2, int(round(np.sqrt(k / 2))))
    return nt, max(4, k // nt)


def pearson(observed: np.ndarray, expected: np.ndarray) -> tuple[float, int, float]:
    """Pearson's X² after pooling bins with expected count < 5; returns (X², dof, p-value)."""
    obs, exp = observed.ravel(), expected.ravel()
    if not (np.all(np.isfinite(obs)) and np.all(np.isfinite(exp))) or obs.sum() == 0 or exp.sum() <= 0:
        # No samples, or a pdf that is not finite: there is nothing to test; this must never read as a pass.
        return float("nan"), 0, float("nan")
    small = exp < 5
    o = np.append(obs[~small], obs[small].sum())
    e = np.append(exp[~small], exp[small].sum())
    if e[-1] < 5 and len(e) > 1:  # the pooled bin is itself too small: merge it into the last regular bin
        o[-2] += o[-1]
        e[-2] += e[-1]
        o, e = o[:-1], e[:-1]
    with np.errstate(divide="ignore", invalid="ignore"):
        terms = np.where(e > 0, (o - e) ** 2 / e, np.where(o > 0, np.inf, 0.0))
    stat = float(terms.sum())
    dof = len(o) - 1
    if dof < 1:  # everything pooled into one bin: no degree of freedom, no test
        return stat, 0, float("nan")
    from scipy import stats  # here, not at the top: scipy.stats costs ~1 s of start-up for every command

    return stat, dof, (float(stats.chi2.sf(stat, dof)) if np.isfinite(stat) else 0.0)


def directions_test(name: str, wo: np.ndarray, n_total: int, pdf: Callable[[np.ndarray], np.ndarray],
                    pilot: np.ndarray, *, seed: int | None = None, params: dict | None = None,
                    threshold: float = SIGNIFICANCE, shape: tuple[int, int] | None = None,
                    mix_rng: np.random.Generator | None = None) -> Chi2Result:
    """Chi-square test of observed directions against a density, with bins from an independent pilot.

    Parameters
    ----------
    wo
        (k, 3) valid observed directions (the other ``n_total − k`` samples failed).
    n_total
        Number of samples drawn, failed ones included.
    pdf
        Claimed solid-angle density, (M, 3) → (M,).
    pilot
        (m, 3) directions from the same sampler but an independent stream (or from a reference sampler);
        they place the bins only.
    shape
        (n_theta, n_phi); default :func:`bin_shape` of ``n_total``.
    mix_rng
        Stream of the 10 % uniform directions mixed into the pilot.
    """
    nt, nph = shape or bin_shape(n_total)
    mix_rng = mix_rng or np.random.default_rng(seed)
    from brdflab.math.warps import square_to_uniform_sphere

    extra = square_to_uniform_sphere(mix_rng.random((max(len(pilot) // 9, 200), 2)))
    z = np.array([0.0, 0.0, 1.0])
    pt, pp = to_angles(np.concatenate([np.asarray(pilot, dtype=float).reshape(-1, 3), extra]), z)
    te, pe = pilot_bins(pt, pp, nt, nph)
    th, ph = to_angles(np.asarray(wo, dtype=float).reshape(-1, 3), z)
    obs = bin_counts(th, ph, te, pe)
    mass, merr = integrate_sphere_bins(pdf, te, pe, n_total)
    integral, ierr = float(mass.sum()), float(merr.sum())
    valid = len(wo) / max(n_total, 1)
    fail_exp = max(n_total * (1.0 - integral), 0.0)
    stat, dof, pval = pearson(np.append(obs.ravel(), n_total - len(wo)), np.append(mass.ravel() * n_total, fail_exp))
    fault = None
    if len(wo) == 0:
        fault = "no valid sample (every sample failed): nothing to test"
    elif integral > 1 + 1e-3 + 3 * ierr:
        fault = f"∫ p dω = {integral:.5f} > 1 (the claimed pdf has more than unit mass)"
    elif dof < 4:
        fault = f"only {dof + 1} populated bins: the test would be blind"
    res = Chi2Result(name, dict(params or {}), stat, dof, pval, threshold, obs, mass * n_total, te,
                     integral=integral, valid_fraction=valid, phi_edges=pe, seed=seed, n=n_total,
                     integration_error=ierr, fault=fault)
    res.message = res.summary()
    return res


def sampler_test(name: str, sample: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
                 pdf: Callable[[np.ndarray], np.ndarray], n: int = 200_000, seed: int = 0,
                 params: dict | None = None, threshold: float = SIGNIFICANCE, uniforms: int = 3,
                 shape: tuple[int, int] | None = None) -> Chi2Result:
    """Chi-square test of ``sample`` (uniforms (N, ``uniforms``) → (directions, pdf); pdf 0 = failed) vs ``pdf``.

    Three independent streams spawned from ``seed``: the pilot (bins), the observed sample, the uniform mix.
    """
    if n < 1:
        raise BrdflabError(f"a chi-square test needs at least 1 sample, got {n}")
    s_pilot, s_obs, s_mix = np.random.SeedSequence(seed).spawn(3)
    pw, pp = sample(np.random.default_rng(s_pilot).random((max(n // 4, 2000), uniforms)))
    w, p = sample(np.random.default_rng(s_obs).random((n, uniforms)))
    return directions_test(name, w[p > 0], n, pdf, pw[pp > 0], seed=seed, params=params, threshold=threshold,
                           shape=shape, mix_rng=np.random.default_rng(s_mix))


def chi2_test(
    name: str,
    sample: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
    pdf: Callable[[np.ndarray], np.ndarray],
    axis: np.ndarray | None = None,
    n: int = 200_000,
    n_theta: int = 20,
    n_phi: int = 40,
    seed: int = 0,
    params: dict | None = None,
    threshold: float = SIGNIFICANCE,
    uniforms: int = 3,
) -> Chi2Result:
    """Low-level chi-square test of a sampler (kept for callers of the old signature; ``axis`` is unused).

    The BSDF-level function with keyword parameters is :func:`brdflab.validate.chi2_test`.
    """
    return sampler_test(name, sample, pdf, n, seed, params, threshold, uniforms, shape=(n_theta, n_phi))


# -- adapters for BSDFs and warps ----------------------------------------------------------------------
def incident(theta_deg: float) -> np.ndarray:
    """Unit incident direction at ``theta_deg`` from the normal, in the x–z plane."""
    t = np.radians(theta_deg)
    return np.array([np.sin(t), 0.0, np.cos(t)])


def bsdf_test(name: str, bsdf, theta_deg: float, n: int, seed: int = 0, params: dict | None = None,
              threshold: float = SIGNIFICANCE, axis: np.ndarray | None = None) -> Chi2Result:
    """Chi-square test of ``bsdf.sample`` against ``bsdf.pdf`` for incident angle ``theta_deg``.

    The BSDF is called through :class:`~brdflab.validate.guard.CheckedBSDF`: a contract violation gives a
    failed result naming the method, the parameters and the first offending directions. ``axis`` is unused
    (the bins adapt to the lobe, see the module docstring).
    """
    from brdflab.validate.guard import CheckedBSDF, PluginFault

    params = dict(params or {})
    checked_bsdf = CheckedBSDF(bsdf, name, {k: v for k, v in params.items() if k != "theta"})
    wi1 = incident(theta_deg)

    def sample(u):
        wi = np.ascontiguousarray(np.broadcast_to(wi1, (len(u), 3)))
        r = checked_bsdf.sample(wi, u)
        return r.wo, r.pdf

    def pdf(w):
        return checked_bsdf.pdf(np.ascontiguousarray(np.broadcast_to(wi1, (len(w), 3))), w)

    try:
        return sampler_test(name, sample, pdf, n=n, seed=seed, params=params, threshold=threshold)
    except PluginFault as fault:
        return faulted(name, params, str(fault), seed, threshold, n)


def warp_test(name: str, warp: Callable, warp_pdf: Callable, n: int, seed: int = 0, params: dict | None = None,
              threshold: float = SIGNIFICANCE, axis: np.ndarray | None = None) -> Chi2Result:
    """Chi-square test of a direction warp against its pdf (``axis`` is unused)."""

    def sample(u):
        w = warp(u[:, :2])
        return w, warp_pdf(w)

    return sampler_test(name, sample, warp_pdf, n=n, seed=seed, params=params, threshold=threshold)


def point_warp_test(name: str, warp: Callable, warp_pdf: Callable, bounds: tuple[float, float, float, float],
                    n: int, bins: int = 20, seed: int = 0, params: dict | None = None,
                    threshold: float = SIGNIFICANCE) -> Chi2Result:
    """Chi-square test of a warp to 2-D points (disk, triangle) on a ``bins``² grid over ``bounds``."""
    rng = np.random.default_rng(seed)
    pts = warp(rng.random((n, 2)))
    x0, x1, y0, y1 = bounds
    xe, ye = np.linspace(x0, x1, bins + 1), np.linspace(y0, y1, bins + 1)
    obs, _, _ = np.histogram2d(pts[:, 0], pts[:, 1], bins=[xe, ye])
    expected = adaptive_integrate(lambda x, y: warp_pdf(np.stack([x, y], axis=1)), xe, ye, n) * n
    stat, dof, pval = pearson(obs, expected)
    r = Chi2Result(name, params or {}, stat, dof, pval, threshold, obs, expected, xe,
                   integral=float(expected.sum() / n), valid_fraction=1.0, seed=seed, n=n)
    r.message = r.summary()
    return r
