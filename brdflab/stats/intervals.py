"""Confidence intervals and multiple-comparison corrections used by checks and reports.

* :func:`t_interval` — Student-t interval of a mean over independent runs.
* :func:`positive_interval` — the same on log scale (delta method) for positive, skewed values.
* :func:`welch_df` — Welch–Satterthwaite degrees of freedom of a sum of variance estimates
  (Welch 1947, eq. (9); Satterthwaite 1946).
* :func:`holm` — Holm's step-down family-wise correction (Holm 1979): sort the m p-values,
  reject p_(i) while p_(i) ≤ α/(m − i + 1); the adjusted p-values are the running maximum of
  (m − i + 1)·p_(i).
* :func:`sidak` — the per-test level 1 − (1 − α)^(1/m) (Šidák 1967).
* :func:`log_ratio_interval` — interval of a ratio of two positive means by the delta method on
  log scale (var log X̄ ≈ var X̄ / X̄²), with Welch–Satterthwaite degrees of freedom.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import stats


def t_interval(values, level: float = 0.95) -> tuple[float, float, float]:
    """(mean, low, high) of the Student-t interval of the mean of independent ``values``.

    One value gives the degenerate interval (mean, nan, nan).
    """
    v = np.asarray(values, dtype=np.float64)
    m = float(v.mean())
    if v.size < 2:
        return m, math.nan, math.nan
    half = float(stats.t.ppf(0.5 + level / 2, v.size - 1) * v.std(ddof=1) / math.sqrt(v.size))
    return m, m - half, m + half


def positive_interval(values, level: float = 0.95) -> tuple[float, float, float]:
    """(mean, low, high) for the mean of positive, skewed run values (relMSE, seconds): the t interval
    of log(mean) by the delta method, log X̄ ± t_{K−1} · s/(√K · X̄) — never below zero."""
    v = np.asarray(values, dtype=np.float64)
    m = float(v.mean())
    if v.size < 2 or m <= 0:
        return m, math.nan, math.nan
    half = float(stats.t.ppf(0.5 + level / 2, v.size - 1) * v.std(ddof=1) / math.sqrt(v.size) / m)
    return m, m * math.exp(-half), m * math.exp(half)


def welch_df(variances, dfs):
    """Welch–Satterthwaite degrees of freedom of Σ vᵢ: (Σ vᵢ)² / Σ (vᵢ² / dfᵢ) (element-wise)."""
    vs = [np.asarray(v, dtype=np.float64) for v in variances]
    num = sum(vs) ** 2
    den = sum(v * v / np.asarray(d, dtype=np.float64) for v, d in zip(vs, dfs, strict=True))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(den > 0, num / den, np.inf)


def holm(p, alpha: float) -> tuple[np.ndarray, np.ndarray]:
    """Holm step-down correction; returns (rejected mask, adjusted p-values), shaped like ``p``."""
    p = np.asarray(p, dtype=np.float64)
    flat = p.ravel()
    m = flat.size
    if m == 0:
        return np.zeros(p.shape, bool), p.copy()
    order = np.argsort(flat, kind="stable")
    adj_sorted = np.minimum(1.0, np.maximum.accumulate((m - np.arange(m)) * flat[order]))
    adj = np.empty(m)
    adj[order] = adj_sorted
    adj = adj.reshape(p.shape)
    return adj <= alpha, adj


def sidak(alpha: float, m: int) -> float:
    """Per-test level of a Šidák correction of ``m`` independent tests at family-wise level ``alpha``."""
    return 1.0 - (1.0 - alpha) ** (1.0 / max(m, 1))


def mean_interval(mean: float, var: float, df: float, level: float) -> tuple[float, float]:
    """Symmetric t interval mean ± t_{df}·√var (normal when df is infinite)."""
    q = stats.norm.ppf(0.5 + level / 2) if not np.isfinite(df) else stats.t.ppf(0.5 + level / 2, df)
    half = float(q * math.sqrt(max(var, 0.0)))
    return mean - half, mean + half


def log_ratio_interval(a, b, level: float = 0.95) -> tuple[float, float, float]:
    """Ratio mean(a)/mean(b) of independent positive run values with its delta-method interval.

    Parameters
    ----------
    a, b
        Per-run values (e.g. relMSE·seconds of two integrators); at least two each.

    Returns
    -------
    (ratio, low, high)
    """
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    ma, mb = a.mean(), b.mean()
    ratio = float(ma / mb)
    if a.size < 2 or b.size < 2 or ma <= 0 or mb <= 0:
        return ratio, math.nan, math.nan
    va = a.var(ddof=1) / a.size / ma**2
    vb = b.var(ddof=1) / b.size / mb**2
    df = float(welch_df([va, vb], [a.size - 1, b.size - 1]))
    lo, hi = mean_interval(math.log(ratio), va + vb, df, level)
    return ratio, math.exp(lo), math.exp(hi)
