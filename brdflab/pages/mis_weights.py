"""MIS weight images (Veach 1997, fig. 9.2): per pixel, the share of the estimate carried by emitter
samples versus BSDF samples.

:class:`brdflab.integrator.direct_mis.DirectMIS` has a ``parts`` switch (off — ``"both"`` — in every
normal render, so the render path is unchanged): ``"emitter"`` returns only the MIS-weighted emitter
samples, ``"bsdf"`` only the weighted BSDF samples. Both parts drawn with the same seed use the same
random numbers, so per pixel

    share_emitter = Y(emitter part) / (Y(emitter part) + Y(BSDF part))

with Y the mean of R, G, B; pixels with no direct illumination (emitters seen directly, background) are
undefined (drawn grey).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from brdflab.imageio import _atomic_write


def mis_parts(scene_path: Path, spec: str, spp: int, seed: int, resolution=None, workers=None
              ) -> tuple[np.ndarray, np.ndarray]:
    """(emitter part, BSDF part) images of an MIS integrator spec, rendered with the same seed."""
    from brdflab.renderer import render
    from brdflab.stats.jobs import RenderJob, load_for, run_seed

    job = RenderJob(Path(scene_path), spec, spp, run_seed(seed, 0, "reference") ^ 0x5EED, resolution, workers)
    out = []
    for part in ("emitter", "bsdf"):
        scene = load_for(job)
        scene.integrator.parts = part
        img, _ = render(scene, spp=spp, seed=job.seed, workers=workers)
        out.append(img)
    return out[0], out[1]


def mis_weight_image(scene_path: Path, spec: str, spp: int = 64, seed: int = 0, resolution=None, workers=None
                     ) -> np.ndarray:
    """(H, W) share of the estimate contributed by emitter samples (NaN where there is no estimate)."""
    em, bs = mis_parts(scene_path, spec, spp, seed, resolution, workers)
    a = em.astype(np.float64).mean(axis=2)
    b = bs.astype(np.float64).mean(axis=2)
    tot = a + b
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(tot > 0, a / np.where(tot > 0, tot, 1.0), np.nan)


def write_weight_image(path: Path, share: np.ndarray, title: str = "") -> None:
    """Blue where emitter samples carry the estimate, red where BSDF samples do, near-white half and half; black
    where no light arrives (undefined) — grey there read as "50/50"."""
    import matplotlib

    matplotlib.use("Agg")
    from brdflab.viz.mpl import safe_figures

    safe_figures()  # user text is never mathtext; log axes still read 10⁻²
    import matplotlib.pyplot as plt

    h, w = share.shape
    fig, ax = plt.subplots(figsize=(5.2, 5.2 * h / w + 0.5), dpi=100)
    cmap = matplotlib.colormaps["coolwarm_r"].with_extremes(bad="black")
    im = ax.imshow(np.ma.masked_invalid(share), cmap=cmap, vmin=0, vmax=1, interpolation="nearest")
    ax.set_axis_off()
    ax.set_title(title, fontsize=9)
    fig.colorbar(im, ax=ax, fraction=0.046, pad=0.02,
                 label="emitter samples' share (black: no light)")
    fig.tight_layout()
    _atomic_write(path, lambda tmp: fig.savefig(tmp, format="png"))
    plt.close(fig)
