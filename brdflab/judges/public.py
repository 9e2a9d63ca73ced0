"""The judges' public functions (``bl.chi2_test``, ``bl.warp_chi2_test``, ``bl.emitter_checks``,
``bl.estimator_agreement``, …): keyword parameters in, a result object out, never a printout. Each draws from
its own random stream (:func:`default_seed`, :func:`brdflab.judges.core.seeding.test_seed`).
"""


from __future__ import annotations

import zlib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from brdflab.judges.core.seeding import bsdf_identity, test_seed
from brdflab.judges.material import chi2 as _c2
from brdflab.judges.material.chi2 import SIGNIFICANCE, Chi2Result


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


def chi2_test(bsdf, theta: float = 30.0, samples: int = 100_000, seed: int | None = None,
              threshold: float | None = None, name: str | None = None, params: dict | None = None, *,
              count: int | None = None, output: str | Path | None = None, force: bool = False) -> Chi2Result:
    """Chi-square goodness of fit of ``bsdf.sample`` against ``bsdf.pdf`` for one incident angle.

    Bins are placed by a pilot sample of the BSDF's own sampler on an independent stream (equal
    probability wherever the lobe is); expected counts come from integrating ``pdf`` over every bin by
    adaptive quadrature; failed samples (pdf 0) form one more category whose expectation is 1 − ∫ p dω.
    See :mod:`brdflab.judges.material.chi2`.

    Parameters
    ----------
    bsdf
        Any :class:`brdflab.BSDF`, a user's plugin included.
    theta
        Incident angle θ_i in degrees (in [0, 90); up to 180 for a ``two_sided`` BSDF, ω_i inside). A delta BSDF
        (``all_delta``) is judged by :func:`brdflab.judges.material.delta.delta_test` instead (a
        :class:`~brdflab.judges.material.delta.DeltaResult`).
    samples
        Number of observed samples (the pilot adds a quarter more).
    seed
        Default: derived from the BSDF's type, its parameters and θ, so that two configurations never share
        random numbers.
    threshold
        Per-test significance (the test passes when p > threshold).
    name, params
        For messages (default: the type name and the BSDF's scalar attributes).
    count
        The command line's name (``-n/--count``) for ``samples``; wins when given.
    output, force
        A folder for the chi-square page (``-o``), checked before the test.

    Returns
    -------
    Chi2Result
        Statistic, dof, p-value, ``passed``, the observed and expected histograms, the seed, ``message``.

    Examples
    --------
    >>> import brdflab.judges as v
    >>> from brdflab.bsdf.roughconductor import RoughConductor
    >>> r = v.chi2_test(RoughConductor(R0=0.5, alpha=0.1), theta=30.0, samples=20_000)
    >>> r.passed, r.observed.shape == r.expected.shape
    (True, True)
    """
    from brdflab.judges.core.guard import bsdf_params, describe
    from brdflab.limits import check_test_arguments

    theta, samples, threshold = check_test_arguments(theta, samples if count is None else count, threshold,
                                                     two_sided=bool(getattr(bsdf, "two_sided", False)))
    params = dict(params if params is not None else bsdf_params(bsdf))
    name = name or describe(bsdf)
    if output is not None:
        from brdflab.outputs import prepare_folder
        from brdflab.pages.validation import VALIDATION_FILES

        prepare_folder(Path(output), list(VALIDATION_FILES), [], force)  # before the work
    if seed is None:
        seed = test_seed("chi2", bsdf_identity(bsdf), params, float(theta))
    if getattr(bsdf, "all_delta", False):  # no density to bin: the delta judge (exact directions, binomial)
        from brdflab.judges.material.delta import delta_test

        result = delta_test(bsdf, float(theta), int(samples), seed=seed, name=name, params=params,
                            threshold=SIGNIFICANCE if threshold is None else threshold)
    else:
        result = _c2.bsdf_test(name, bsdf, float(theta), int(samples), seed=seed, params={**params, "theta": theta},
                               threshold=SIGNIFICANCE if threshold is None else threshold)
    if output is not None:
        from brdflab.judges.material.battery import Battery
        from brdflab.outputs import record_outputs
        from brdflab.pages.validation import VALIDATION_FILES, write_validation_report

        write_validation_report(Battery(chi2=[result], threshold=result.threshold), Path(output),
                                title=f"brdflab chi-square: {name}")
        record_outputs(Path(output), list(VALIDATION_FILES))
    return result


def warp_chi2_test(warp: Callable, pdf: Callable, samples: int = 200_000, seed: int | None = None,
                   threshold: float | None = None, name: str = "warp") -> Chi2Result:
    """Chi-square test of a square-to-sphere warp ``warp(u) -> (N, 3)`` against ``pdf(w) -> (N,)``.

    Examples
    --------
    >>> import brdflab as bl
    >>> r = bl.warp_chi2_test(bl.warps.square_to_cosine_hemisphere, bl.warps.square_to_cosine_hemisphere_pdf,
    ...                       samples=50_000)
    >>> r.passed
    True
    """
    from brdflab.limits import check_test_arguments

    _, samples, threshold = check_test_arguments(None, samples, threshold)
    seed = test_seed("warp", name) if seed is None else seed
    return _c2.warp_test(name, warp, pdf, int(samples), seed=seed,
                         threshold=SIGNIFICANCE if threshold is None else threshold)


def check_samples(*args, **kwargs):
    """Chi-square and pdf/weight comparison of external samples
    (:func:`brdflab.judges.samples.bsdf_checks.check_samples`)."""
    from brdflab.judges.samples.bsdf_checks import check_samples as _check

    return _check(*args, **kwargs)


def emitter_checks(scene, n: int = 100_000, seed: int = 0) -> tuple[list, list]:
    """Chi-square tests of every emitter sampler of ``scene`` (area lights by area, the fused set, the
    environment's directions) and ``sample().pdf`` against the hit pdf; see :mod:`brdflab.judges.lights.samplers`.
    Returns (chi-square results, pdf checks)."""
    from brdflab.integrator.common import area_light_set
    from brdflab.judges.lights import samplers as emitters

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
    """ems vs mats vs mis on one scene file; see :func:`brdflab.judges.estimators.agreement.estimator_agreement`."""
    from brdflab.judges.estimators.agreement import estimator_agreement as _agree

    return _agree(path, **kwargs)
