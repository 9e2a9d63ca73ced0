"""The statistics of ``brdflab check`` (the method is derived in :mod:`brdflab.stats.render_check`): brdflab's side from
independent runs, the residual and single-render variance models, neighbour pooling, the window scan from additive
block sums, the t-tests with their rounding floor, and the painting of flagged regions at their finest size. No
I/O, no rendering: arrays in, arrays out.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy import stats
from scipy.ndimage import maximum_filter

from brdflab.stats import blocks as B
from brdflab.stats.intervals import welch_df

#: Relative rounding floor of a block's standard deviation (float32 accumulation of a few thousand samples).
ROUNDING = 1e-5


@dataclass
class Estimate:
    """A mean image with what is known about its noise.

    ``runs`` holds the individual runs (K, H, W, 3) when there are several; ``pixel_var`` the variance
    of each pixel of ``mean`` when it is given instead (a reference's variance image).
    """

    mean: np.ndarray
    runs: np.ndarray | None = None
    pixel_var: np.ndarray | None = None
    label: str = ""
    run_spp: int = 0
    """Samples per pixel of one run (for the variance model of a single user render)."""

    @classmethod
    def from_runs(cls, images: list[np.ndarray], label: str = "", run_spp: int = 0) -> Estimate:
        """Estimate from independent runs."""
        a = np.stack([np.asarray(i, dtype=np.float64) for i in images])
        return cls(a.mean(axis=0), a if len(images) >= 2 else None, None, label, run_spp)


def _with_mean_channel(a: np.ndarray) -> np.ndarray:
    """(…, 3) → (…, 4): R, G, B and their mean (the whole-image test's scalar)."""
    return np.concatenate([a, a.mean(axis=-1, keepdims=True)], axis=-1)


def _side_from_runs(runs: np.ndarray, valid: np.ndarray, block: int, info: dict | None = None):
    """Variance (and df) of the block means of the mean of ``runs`` (K, H, W, 4); image-mean variance."""
    k = runs.shape[0]
    e = runs - runs.mean(axis=0)
    e[:, ~valid] = 0.0
    cnt = B.block_sum(valid[..., None].astype(np.float64), block)  # (By, Bx, 1)
    s2 = B.block_sum((e * e).sum(axis=0), block) / (k - 1)  # Σ_p per-pixel variance of one run
    with np.errstate(invalid="ignore", divide="ignore"):
        sig = np.where(cnt > 0, s2 / np.maximum(cnt, 1), 0.0)
        z = e / np.sqrt(np.where(B.expand(sig, block, valid.shape) > 0, B.expand(sig, block, valid.shape), 1.0))
    rho = B.correlation(z, valid)
    if info is not None:
        info["rho"] = rho
    f = B.correlation_factor(rho, block, runs.shape[-1])
    f_inf = B.correlation_factor(rho, None, runs.shape[-1])
    var = f * s2 / np.maximum(cnt, 1) ** 2 / k
    df = B.kurtosis_df(e, valid, block, cnt * (k - 1) / f)
    n = valid.sum()
    mean_var = f_inf * s2.sum(axis=(0, 1)) / n**2 / k
    return var, df, mean_var, float(f[:3].mean())


def _residual(r: np.ndarray, valid: np.ndarray, block: int, y: np.ndarray | None = None,
              info: dict | None = None):
    """Variance (and df) of the block means of r = x̄ − ȳ from its within-block spread (one render).

    With ``y`` (brdflab's estimate) each block's least-squares slope of r on y is removed too, so that a
    bias proportional to the image inside a block (a wall 10 % too dark) does not pass for spread; this
    fit absorbs brdflab's own noise where the block is flat, so it is used only as a lower bound beside
    a variance that contains that noise (the single-render model).
    """
    r = np.where(valid[..., None], r, 0.0)
    cnt = B.block_sum(valid[..., None].astype(np.float64), block)
    n = np.maximum(cnt, 1)
    mean_b = B.block_sum(r, block) / n
    centred = r - B.expand(mean_b, block, valid.shape)
    centred[~valid] = 0.0
    fitted = 1.0
    if y is not None:
        yc = np.where(valid[..., None], y, 0.0)
        yc = yc - B.expand(B.block_sum(yc, block) / n, block, valid.shape)
        yc[~valid] = 0.0
        syy = B.block_sum(yc * yc, block)
        with np.errstate(invalid="ignore", divide="ignore"):
            beta = np.where(syy > 0, B.block_sum(centred * yc, block) / np.where(syy > 0, syy, 1.0), 0.0)
        centred = centred - B.expand(beta, block, valid.shape) * yc
        fitted = 2.0
    ss = B.block_sum(centred * centred, block)
    with np.errstate(invalid="ignore", divide="ignore"):
        sd = np.sqrt(B.expand(ss / n, block, valid.shape))
        z = np.where(sd > 0, centred / np.where(sd > 0, sd, 1.0), 0.0)[None]
    rho = B.correlation(z, valid)
    c = r.shape[-1]
    f = B.correlation_factor(rho, block, c, centred_in=block * block)
    if info is not None:
        info["rho"] = _uncentred(rho, f, block * block)
    f_inf = B.correlation_factor(rho, None, c, centred_in=block * block)
    sig = ss / np.maximum(n - fitted * f, 1.0)  # E Σ (r − r̄)² = (n − F) σ² (one more F per fitted slope)
    var = f * sig / n
    df = B.kurtosis_df(centred[None], valid, block, np.maximum(n / f - fitted, 1.0))
    mean_var = f_inf * (sig * cnt).sum(axis=(0, 1)) / valid.sum() ** 2
    return var, df, mean_var, float(f[:3].mean())


def _pool_neighbours(var: np.ndarray, refb: np.ndarray, cnt: np.ndarray) -> np.ndarray:
    """Variance of each block raised to the median relative variance of its 3 × 3 neighbourhood.

    One render cannot show the variance of a block where its rare large samples (a BSDF sample finding
    a small light) happened not to occur: there the spread of the residuals is only brdflab's. Such
    regions are larger than a block, so each block's variance is taken as at least
    median_{3×3}(Var/ȳ²) · ȳ_b² (conservative: it only widens intervals).
    """
    with np.errstate(invalid="ignore", divide="ignore"):
        rel = np.where((refb > 0) & (cnt > 0), var / (refb * refb), np.nan)
    by, bx, c = rel.shape
    pad = np.pad(rel, ((1, 1), (1, 1), (0, 0)), constant_values=np.nan)
    stack = np.stack([pad[i:i + by, j:j + bx] for i in range(3) for j in range(3)])
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN neighbourhoods (black regions)
        med = np.nanmedian(stack, axis=0)
    pooled = np.where(np.isfinite(med), med * refb * refb, 0.0)
    return np.maximum(var, pooled)


def _single_render_var(estimate: Estimate, r_var: np.ndarray, y4: np.ndarray, finite: np.ndarray, block: int,
                       cnt: np.ndarray, user_spp: int | None, info: dict | None = None):
    """Variance (and df) of the block differences D_b with one user render and brdflab's K runs.

    See the module docstring ("model"): brdflab's block variance scaled to the user's spp × η, plus
    brdflab's own, and at least the residual estimate (with per-block slope removed) of the difference.
    """
    k = estimate.runs.shape[0]
    info = {} if info is None else info
    info["runs"], info["res"] = {}, {}
    vy, dfy, mvy, fac_used = _side_from_runs(_with_mean_channel(estimate.runs), finite, block, info["runs"])
    vres, dfr, mvr, _ = _residual(r_var, finite, block, y4, info["res"])
    scale = k * (estimate.run_spp / user_spp if user_spp and estimate.run_spp else 1.0)
    model = vy * scale
    ok = (model[..., :3] > 0) & (cnt > 0)
    ratio = vres[..., :3][ok] / (model[..., :3][ok] + vy[..., :3][ok])
    eta = max(1.0, float(np.median(ratio))) if ratio.size else 1.0
    vx = eta * model
    vm, dfm = vx + vy, welch_df([vx, vy], [dfy, dfy])
    var = np.maximum(vm, vres)
    df = np.minimum(dfm, dfr)
    mean_var = np.maximum((eta * scale + 1.0) * mvy, mvr)
    info.update(eta=eta, scale=scale, k=k)
    return var, df, mean_var, fac_used, eta


def _uncentred(rho: dict, f0: np.ndarray, n0: int) -> dict:
    """ρ(d) from correlations measured on residuals centred on n0-pixel block means: centring turns ρ
    into ρ_c ≈ (ρ − F0/n0)/(1 − F0/n0) (see :func:`brdflab.stats.blocks.correlation_factor`), so
    ρ = ρ_c (1 − F0/n0) + F0/n0; used to get F of larger windows from one measurement."""
    g = np.asarray(f0, dtype=np.float64) / n0
    return {d: r * (1.0 - g) + g for d, r in rho.items()}


def _window_sum(a: np.ndarray, m: int) -> np.ndarray:
    """Sums over every m × m window of base blocks: (By, Bx, C) → (By − m + 1, Bx − m + 1, C).

    Direct sums of shifted copies (not differences of cumulative sums, whose round-off would give an
    empty window a tiny non-zero difference and a zero variance: t = ∞)."""
    ly, lx = a.shape[0] - m + 1, a.shape[1] - m + 1
    rows = sum(a[i:i + ly] for i in range(m))
    return sum(rows[:, j:j + lx] for j in range(m))


def _scan_sums(runs4: np.ndarray, x4: np.ndarray, y4: np.ndarray, r_var: np.ndarray, finite: np.ndarray,
               block: int) -> dict:
    """Additive per-block sums from which every window of m × m blocks gets the statistics of
    :func:`_single_render_var` (the scan of the single-render model)."""
    e = runs4 - runs4.mean(axis=0)
    e[:, ~finite] = 0.0
    e2 = (e * e).sum(axis=0)
    e4 = (e * e * e * e).sum(axis=0)
    v = finite[..., None]
    r, y = np.where(v, r_var, 0.0), np.where(v, y4, 0.0)
    cnt = B.block_sum(v.astype(np.float64), block)
    c = r - B.expand(B.block_sum(r, block) / np.maximum(cnt, 1), block, finite.shape)
    c[~finite] = 0.0
    c2 = c * c
    sums = {"cnt": cnt, "d": np.where(v, x4 - y4, 0.0), "e2": e2, "e4": e4, "r": r, "rr": r * r, "y": y,
            "yy": y * y, "ry": r * y, "c2": c2, "c4": c2 * c2}
    return {k: (a if k == "cnt" else B.block_sum(a, block)) for k, a in sums.items()}


def _scan_level(sums: dict, m: int, info: dict, block: int) -> dict:
    """The single-render model test on every window of m × m blocks, at every block offset.

    Window statistics from the additive sums (:func:`_scan_sums`): brdflab's run-to-run variance and its
    kurtosis degrees of freedom (:mod:`brdflab.stats.blocks` eq. (2)), F of eq. (1) for the window's
    size from the correlations measured once at the base block, the residual spread with the window's
    mean and slope on ȳ removed (its kurtosis from residuals centred per base block).
    """
    w = {k: _window_sum(a, m) for k, a in sums.items()}
    size, k = m * block, info["k"]
    cnt = w["cnt"]
    n = np.maximum(cnt, 1)
    channels = w["d"].shape[-1]
    with np.errstate(invalid="ignore", divide="ignore"):
        f_y = B.correlation_factor(info["runs"]["rho"], size, channels)
        vy = f_y * w["e2"] / (k - 1) / n**2 / k
        e2 = np.where(w["e2"] > 0, w["e2"], 1.0)
        kap = np.clip(np.where(w["e2"] > 0, cnt * k * w["e4"] / e2**2, 3.0), 3.0, None)
        dfy = np.clip(2.0 * cnt * (k - 1) / f_y / (kap - 1.0), 1.0, None)
        vx = info["eta"] * info["scale"] * vy
        vm, dfm = vx + vy, welch_df([vx, vy], [dfy, dfy])
        f_r = B.correlation_factor(info["res"]["rho"], size, channels)
        ss = w["rr"] - w["r"] ** 2 / n
        syy = w["yy"] - w["y"] ** 2 / n
        sry = w["ry"] - w["r"] * w["y"] / n
        ss = np.maximum(ss - np.where(syy > 0, sry**2 / np.where(syy > 0, syy, 1.0), 0.0), 0.0)
        vres = f_r * ss / np.maximum(n - 2.0 * f_r, 1.0) / n
        kap_r = np.clip(np.where(w["c2"] > 0, cnt * w["c4"] / np.where(w["c2"] > 0, w["c2"], 1.0) ** 2, 3.0), 3.0,
                        None)
        dfr = np.clip(2.0 * np.maximum(n / f_r - 2.0, 1.0) / (kap_r - 1.0), 1.0, None)
    var, df = np.maximum(vm, vres), np.minimum(dfm, dfr)
    diff, refb = w["d"] / n, w["y"] / n
    t, p = _t_tests(diff, var, df, cnt, refb)
    return {"size": size, "step": block, "cnt": cnt, "diff": diff[..., :3], "refb": refb[..., :3], "var": var,
            "df": df, "t": t, "p": p}


def _t_tests(diff: np.ndarray, var: np.ndarray, df: np.ndarray, cnt: np.ndarray,
             refb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """t statistics of R, G, B and their two-sided p-values.

    The variance is at least (ROUNDING · block mean)²: where brdflab's runs are exactly constant (a light
    seen directly) a float32 render by another program differs by rounding, which is no bias.
    """
    var = np.maximum(var, (ROUNDING * refb) ** 2)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(var > 0, diff / np.sqrt(np.where(var > 0, var, 1.0)),
                     np.where(diff != 0, np.copysign(np.inf, diff), 0.0))
    tb = np.where(cnt > 0, t, 0.0)[..., :3]
    return tb, 2.0 * stats.t.sf(np.abs(tb), np.broadcast_to(df[..., :3], tb.shape))


def _covered(a: np.ndarray, lv: dict, block: int, shape: tuple[int, int]):
    """For each position of level ``lv``, the (row, column) index arrays of the base cells it covers, as
    pairs (level slice mask, base cell index) per offset inside the window."""
    r, cover = lv["step"] // block, lv["size"] // block
    for di in range(cover):
        for dj in range(cover):
            ys, xs = np.arange(a.shape[0]) * r + di, np.arange(a.shape[1]) * r + dj
            iy, ix = ys < shape[0], xs < shape[1]
            yield np.ix_(iy, ix), np.ix_(ys[iy], xs[ix])


def _paint_coarse(signed: np.ndarray, lv: dict, block: int) -> np.ndarray:
    """Mark on the base grid the significant windows of a coarser level that show something new.

    Each region is shown at the finest size that detects it: a window is skipped when a base cell it
    covers is already marked with its sign; of overlapping windows only the local maxima of |t| (within
    half a window) are drawn, so a patch found by 128-pixel windows at every offset is not drawn as the
    union of them all. Sets ``lv["shown"]`` (the windows listed in ``flagged``).
    """
    lb = np.argmax(np.abs(lv["t"]), axis=-1)
    lz = np.take_along_axis(lv["t"], lb[..., None], axis=-1)[..., 0]
    rej = lv["rej"].any(axis=-1)
    sign = np.where(rej, np.sign(lz), 0).astype(np.int8)
    explained = np.zeros(sign.shape, bool)
    for lvl, cell in _covered(sign, lv, block, signed.shape):
        explained[lvl] |= (signed[cell] == sign[lvl]) & (sign[lvl] != 0)
    score = np.where(rej & ~explained, np.abs(lz), -1.0)
    half = max(1, (lv["size"] // lv["step"]) // 2)
    peak = maximum_filter(score, size=2 * half + 1, mode="constant", cval=-1.0)
    shown = (score >= 0) & (score >= peak)
    lv["shown"] = shown
    paint = np.where(shown, sign, 0).astype(np.int8)
    out = signed.copy()
    for lvl, cell in _covered(paint, lv, block, signed.shape):
        out[cell] = np.where(out[cell] == 0, paint[lvl], out[cell])
    return out


def _block_level(sides, block: int, info: dict | None = None) -> dict:
    """Block differences, their variance, degrees of freedom, t and two-sided p at one block size."""
    xs4, x4, y4, r_var, finite, estimate, user_spp = sides
    cnt = B.block_sum(finite[..., None].astype(np.float64), block)
    n = np.maximum(cnt, 1)
    diff = B.block_sum(x4 - y4, block) / n
    refb = B.block_sum(y4, block) / n
    welch = xs4.shape[0] >= 2 and (estimate.runs is not None or estimate.pixel_var is not None)
    if welch:
        vx, dfx, mvx, fx = _side_from_runs(xs4, finite, block)
        if estimate.runs is not None:
            vy, dfy, mvy, _ = _side_from_runs(_with_mean_channel(estimate.runs), finite, block)
        else:
            pv = _with_mean_channel(np.where(finite[..., None], estimate.pixel_var, 0.0))
            pv[..., 3] = estimate.pixel_var.mean(axis=-1)  # conservative: channels fully correlated
            fac = np.array([fx] * 4)
            vy = fac * B.block_sum(pv, block) / n**2
            dfy = np.full_like(vy, np.inf)
            mvy = fac * pv.sum(axis=(0, 1)) / finite.sum() ** 2
        var, df = vx + vy, welch_df([vx, vy], [dfx, dfy])
        mean_var = mvx + mvy
        fac_used = fx
        method = "welch"
    elif estimate.runs is not None:
        var, df, mean_var, fac_used, eta = _single_render_var(estimate, r_var, y4, finite, block, cnt,
                                                              user_spp, info)
        method = f"model (brdflab's noise at the user's spp × η = {eta:.2f}, at least the residual spread)"
    else:
        var, df, mean_var, fac_used = _residual(r_var, finite, block)
        var = _pool_neighbours(var, refb, cnt)
        method = "residual"
    tb, p_block = _t_tests(diff, var, df, cnt, refb)
    return {"size": block, "step": block, "cnt": cnt, "diff": diff[..., :3], "refb": refb[..., :3], "var": var,
            "df": df, "t": tb, "p": p_block, "mean_var": mean_var, "fac": fac_used, "method": method}
