"""Quadrature for the statistical checks: adaptive tensor Gauss–Legendre integration over rectangles (cells split
where the 4- and 8-point rules disagree, budget from :mod:`brdflab.effort`), spherical cells about an axis graded
towards narrow neighbouring bins, and the integrals of a density over the chi-square bins, ∫ p dω and the albedo.
Used by :mod:`brdflab.judges.material.chi2` (expected counts), the consistency and furnace checks and the plots.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np


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
    neighbouring bins (:func:`_graded_cuts`), and into pieces no larger than :data:`BASE_CELL`. Bins below the
    horizon are also cut at the φ edges of the last strip above it: a lobe that crosses the horizon (a
    reflection at grazing incidence, much more so with visible-normal sampling) continues below it at the same
    φ, where the pilot placed narrow bins above, while the few samples below leave wide bins whose Gauss nodes
    can all miss it (GGX, α = 10⁻³, θ_i = 89°: 0.06 % of the mass, 60 samples in 10⁵, expected 0).
    """
    nt, nph = phi_edges.shape[0], phi_edges.shape[1] - 1
    tw = np.diff(theta_edges)
    tl, tr = _neighbour_widths(tw, periodic=False)
    pw = np.diff(phi_edges, axis=1)
    pl, pr = _neighbour_widths(pw, periodic=True)
    xs = [_graded_cuts(theta_edges[i], theta_edges[i + 1], tl[i], tr[i], BASE_CELL[0], (np.pi / 2,), True)
          if tw[i] > 0 else [] for i in range(nt)]
    above = [i for i in range(nt) if theta_edges[i + 1] <= np.pi / 2 and tw[i] > 0]
    lobe_cuts = tuple(phi_edges[above[-1], 1:-1]) if above else ()
    xa, xb, ya, yb, ow = [], [], [], [], []
    for i in range(nt):
        x = xs[i]
        cuts = lobe_cuts if theta_edges[i] >= np.pi / 2 else ()
        for j in range(nph):
            if len(x) < 2 or pw[i, j] <= 0:
                continue
            y = _graded_cuts(phi_edges[i, j], phi_edges[i, j + 1], pl[i, j], pr[i, j], BASE_CELL[1], cuts)
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


def integrate_bins_finely(func: Callable[[np.ndarray], np.ndarray], theta_edges: np.ndarray, phi_edges: np.ndarray,
                          bins: np.ndarray, n: int = 1, k: int = 48, axis: np.ndarray | None = None) -> np.ndarray:
    """∫ func dω over the bins ``bins`` ((m, 2) strip and bin indices), each first cut into a k × k grid.

    For bins that the pilot sample says hold mass where the regular cells found none: a lobe far thinner
    than a bin (a streak of an anisotropic microfacet lobe, α_u/α_v = 250) can pass between all the Gauss nodes
    of :func:`sphere_cells`; a fine grid puts nodes across it before the adaptive refinement.
    """
    xa, xb, ya, yb, ow = [], [], [], [], []
    g = np.linspace(0.0, 1.0, k + 1)
    for m, (i, j) in enumerate(bins):
        t = theta_edges[i] + (theta_edges[i + 1] - theta_edges[i]) * g
        p = phi_edges[i, j] + (phi_edges[i, j + 1] - phi_edges[i, j]) * g
        tt, pp = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
        xa.append(t[tt.ravel()])
        xb.append(t[tt.ravel() + 1])
        ya.append(p[pp.ravel()])
        yb.append(p[pp.ravel() + 1])
        ow.append(np.full(k * k, m))
    if not xa:
        return np.zeros(0)
    return integrate_rects(sphere_integrand(func, axis), np.concatenate(xa), np.concatenate(xb), np.concatenate(ya),
                           np.concatenate(yb), np.concatenate(ow), len(bins), n)[0]


def integrate_bins(pdf: Callable[[np.ndarray], np.ndarray], axis: np.ndarray, theta_edges: np.ndarray,
                   n_phi: int, n: int = 1) -> np.ndarray:
    """∫ p dω over each (θ′, φ′) bin of a regular φ′ grid about ``axis`` (dω = sin θ′ dθ′ dφ′), adaptively."""
    pe = np.tile(np.linspace(0, 2 * np.pi, n_phi + 1), (len(theta_edges) - 1, 1))
    return integrate_sphere_bins(pdf, theta_edges, pe, n, axis)[0]
