"""Block statistics of Monte Carlo images: block sums, the variance of a block mean, its degrees of freedom.

Pixel noise of a Monte Carlo render is heavy-tailed (a pixel's value is a mean of a few samples with
rare large ones), and neighbouring pixels are correlated (a reconstruction filter wider than a pixel
splats one sample into several). Tests are therefore made on **block means**: a 16 × 16 block of a
64-spp render averages 16 k samples, so its mean is close to normal (central limit theorem), while the
Šidák/Holm correction over the ~1 900 blocks of an 800 × 600 image still leaves them small enough to
localise a biased wall.

For a block of n pixels with per-pixel noise variance σ² and spatial correlation ρ(d) between pixels at
offset d, the variance of the block mean is (a sum over pairs of pixels in an s × s block)

    Var(block mean) = σ²/n · F,   F = Σ_d ρ(d) · (1 − |d_x|/s)(1 − |d_y|/s)            (1)

and F∞ = Σ_d ρ(d) applies to the mean of the whole image. :func:`correlation_factor` estimates ρ(d)
for |d_x|, |d_y| ≤ 3 pixels (a Gaussian filter of radius 2 correlates pixels up to 2 apart) from a
normalised noise field pooled over the whole image, and takes F = max(1, ·) (conservative).

Degrees of freedom of a pooled variance estimate of heavy-tailed values: Var(s²) ≈ σ⁴ (κ − 1)/n for
kurtosis κ, so the equivalent chi-square count is (Satterthwaite)

    df = 2 n_eff / (κ − 1),   n_eff = n · (runs − 1) / F                                (2)

(df = n_eff for normal noise, κ = 3); a block with a firefly gets a large κ, few degrees of freedom and a
wide t-quantile, rather than a false alarm.
"""

from __future__ import annotations

import numpy as np

#: Largest pixel offset at which correlation is estimated (Nori's Gaussian filter has radius 2).
MAX_LAG = 3


def grid(shape: tuple[int, int], block: int) -> tuple[int, int]:
    """Number of block rows and columns covering an image of ``shape`` = (H, W) (edge blocks partial)."""
    h, w = shape
    return -(-h // block), -(-w // block)


def block_sum(a: np.ndarray, block: int) -> np.ndarray:
    """Sums over ``block × block`` tiles of the last-but-one two axes: (..., H, W, C) → (..., By, Bx, C)."""
    *lead, h, w, c = a.shape
    by, bx = grid((h, w), block)
    pad = [(0, 0)] * len(lead) + [(0, by * block - h), (0, bx * block - w), (0, 0)]
    p = np.pad(a, pad) if (by * block != h or bx * block != w) else a
    return p.reshape(*lead, by, block, bx, block, c).sum(axis=(-4, -2))


def expand(b: np.ndarray, block: int, shape: tuple[int, int]) -> np.ndarray:
    """Per-block values (By, Bx, C) repeated to pixels (H, W, C)."""
    return np.repeat(np.repeat(b, block, axis=0), block, axis=1)[: shape[0], : shape[1]]


def correlation(z: np.ndarray, valid: np.ndarray, max_lag: int = MAX_LAG) -> dict[tuple[int, int], np.ndarray]:
    """Correlation ρ(d) per channel of a zero-mean noise field at offsets d = (dy, dx), |dx|, |dy| ≤ max_lag.

    Parameters
    ----------
    z
        (M, H, W, C) noise realisations, each pixel scaled to unit variance; invalid pixels hold 0.
    valid
        (H, W) mask of the pixels that count.
    """
    m, h, w, c = z.shape
    v = valid.astype(np.float64)
    zz = np.einsum("mhwc,mhwc->c", z, z) / max(m * v.sum(), 1.0)
    out = {}
    for dy in range(0, max_lag + 1):
        for dx in range(-max_lag, max_lag + 1):
            if dy == 0 and dx <= 0:
                continue
            xa, xb = max(dx, 0), w + min(dx, 0)
            a = z[:, dy:, xa:xb]
            b = z[:, : h - dy, xa - dx: xb - dx]
            pairs = (v[dy:, xa:xb] * v[: h - dy, xa - dx: xb - dx]).sum() * m
            s = np.einsum("mhwc,mhwc->c", a, b)
            rho = s / max(pairs, 1.0) / np.where(zz > 0, zz, 1.0)
            out[(dy, dx)] = rho
            out[(-dy, -dx)] = rho
    return out


def correlation_factor(rho: dict[tuple[int, int], np.ndarray], block: int | None, channels: int,
                       centred_in: int | None = None) -> np.ndarray:
    """F of eq. (1) per channel for an s × s block (``block=None``: F∞ of the whole image), at least 1.

    ``centred_in=n``: ``rho`` was measured on residuals centred on their n-pixel block means (so that a
    bias constant over a block does not pass for correlation). Centring turns ρ(d) into
    ρ_c(d) ≈ (ρ(d) − F/n)/(1 − F/n); summed with the weights w(d) of eq. (1) (Σ w = W) over the lag
    window this gives S_c = (F − F·W/n)/(1 − F/n), solved as F = S_c / (1 + (S_c − W)/n).
    """
    f = np.ones(channels)
    wsum = 1.0
    for (dy, dx), r in rho.items():
        wgt = 1.0 if block is None else max(0.0, 1 - abs(dx) / block) * max(0.0, 1 - abs(dy) / block)
        f = f + wgt * r
        wsum += wgt
    if centred_in:
        f = f / np.maximum(1.0 + (f - wsum) / centred_in, 0.05)
    return np.maximum(f, 1.0)


def kurtosis_df(e: np.ndarray, valid: np.ndarray, block: int, n_eff: np.ndarray) -> np.ndarray:
    """Degrees of freedom of eq. (2) per block and channel from zero-mean residuals ``e`` (M, H, W, C).

    ``n_eff`` (By, Bx, C) is the effective number of independent squared residuals in the block.
    """
    e2 = e * e
    s2 = block_sum(e2.sum(axis=0), block)
    s4 = block_sum((e2 * e2).sum(axis=0), block)
    cnt = block_sum(np.broadcast_to(valid[..., None], e.shape[1:]).astype(np.float64), block) * e.shape[0]
    with np.errstate(divide="ignore", invalid="ignore"):
        kappa = np.where(s2 > 0, cnt * s4 / (s2 * s2), 3.0)
    kappa = np.clip(kappa, 3.0, None)  # lighter tails than normal: keep the normal-theory count
    return np.clip(2.0 * n_eff / (kappa - 1.0), 1.0, None)
