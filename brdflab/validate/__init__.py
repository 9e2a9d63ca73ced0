"""Statistical validation of materials and warps: chi-square, consistency, furnace, stability.

The functions below are the public face of the checks (``bl.chi2_test`` …): they take any
:class:`brdflab.BSDF` — built-in or a user's — and return result objects, never printouts. Each test draws
from its own random stream: without an explicit ``seed`` it is derived from the test's identity (the
BSDF's type and parameters, the angle, the check), so two configurations never share random numbers.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable
from typing import Any

import numpy as np


def default_seed(*parts: Any) -> int:
    """A reproducible seed distinct for every test identity ``parts`` (type, parameters, angle, check)."""
    return zlib.crc32(repr(tuple(_plain(p) for p in parts)).encode())


def _plain(p: Any) -> Any:
    if isinstance(p, np.ndarray):
        return tuple(np.round(p.ravel(), 12).tolist())
    if isinstance(p, dict):
        return tuple(sorted((k, _plain(v)) for k, v in p.items()))
    if isinstance(p, float):
        return round(p, 12)
    return p


def identity(bsdf: Any) -> tuple:
    """The BSDF's type name and parameters (its public attributes), for seeds and labels."""
    attrs = {k: v for k, v in vars(bsdf).items() if not k.startswith("_")}
    out = []
    for k, v in sorted(attrs.items()):
        value = getattr(v, "value", v)  # constant textures
        if isinstance(value, int | float | str | bool | np.ndarray | tuple | list):
            out.append((k, _plain(np.asarray(value) if isinstance(value, list | tuple) else value)))
    return (type(bsdf).type_name or type(bsdf).__name__, tuple(out))


def chi2_test(bsdf: Any, theta: float = 30.0, samples: int = 200_000, seed: int | None = None,
              threshold: float | None = None, name: str | None = None):
    """Chi-square goodness of fit of ``bsdf.sample`` against ``bsdf.pdf`` at incident angle ``theta``.

    Parameters
    ----------
    bsdf
        Any :class:`brdflab.BSDF`.
    theta
        Incident angle from the normal, degrees (ω_i in the x–z plane).
    samples
        Number of sampled directions.
    seed
        Random seed; default derived from the BSDF's type, parameters and ``theta``.
    threshold
        Reject when p ≤ threshold (default 0.01; correct it for the number of tests you run).
    name
        Label of the result (default: the BSDF's type name).

    Returns
    -------
    Chi2Result
        ``statistic``, ``dof``, ``p_value``, ``passed``, the ``observed`` and ``expected`` histograms.

    Examples
    --------
    >>> import brdflab as bl
    >>> r = bl.chi2_test(bl.RoughConductor(R0=0.9, alpha=0.2), theta=45, samples=50_000)
    >>> r.passed, r.dof > 100
    (True, True)
    """
    from brdflab.validate import chi2 as c2

    seed = default_seed("chi2", identity(bsdf), theta) if seed is None else seed
    label = name or type(bsdf).type_name or type(bsdf).__name__
    return c2.bsdf_test(label, bsdf, float(theta), int(samples), seed=seed, params={"theta": theta},
                        threshold=c2.SIGNIFICANCE if threshold is None else threshold)


def warp_chi2_test(warp: Callable, pdf: Callable, samples: int = 200_000, seed: int | None = None,
                   threshold: float | None = None, name: str = "warp"):
    """Chi-square test of a square-to-sphere warp ``warp(u) -> (N, 3)`` against ``pdf(w) -> (N,)``.

    Examples
    --------
    >>> import brdflab as bl
    >>> r = bl.warp_chi2_test(bl.warps.square_to_cosine_hemisphere, bl.warps.square_to_cosine_hemisphere_pdf,
    ...                       samples=50_000)
    >>> r.passed
    True
    """
    from brdflab.validate import chi2 as c2

    seed = default_seed("warp", name) if seed is None else seed
    return c2.warp_test(name, warp, pdf, int(samples), seed=seed,
                        threshold=c2.SIGNIFICANCE if threshold is None else threshold)


def consistency_test(bsdf: Any, theta: float = 30.0, samples: int = 100_000, seed: int | None = None,
                     name: str | None = None):
    """Weight = eval·cos/pdf, ∫ pdf ≤ 1 (= the valid fraction), reciprocity, no negative or non-finite value.

    Examples
    --------
    >>> import brdflab as bl
    >>> bl.consistency_test(bl.Diffuse(albedo=0.5), theta=20, samples=20_000).passed
    True
    """
    from brdflab.validate import consistency

    seed = default_seed("consistency", identity(bsdf), theta) if seed is None else seed
    return consistency.check_bsdf(name or type(bsdf).type_name, bsdf, float(theta), n=int(samples), seed=seed)


def furnace_test(bsdf: Any, thetas: tuple[float, ...] = (0.0, 30.0, 60.0, 85.0), samples: int = 50_000,
                 seed: int | None = None, name: str | None = None) -> list:
    """Directional albedo ρ(θ_i) by quadrature and by Monte Carlo (with its standard error), per angle.

    Each point passes when ρ ≤ 1 and the two estimates agree within their error.

    Examples
    --------
    >>> import brdflab as bl
    >>> pts = bl.furnace_test(bl.RoughConductor(R0=1.0, alpha=0.3), thetas=(0.0, 60.0), samples=20_000)
    >>> [p.passed for p in pts]
    [True, True]
    """
    from brdflab.validate import furnace

    seed = default_seed("furnace", identity(bsdf)) if seed is None else seed
    alpha = float(getattr(bsdf, "alpha_value", 0.0))
    out = []
    for k, th in enumerate(thetas):
        q = furnace.albedo_quadrature(bsdf, float(th), alpha)
        m, se = furnace.albedo_monte_carlo(bsdf, float(th), int(samples), seed=seed + k)
        out.append(furnace.AlbedoPoint(name or type(bsdf).type_name, alpha, float(th), q, m, se))
    return out


def stability_test(seed: int = 0) -> list:
    """The stiff cases (α → 0, grazing, ω_i = ω_o, tangent ω_o, extreme IORs) of the built-in materials."""
    from brdflab.validate import stability

    return stability.run(seed)


def run_battery(*args: Any, **kwargs: Any):
    """The whole battery (what ``brdflab validate`` runs); see :func:`brdflab.validate.battery.run_battery`."""
    from brdflab.validate.battery import run_battery as _run

    return _run(*args, **kwargs)


def emitter_checks(scene, n: int = 100_000, seed: int = 0) -> tuple[list, list]:
    """Chi-square tests of every emitter sampler of ``scene`` (area lights by area, the fused set, the
    environment's directions) and ``sample().pdf`` against the hit pdf; see :mod:`brdflab.validate.emitters`.
    Returns (chi-square results, pdf checks)."""
    from brdflab.integrator.common import area_light_set
    from brdflab.validate import emitters

    chi = []
    for k, em in enumerate(scene.emitters):
        if em.is_environment:
            chi.append(emitters.environment_test(f"environment {k}", em, n, default_seed("env", k, seed)))
        elif not em.is_delta:
            ref, _ = emitters.reference_points(scene, seed=seed)
            chi.append(emitters.area_emitter_test(f"area light {k}", em, ref, n, default_seed("area", k, seed)))
    if area_light_set(scene) is not None:
        ref, _ = emitters.reference_points(scene, seed=seed)
        chi.append(emitters.fused_set_test("fused area lights", scene, ref, n, default_seed("fused", seed)))
    return chi, emitters.pdf_checks(scene, str(getattr(scene, "path", "scene")), seed=seed)


def estimator_agreement(path: Any, **kwargs: Any):
    """ems vs mats vs mis on one scene file; see :func:`brdflab.validate.agreement.estimator_agreement`."""
    from brdflab.validate.agreement import estimator_agreement as _agree

    return _agree(path, **kwargs)
