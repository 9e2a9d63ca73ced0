"""Image error metrics against a reference (per channel and overall).

==========  ===============================================  ======================================
metric      definition (per pixel p, channel c, means over p)  note
==========  ===============================================  ======================================
MSE         mean (x − r)²
RMSE        √MSE
relMSE      mean (x − r)² / (r² + 0.01)                      the course's relative MSE
MAPE        mean |x − r| / (|r| + 0.01)                      mean absolute percentage error
bias        mean(x)/mean(r) − 1                              relative bias of the image mean
==========  ===============================================  ======================================

Non-finite pixels of the test image are counted and excluded from every metric (so one NaN does not
hide the rest); the reference must be finite.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from brdflab.errors import ImageError

EPS = 0.01
CHANNELS = ("R", "G", "B")


@dataclass
class Metrics:
    """Error of one image against a reference."""

    mse: float
    rmse: float
    relmse: float
    mape: float
    bias: float
    per_channel: dict[str, dict[str, float]]
    nonfinite: int
    pixels: int

    def to_dict(self) -> dict:
        """Plain-dict form (for JSON)."""
        return asdict(self)


def _check(test: np.ndarray, ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    test = np.asarray(test, dtype=np.float64)
    ref = np.asarray(ref, dtype=np.float64)
    if test.ndim == 2:
        test = test[..., None]
    if ref.ndim == 2:
        ref = ref[..., None]
    if test.shape[:2] != ref.shape[:2]:
        raise ImageError(f"image sizes differ: test is {test.shape[1]}×{test.shape[0]}, reference is "
                         f"{ref.shape[1]}×{ref.shape[0]}")
    if test.shape[2] != ref.shape[2]:
        raise ImageError(f"channel counts differ: test has {test.shape[2]}, reference has {ref.shape[2]}")
    if not np.isfinite(ref).all():
        raise ImageError("the reference image contains NaN or infinite values")
    return test, ref


def _metrics(x: np.ndarray, r: np.ndarray) -> dict[str, float]:
    d = x - r
    mse = float(np.mean(d * d))
    return {
        "mse": mse,
        "rmse": float(np.sqrt(mse)),
        "relmse": float(np.mean(d * d / (r * r + EPS))),
        "mape": float(np.mean(np.abs(d) / (np.abs(r) + EPS))),
        "bias": float(np.mean(x) / np.mean(r) - 1.0) if np.mean(r) != 0 else float("nan"),
    }


def compare(test: np.ndarray, ref: np.ndarray) -> Metrics:
    """Compare ``test`` with ``ref`` (both (H, W, C)); see the module docstring for definitions."""
    test, ref = _check(test, ref)
    finite = np.isfinite(test).all(axis=2) & np.isfinite(ref).all(axis=2)
    if not finite.any():
        raise ImageError("no pixel is finite in both images: nothing to compare")
    x, r = test[finite], ref[finite]
    overall = _metrics(x, r)
    names = CHANNELS if test.shape[2] == 3 else tuple(str(i) for i in range(test.shape[2]))
    per = {names[c]: _metrics(x[:, c], r[:, c]) for c in range(test.shape[2])}
    return Metrics(**overall, per_channel=per, nonfinite=int((~finite).sum()), pixels=int(finite.size))


def relmse_map(test: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Per-pixel relative squared error (x − r)²/(r² + 0.01), averaged over channels, (H, W)."""
    test, ref = _check(test, ref)
    d = test - ref
    return np.mean(d * d / (ref * ref + EPS), axis=2)


def write_heatmap(path, test: np.ndarray, ref: np.ndarray, title: str = "relative squared error") -> None:
    """Write a false-colour, log-scale per-pixel error heatmap with a colour bar (PNG or SVG)."""
    import matplotlib

    matplotlib.use("Agg")
    from brdflab.viz.mpl import safe_figures

    safe_figures()  # user text is never mathtext; log axes still read 10⁻²
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm

    from brdflab.imageio import _atomic_write

    err = relmse_map(test, ref)
    bad = ~np.isfinite(err)
    pos = err[(err > 0) & ~bad]
    lo = max(float(np.percentile(pos, 1)), 1e-8) if pos.size else 1e-8
    hi = max(float(np.percentile(pos, 99.9)), lo * 10) if pos.size else 1.0
    h, w = err.shape
    fig, ax = plt.subplots(figsize=(6.4, 6.4 * h / w + 0.6), dpi=100)
    im = ax.imshow(np.where(bad, np.nan, np.clip(err, lo, hi)), cmap="inferno", norm=LogNorm(lo, hi))
    ax.set_axis_off()
    ax.set_title(title)
    fig.colorbar(im, ax=ax, fraction=0.046, pad=0.02, label="(x − r)² / (r² + 0.01)")
    fig.tight_layout()
    fmt = str(path).rsplit(".", 1)[-1].lower()
    _atomic_write(path, lambda tmp: fig.savefig(tmp, format=fmt))
    plt.close(fig)


# -- HDR-FLIP ---------------------------------------------------------------------------------------------
def flip_parameters(ref: np.ndarray) -> dict | None:
    """HDR-FLIP's exposure range (start, stop, number of exposures) computed once from the reference.

    NVIDIA's ``flip_evaluator`` derives c_start/c_stop from the reference's luminance (Andersson et al.
    2021, HDR-FLIP §3); fixing them here makes every test image of a study — any integrator, any spp —
    judged at the same exposures.

    Returns None when HDR-FLIP is undefined for this reference: its largest luminance is below
    :data:`FLIP_MIN_LUMINANCE` (an all-black, all-negative or all-NaN image). ``flip_evaluator`` places
    the stop exposure at the median luminance floored at float32's ε (2^-23) and the start exposure at
    the largest luminance, and ends the whole process (exit status 255, "Start exposure must be smaller
    than stop exposure") when start > stop; measured: a constant 10⁻⁶ image works, 10⁻⁷ exits.
    """
    import flip_evaluator

    r = _flip_input(ref)
    if not float((r @ np.array([0.2126, 0.7152, 0.0722], np.float32)).max(initial=0.0)) >= FLIP_MIN_LUMINANCE:
        return None
    _, _, params = flip_evaluator.evaluate(r, r, "HDR", applyMagma=False, computeMeanError=False)
    return {k: params[k] for k in ("startExposure", "stopExposure", "numExposures")}


#: Smallest largest-luminance of a reference for which HDR-FLIP is defined (float32 ε = 1.19e-7, with a margin).
FLIP_MIN_LUMINANCE = 2e-7


def _flip_input(img: np.ndarray) -> np.ndarray:
    """What FLIP may be given: finite, non-negative float32 (NaN and −∞ → 0, +∞ → the largest float32)."""
    a = np.nan_to_num(np.asarray(img, dtype=np.float32), nan=0.0, neginf=0.0)
    return np.ascontiguousarray(np.clip(a, 0, None), dtype=np.float32)


def flip_error(test: np.ndarray, ref: np.ndarray, params: dict | None = None, with_map: bool = False):
    """Mean HDR-FLIP error of ``test`` against ``ref`` (0 = identical, 1 = maximal); with ``with_map``
    also the (H, W) per-pixel error map. Non-finite test pixels count as 0; negative values are clipped
    (FLIP expects non-negative linear sRGB)."""
    import flip_evaluator

    test, ref = _check(test, ref)
    t = np.ascontiguousarray(np.clip(np.nan_to_num(test, nan=0.0, posinf=0.0), 0, None), dtype=np.float32)
    r = _flip_input(ref)
    params = params or flip_parameters(r)
    if params is None:  # undefined for this reference (see flip_parameters)
        return (float("nan"), np.full(r.shape[:2], np.nan)) if with_map else float("nan")
    err, mean, _ = flip_evaluator.evaluate(r, t, "HDR", applyMagma=False, parameters=dict(params))
    return (float(mean), np.asarray(err)[..., 0]) if with_map else float(mean)


def signed_difference(test: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Per-pixel signed relative difference (x − r)/(r + 0.01), averaged over channels, (H, W)."""
    test, ref = _check(test, ref)
    return np.mean((test - ref) / (np.abs(ref) + EPS), axis=2)


def write_signed_map(path, test: np.ndarray, ref: np.ndarray, title: str = "signed difference",
                     limit: float | None = None) -> None:
    """Diverging false-colour map of :func:`signed_difference`: blue too dark, red too bright (PNG/SVG).

    The colour range is symmetric, ±``limit`` (default: the 99th percentile of |difference|).
    """
    import matplotlib

    matplotlib.use("Agg")
    from brdflab.viz.mpl import safe_figures

    safe_figures()  # user text is never mathtext; log axes still read 10⁻²
    import matplotlib.pyplot as plt

    from brdflab.imageio import _atomic_write

    d = signed_difference(test, ref)
    bad = ~np.isfinite(d)
    lim = limit or max(float(np.percentile(np.abs(d[~bad]), 99)) if (~bad).any() else 1.0, 1e-6)
    h, w = d.shape
    fig, ax = plt.subplots(figsize=(6.4, 6.4 * h / w + 0.6), dpi=100)
    im = ax.imshow(np.where(bad, np.nan, d), cmap="RdBu_r", vmin=-lim, vmax=lim)
    ax.set_axis_off()
    ax.set_title(title, fontsize=9)
    fig.colorbar(im, ax=ax, fraction=0.046, pad=0.02, label="(x − r)/(r + 0.01): blue too dark, red too bright")
    fig.tight_layout()
    fmt = str(path).rsplit(".", 1)[-1].lower()
    _atomic_write(path, lambda tmp: fig.savefig(tmp, format=fmt))
    plt.close(fig)


def crop(img: np.ndarray, box: tuple[int, int, int, int]) -> np.ndarray:
    """The region (x, y, w, h) of an (H, W, C) image; raises :class:`ImageError` when it is not inside."""
    x, y, w, h = box
    H, W = img.shape[:2]
    if w <= 0 or h <= 0 or x < 0 or y < 0 or x + w > W or y + h > H:
        raise ImageError(f"crop {x},{y},{w},{h} is not inside the {W}×{H} image")
    return img[y:y + h, x:x + w]
