"""A file of samples of a delta BSDF (``chi2 --samples FILE --against dielectric`` or ``mirror``), per ω_i group.

A delta lobe has no density, so the self-consistency and chi-square tests of
:mod:`brdflab.judges.samples.bsdf_checks` do not apply; the group is judged by
:func:`brdflab.judges.material.delta.judge_samples` instead: every direction is the mirror or Snell's refraction
(within 10⁻⁴: files are printed with a few digits), the reflected fraction against Fresnel's F by an exact
binomial test, and — with weight columns — reflection weights 1 and refraction weights in one of the
radiance-scale conventions that telescope along air–glass–air paths (brdflab's (η_i/η_t)², the course's
η_t/η_i, or 1; the one the file uses is named). The pdf column is ignored (Nori's ``pdf()`` of a discrete lobe
is 0, a sampler may write the lobe probability); a failed sample is a line with ω_o = 0 0 0 or with all
weights 0.
"""

from __future__ import annotations

import numpy as np

from brdflab.judges.material.delta import judge_samples
from brdflab.judges.samples.bsdf_results import GroupResult
from brdflab.judges.samples.tables import Samples

#: Tolerances for directions and weights read from a text file.
FILE_DIRECTION_ATOL = 1e-4
FILE_WEIGHT_RTOL = 1e-3


def check_delta_group(s: Samples, idx: np.ndarray, name: str, ref, thr: float) -> GroupResult:
    """Judge the samples ``idx`` of one ω_i of file ``s`` against the delta BSDF ``ref``."""
    from brdflab.judges.core.guard import CheckedBSDF, PluginFault

    wo = s.wo[idx]
    norm = np.sqrt((wo * wo).sum(axis=1))
    weight = None if s.weight is None else s.weight[idx]
    failed = norm == 0
    if weight is not None:
        failed |= np.all(weight == 0, axis=1)
    wi1 = s.wi[idx].mean(axis=0)
    wi1 = wi1 / max(np.linalg.norm(wi1), 1e-300)
    g = GroupResult(wi1, len(idx), int(s.lines[idx][0]), None)
    wo_n = np.where(failed[:, None], 0.0, wo / np.where(norm > 0, norm, 1.0)[:, None])
    try:
        g.chi2 = judge_samples(CheckedBSDF(ref, name), wi1, wo_n, weight, ~failed, name=f"{name} (file)",
                               params={"wi": "(" + ", ".join(f"{x:.5g}" for x in wi1) + ")"}, threshold=thr,
                               direction_atol=FILE_DIRECTION_ATOL, weight_rtol=FILE_WEIGHT_RTOL, conventions=3)
    except PluginFault as fault:
        g.problems.append(str(fault))
    return g
