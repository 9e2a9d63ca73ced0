"""Chi-square goodness-of-fit tests of sampling routines against their densities.

For a sampler of directions with claimed solid-angle density p:

1. Draw N directions (plus a pilot sample of N/4 used only to place the bins).
2. Bin them on the whole sphere in spherical coordinates (θ′, φ′) about the lobe's axis (the mirror
   direction for microfacet lobes, the normal for diffuse lobes and warps): ``n_theta`` bins in θ′
   whose edges are quantiles of the pilot sample (so very peaked lobes, α = 10⁻³, still get many
   populated bins) and ``n_phi`` uniform bins in φ′.
3. Integrate p over every bin with adaptive tensor Gauss–Legendre rules in (θ′, φ′)
   (dω = sin θ′ dθ′ dφ′) to get the expected counts N·∫_bin p dω.
4. Pool the bins with expected count < 5 into one, and compute Pearson's statistic
   X² = Σ (O − E)²/E with k − 1 degrees of freedom; the p-value comes from ``scipy.stats.chi2``.
5. Reject at significance α = 0.01 after a Šidák correction for the number of tests m:
   α_m = 1 − (1 − α)^(1/m).

Samples reported as failed (pdf 0) are not counted; their probability is the mass ∫ p dω is missing.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from brdflab.errors import BrdflabError

SIGNIFICANCE = 0.01


@dataclass
class Chi2Result:
    """Outcome of one chi-square test."""

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

    @property
    def passed(self) -> bool:
        """True when the p-value is above the (corrected) threshold; never for a test without data (no
        samples, no degree of freedom, non-finite counts: see :func:`pearson`)."""
        return bool(self.dof > 0 and np.isfinite(self.p_value) and self.p_value > self.threshold)


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
    """Spherical angles (θ′, φ′ ∈ [0, 2π)) of directions about ``axis``."""
    s, t = _frame(axis)
    a = axis / np.linalg.norm(axis)
    z = np.clip(w @ a, -1.0, 1.0)
    theta = np.arccos(z)
    phi = np.mod(np.arctan2(w @ t, w @ s), 2 * np.pi)
    return theta, phi


def from_angles(theta: np.ndarray, phi: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Unit directions for angles about ``axis``."""
    s, t = _frame(axis)
    a = axis / np.linalg.norm(axis)
    st = np.sin(theta)
    return (st * np.cos(phi))[:, None] * s + (st * np.sin(phi))[:, None] * t + np.cos(theta)[:, None] * a


def theta_edges_from_pilot(theta: np.ndarray, n_theta: int) -> np.ndarray:
    """Bin edges in θ′: quantiles of the pilot angles, widened to cover [0, π] and made strictly increasing."""
    if len(theta) == 0:
        return np.linspace(0, np.pi, n_theta + 1)
    q = np.quantile(theta, np.linspace(0, 1, n_theta + 1))
    q[0], q[-1] = 0.0, np.pi
    # Spread the outermost populated edge a little and keep edges strictly increasing.
    q = np.maximum.accumulate(q)
    for i in range(1, len(q)):
        if q[i] <= q[i - 1] + 1e-9:
            q[i] = q[i - 1] + 1e-9
    q[-1] = max(q[-1], np.pi)
    if q[-2] >= np.pi:
        q = np.linspace(0, np.pi, n_theta + 1)
    return q


def _gl_rects(func, xa, xb, ya, yb, order):
    """Tensor Gauss–Legendre integral of ``func(x, y)`` over many rectangles at once."""
    g, w = np.polynomial.legendre.leggauss(order)
    hx, hy = 0.5 * (xb - xa), 0.5 * (yb - ya)
    X = np.repeat(hx[:, None] * g + (0.5 * (xa + xb))[:, None], order, axis=1)
    Y = np.tile(hy[:, None] * g + (0.5 * (ya + yb))[:, None], (1, order))
    vals = func(X.ravel(), Y.ravel()).reshape(X.shape)
    return (vals * np.outer(w, w).ravel()).sum(axis=1) * hx * hy


def adaptive_integrate(func, x_edges: np.ndarray, y_edges: np.ndarray, n: int = 1,
                       max_depth: int = 10, geometric_x: bool = False) -> np.ndarray:
    """∫∫ func(x, y) dx dy over every cell of the grid ``x_edges`` × ``y_edges``, adaptively.

    Each rectangle is integrated with 4- and 8-point tensor Gauss–Legendre rules; where they differ by
    more than 10⁻³ expected counts (for ``n`` samples) and 10⁻⁴ relative, it is split 2×2 and retried,
    up to ``max_depth`` times. With ``geometric_x``, cells wider than a factor 2 in x are first split
    geometrically, so that no narrow peak can hide between the nodes of a wide cell (false convergence).
    """
    nx, ny = len(x_edges) - 1, len(y_edges) - 1
    xa_l, xb_l, own_l = [], [], []
    for i in range(nx):
        a, b = x_edges[i], x_edges[i + 1]
        k = int(np.ceil(np.log2(b / a))) if geometric_x and a > 0 and b / a > 2 else 1
        cuts = np.geomspace(a, b, k + 1) if k > 1 else np.array([a, b])
        xa_l.append(cuts[:-1])
        xb_l.append(cuts[1:])
        own_l.append(np.full(len(cuts) - 1, i))
    xa0, xb0, ox = np.concatenate(xa_l), np.concatenate(xb_l), np.concatenate(own_l)
    ix, iy = np.meshgrid(np.arange(len(xa0)), np.arange(ny), indexing="ij")
    xa, xb = xa0[ix.ravel()], xb0[ix.ravel()]
    ya, yb = y_edges[iy.ravel()], y_edges[iy.ravel() + 1]
    owner = ox[ix.ravel()] * ny + iy.ravel()
    total = np.zeros(nx * ny)
    for depth in range(max_depth + 1):
        if len(owner) == 0:
            break
        coarse = _gl_rects(func, xa, xb, ya, yb, 4)
        fine = _gl_rects(func, xa, xb, ya, yb, 8)
        err = np.abs(fine - coarse)
        done = (err * n < 1e-3) | (err <= 1e-4 * np.abs(fine)) | (depth == max_depth)
        total += np.bincount(owner[done], fine[done], minlength=len(total))
        keep = ~done
        xa, xb, ya, yb, owner = xa[keep], xb[keep], ya[keep], yb[keep], owner[keep]
        xm, ym = 0.5 * (xa + xb), 0.5 * (ya + yb)
        xa, xb = np.concatenate([xa, xa, xm, xm]), np.concatenate([xm, xm, xb, xb])
        ya, yb = np.concatenate([ya, ym, ya, ym]), np.concatenate([ym, yb, ym, yb])
        owner = np.tile(owner, 4)
    return total.reshape(nx, ny)


def integrate_bins(pdf: Callable[[np.ndarray], np.ndarray], axis: np.ndarray, theta_edges: np.ndarray,
                   n_phi: int, n: int = 1) -> np.ndarray:
    """∫ p dω over each (θ′, φ′) bin about ``axis`` (dω = sin θ′ dθ′ dφ′), adaptively."""
    def func(theta, phi):
        return pdf(from_angles(theta, phi, axis)) * np.sin(theta)

    return adaptive_integrate(func, theta_edges, np.linspace(0, 2 * np.pi, n_phi + 1), n, geometric_x=True)


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


def chi2_test(
    name: str,
    sample: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
    pdf: Callable[[np.ndarray], np.ndarray],
    axis: np.ndarray,
    n: int = 200_000,
    n_theta: int = 20,
    n_phi: int = 40,
    seed: int = 0,
    params: dict | None = None,
    threshold: float = SIGNIFICANCE,
    uniforms: int = 3,
) -> Chi2Result:
    """Run one chi-square test.

    Parameters
    ----------
    sample
        Maps uniforms (N, ``uniforms``) to (directions (N, 3), pdf (N,)); pdf 0 marks a failed sample.
    pdf
        The claimed density of directions (N, 3) → (N,).
    axis
        Axis for the binning (lobe centre).
    """
    if n < 1:
        raise BrdflabError(f"a chi-square test needs at least 1 sample, got {n}")
    rng = np.random.default_rng(seed)
    pilot_w, pilot_p = sample(rng.random((max(n // 4, 1000), uniforms)))
    pt, _ = to_angles(pilot_w[pilot_p > 0], axis)
    edges = theta_edges_from_pilot(pt, n_theta)
    w, p = sample(rng.random((n, uniforms)))
    ok = p > 0
    th, ph = to_angles(w[ok], axis)
    obs, _, _ = np.histogram2d(th, ph, bins=[edges, np.linspace(0, 2 * np.pi, n_phi + 1)])
    expected = integrate_bins(pdf, axis, edges, n_phi, n) * n
    stat, dof, pval = pearson(obs, expected)
    return Chi2Result(name, params or {}, stat, dof, pval, threshold, obs, expected, edges,
                      integral=float(expected.sum() / n), valid_fraction=float(ok.mean()))


# -- adapters for BSDFs and warps ----------------------------------------------------------------------
def incident(theta_deg: float) -> np.ndarray:
    """Unit incident direction at ``theta_deg`` from the normal, in the x–z plane."""
    t = np.radians(theta_deg)
    return np.array([np.sin(t), 0.0, np.cos(t)])


def bsdf_test(name: str, bsdf, theta_deg: float, n: int, seed: int = 0, params: dict | None = None,
              threshold: float = SIGNIFICANCE, axis: np.ndarray | None = None) -> Chi2Result:
    """Chi-square test of ``bsdf.sample`` against ``bsdf.pdf`` for incident angle ``theta_deg``."""
    wi1 = incident(theta_deg)
    if axis is None:
        axis = np.array([-wi1[0], -wi1[1], wi1[2]])  # mirror direction: the microfacet lobe's centre

    def sample(u):
        wi = np.broadcast_to(wi1, (len(u), 3))
        r = bsdf.sample(np.ascontiguousarray(wi), u)
        return r.wo, r.pdf

    def pdf(w):
        return bsdf.pdf(np.ascontiguousarray(np.broadcast_to(wi1, (len(w), 3))), w)

    return chi2_test(name, sample, pdf, axis, n=n, seed=seed, params=params, threshold=threshold)


def warp_test(name: str, warp: Callable, warp_pdf: Callable, n: int, seed: int = 0, params: dict | None = None,
              threshold: float = SIGNIFICANCE, axis: np.ndarray | None = None) -> Chi2Result:
    """Chi-square test of a direction warp against its pdf."""
    axis = np.array([0.0, 0.0, 1.0]) if axis is None else axis

    def sample(u):
        w = warp(u[:, :2])
        return w, warp_pdf(w)

    return chi2_test(name, sample, warp_pdf, axis, n=n, seed=seed, params=params, threshold=threshold)


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
    return Chi2Result(name, params or {}, stat, dof, pval, threshold, obs, expected, xe,
                      integral=float(expected.sum() / n), valid_fraction=1.0)
