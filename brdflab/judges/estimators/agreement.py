"""Estimator agreement: ``direct_ems``, ``direct_mats`` and ``direct_mis`` converge to the same image.

All three integrators estimate the same direct illumination (spec §13.2), so on any scene their expected
images are equal; a missing selection probability, Jacobian or MIS weight makes one of them converge to
something else. The check renders each estimator ``reps`` times with independent seeds (small images,
few samples), averages every ``block`` × ``block`` pixel block per render, and compares each pair of
estimators block by block with Welch's t-test on the replicate means (the replicate spread is the
estimator's own standard error, no variance model needed). The family-wise p-value over all pairs and
blocks is Šidák's 1 − (1 − p_min)^m; the verdict is *agree* when it exceeds the significance (0.01).

BSDF sampling cannot find delta (point) lights, so on a scene with point lights ``direct_mats`` (and ``path``,
:data:`BSDF_ONLY`) is compared with the others on a copy of the scene without them (:func:`without_delta_lights`),
while ``direct_ems`` and ``direct_mis`` are also compared on the full scene (MIS gives delta lights weight 1).
The path tracers ``path``, ``path_nee``, ``path_mis`` (:data:`PATH_ESTIMATORS`) are compared the same way.

:func:`forget_selection_probability` is the planted bug of the negative control: emitters are still chosen
with their probabilities, but the light-sampling pdf omits them.
"""

from __future__ import annotations

import copy
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy import stats

from brdflab.scene import BUNDLED_SCENES

SIGNIFICANCE = 0.01
LUMINANCE = np.array([0.212671, 0.715160, 0.072169])
ESTIMATORS = ("direct_ems", "direct_mats", "direct_mis")
#: The path tracers (spec §13.2.6–8): the same check applies to them (all three estimate the same image).
PATH_ESTIMATORS = ("path", "path_nee", "path_mis")
#: Estimators by BSDF sampling only: they cannot see delta (point) lights.
BSDF_ONLY = ("direct_mats", "path")


@dataclass
class AgreementResult:
    """Outcome of one estimator-agreement check."""

    name: str
    """Scene (and selection rule) checked."""
    p_value: float
    """Family-wise (Šidák) p-value over all estimator pairs and blocks."""
    tests: int
    """Number of (pair, block) comparisons."""
    worst: str
    """The comparison with the smallest p-value: pair, block and both means."""
    means: dict[str, float] = field(default_factory=dict)
    """Image mean per estimator (on the scene each one was compared on)."""
    threshold: float = SIGNIFICANCE
    params: dict = field(default_factory=dict)

    @property
    def passed(self) -> bool:
        """True when the estimators agree (family-wise p-value above the significance)."""
        return bool(self.tests > 0 and self.p_value > self.threshold)


def _remap_emitters(scene, keep: list[int]):
    """A shallow copy of ``scene`` with only the emitters ``keep`` (indices), caches dropped."""
    s = copy.copy(scene)
    s.__dict__ = {k: v for k, v in scene.__dict__.items() if k not in ("_tables", "_area_light_set")}
    new = np.full(len(scene.emitters) + 1, -1, np.int64)
    new[keep] = np.arange(len(keep))
    s.emitters = [scene.emitters[i] for i in keep]
    s.mesh_emitter = new[np.asarray(scene.mesh_emitter, np.int64)]
    return s


def without_delta_lights(scene, selection: str = "uniform"):
    """A copy of ``scene`` without its point lights (what BSDF sampling can see); None if it has no other
    emitter."""
    keep = [i for i, e in enumerate(scene.emitters) if not e.is_delta]
    if not keep:
        return None
    s = _remap_emitters(scene, keep)
    s.set_emitter_selection(selection)
    return s


def forget_selection_probability(scene) -> None:
    """Planted bug (negative control): divide light samples by p_ω only, not p_sel·p_ω.

    Emitters are still chosen with the scene's pmf (its CDF is kept); only the pmf used in the pdfs is
    replaced by ones, as a student forgetting the selection probability would.
    """
    scene.emitter_pmf = np.ones(len(scene.emitters))
    scene.__dict__.pop("_area_light_set", None)


def _seed(*parts) -> int:
    return zlib.crc32(repr(parts).encode())


def block_means(scene, spp: int, reps: int, block: int, seed: int) -> np.ndarray:
    """(reps, blocks) block means of the luminance of ``reps`` renders."""
    from brdflab.renderer import render

    out = []
    for k in range(reps):
        img, _ = render(scene, spp=spp, seed=seed + k, workers=1)
        h, w = (img.shape[0] // block) * block, (img.shape[1] // block) * block
        lum = img[:h, :w].astype(np.float64) @ LUMINANCE
        out.append(lum.reshape(h // block, block, w // block, block).mean(axis=(1, 3)).reshape(-1))
    return np.array(out)


def _load(path: Path, integrator: str, width: int | None, height: int | None, selection: str,
          prepare: Callable | None):
    from brdflab.scene.loader import load_scene

    s = load_scene(path, integrator)
    if width:
        s.camera.width = width
    if height:
        s.camera.height = height
    s.set_emitter_selection(selection)
    if prepare is not None:
        prepare(s)
    return s


#: Differences below REL_TOL × the block mean + ABS_TOL × the image mean count as agreement (the check resolves
#: biases above 1 % of the image mean per block; a forgotten selection probability or Jacobian is tens of %).
#: This keeps rare events from being read as disagreement: a small bright light seen in a glossy floor that
#: BSDF sampling hits a few times per thousand samples gives replicate means that are almost all 0, whose
#: spread underestimates the standard error (measured: 1 false alarm in 44 runs without it).
REL_TOL, ABS_TOL = 2e-3, 1e-2


def compare_blocks(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Welch t-test p-values per block of two (reps, blocks) arrays, on |Δ| less the tolerance (REL_TOL,
    ABS_TOL); NaN where both are constant and equal (no signal: e.g. blocks that are black for both)."""
    ma, mb = a.mean(axis=0), b.mean(axis=0)
    va, vb = a.var(axis=0, ddof=1) / len(a), b.var(axis=0, ddof=1) / len(b)
    se = np.sqrt(va + vb)
    tol = REL_TOL * 0.5 * np.abs(ma + mb) + ABS_TOL * 0.5 * abs(float(ma.mean() + mb.mean()))
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.maximum(np.abs(ma - mb) - tol, 0.0) / se
        dof = (va + vb) ** 2 / (va**2 / (len(a) - 1) + vb**2 / (len(b) - 1))
    p = 2 * stats.t.sf(np.abs(t), np.where(np.isfinite(dof), dof, 1.0))
    p = np.where(se > 0, p, np.where(np.abs(ma - mb) <= tol, np.nan, 0.0))
    return p


def estimator_agreement(path: str | Path, estimators=ESTIMATORS, spp: int = 8, reps: int = 16,
                        width: int | None = 64, height: int | None = 48, block: int = 8,
                        selection: str = "uniform", seed: int | None = None, significance: float = SIGNIFICANCE,
                        prepare: Callable | None = None, name: str | None = None) -> AgreementResult:
    """Check that the estimators agree on the scene ``path`` (see the module docstring).

    Parameters
    ----------
    path
        A scene file (its own integrator is replaced by each estimator in turn).
    estimators
        Integrator names to compare pairwise.
    spp, reps
        Samples per pixel of each render, and independent renders per estimator.
    width, height
        Image size for the check (None keeps the scene's).
    block
        Side of the pixel blocks whose means are compared.
    selection
        Emitter selection rule (``uniform`` or ``power``).
    seed
        Base seed (default: derived from the scene name); each estimator and replicate has its own stream.
    prepare
        Called on every loaded scene before rendering (the negative control plants a bug here).

    Returns
    -------
    AgreementResult
        With the family-wise p-value and the worst comparison.
    """
    path = Path(path)
    label = name or f"{path.stem} ({selection})"
    base = _seed(path.name, selection) if seed is None else seed
    scenes: dict[str, object] = {}
    reduced: dict[str, object] = {}
    for est in estimators:
        s = _load(path, est, width, height, selection, prepare)
        scenes[est] = s
        if any(e.is_delta for e in s.emitters):
            r = without_delta_lights(s, selection)
            if r is not None and prepare is not None:
                prepare(r)
            reduced[est] = r
    has_delta = bool(reduced)
    data: dict[tuple[str, bool], np.ndarray] = {}

    def means(est: str, full: bool) -> np.ndarray:
        key = (est, full)
        if key not in data:
            s = scenes[est] if full else reduced[est]
            data[key] = block_means(s, spp, reps, block, base + 1000 * len(data) + 1)
        return data[key]

    pairs = []
    for i, a in enumerate(estimators):
        for b in estimators[i + 1:]:
            sees_all = not {a, b} & set(BSDF_ONLY)
            if not has_delta or sees_all:
                pairs.append((a, b, True))
            if has_delta and all(reduced.get(e) is not None for e in (a, b)):
                pairs.append((a, b, False))
    p_min, worst, m = 1.0, "", 0
    img_means: dict[str, float] = {}
    for a, b, full in pairs:
        da, db = means(a, full), means(b, full)
        img_means[a + ("" if full else " (no point lights)")] = float(da.mean())
        img_means[b + ("" if full else " (no point lights)")] = float(db.mean())
        p = compare_blocks(da, db)
        ok = np.isfinite(p)
        m += int(ok.sum())
        if ok.any():
            j = int(np.nanargmin(p))
            if p[j] < p_min or not worst:
                p_min = float(p[j])
                worst = (f"{a} vs {b}{'' if full else ' without point lights'}, block {j}: "
                         f"{da[:, j].mean():.5g} vs {db[:, j].mean():.5g} (p = {p[j]:.3g})")
    p_fw = float(1.0 - (1.0 - p_min) ** m) if m else 0.0
    if m and p_min > 0:
        p_fw = float(-np.expm1(m * np.log1p(-p_min)))  # 1 − (1 − p)^m without cancellation
    return AgreementResult(label, p_fw, m, worst, img_means, significance,
                           {"spp": spp, "reps": reps, "block": block, "size": f"{width}x{height}",
                            "selection": selection})


def canonical_scenes(root: Path | None = None) -> list[tuple[Path, str]]:
    """(scene, selection) pairs of the generated light-path scenes checked by ``brdflab validate``:
    triangle-mesh and polygon lights, fused area lights, and mixed area + point + environment lights
    under both selection rules. Empty when the scenes folder is not beside the package."""
    root = root or BUNDLED_SCENES / "lights"
    out = []
    for stem, selections in (("sphere_light", ("uniform",)), ("polygon_lights", ("uniform", "power")),
                             ("mixed_lights", ("uniform", "power"))):
        p = root / f"{stem}_mis.xml"
        if p.exists():
            out.extend((p, sel) for sel in selections)
    return out


def run(progress: Callable[[str], None] | None = None, reps: int = 16, spp: int = 8) -> tuple[list[AgreementResult],
                                                                                            list[AgreementResult]]:
    """All canonical agreement checks and the negative control (selection probability forgotten on the
    mixed-lights scene, which must be rejected). Returns (checks, negative controls)."""
    scenes = canonical_scenes()
    threshold = 1.0 - (1.0 - SIGNIFICANCE) ** (1.0 / max(1, len(scenes)))
    checks = []
    for path, sel in scenes:
        r = estimator_agreement(path, selection=sel, reps=reps, spp=spp, significance=threshold)
        checks.append(r)
        if progress:
            progress(f"{'PASS' if r.passed else 'FAIL'}  agreement {r.name}: p = {r.p_value:.3g} ({r.tests} block "
                     f"comparisons); worst: {r.worst}")
    negative = []
    mixed = [p for p, sel in scenes if p.stem.startswith("mixed_lights") and sel == "uniform"]
    for path in mixed[:1]:
        r = estimator_agreement(path, reps=reps, spp=spp, significance=threshold, prepare=forget_selection_probability,
                                name=f"{path.stem} without the selection probability [negative control]")
        negative.append(r)
        if progress:
            progress(f"{'REJECTED (good)' if not r.passed else 'NOT REJECTED (bad)'}  agreement negative control: "
                     f"p = {r.p_value:.3g}")
    return checks, negative
