"""Consistency checks of any BSDF: weight = eval·cos/pdf, sampled pdf = pdf(), ∫ pdf ≤ 1, reciprocity.

For one incident direction ω_i (θ_i in the x–z plane) and N samples of the BSDF's own sampler:

* **Contract** (through :class:`~brdflab.judges.core.guard.CheckedBSDF`): shapes, finite values, eval ≥ 0,
  pdf ≥ 0, unit ω_o. A violation fails the check with the method, the parameters and the first (ω_i, ω_o).
* **Weight**: |w − f cos θ_o / p| ≤ 10⁻⁵ · max(|f cos θ_o / p|, 10⁻³⁰) (float64), with p the sample's pdf
  (w must be 0 where p = 0 or cos θ_o ≤ 0).
* **Pdf**: the sample's pdf equals ``pdf(ω_i, ω_o)`` (relative 10⁻⁶).
* **Pdf mass**: ∫ p dω over the sphere by the adaptive quadrature of :mod:`brdflab.judges.material.chi2` (bins
  placed by a pilot sample, so any lobe shape); it must be ≤ 1 + 10⁻³ and equal the fraction of
  non-failed samples within 5 binomial standard errors (or 2·10⁻³) plus the quadrature error.
* **Reciprocity**: f(ω_i, ω_o) = f(ω_o, ω_i) (relative 10⁻⁶) on random pairs of the upper hemisphere and
  on the sampled pairs (where f is large). Required unless the class declares ``reciprocal = False``;
  always reported. For a ``has_transmission`` BSDF the pairs cover the sphere and the radiance BTDF's
  generalised form f(ω_i, ω_o)·(η_o/η_i)² = f(ω_o, ω_i) is required (η_o/η_i from ``eta_ratio``; relative to at
  least 10⁻⁹ of the largest f compared, since 1 − F cancels near total internal reflection), and the
  weight is f·|cos θ_o|/p. A ``two_sided`` BSDF may be tested from inside (θ_i in [90°, 180°)).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from brdflab.judges.core.guard import CheckedBSDF, PluginFault, bsdf_params, describe, format_params
from brdflab.judges.core.seeding import bsdf_identity, test_seed
from brdflab.judges.material.chi2 import best_frame, incident
from brdflab.judges.material.furnace import energy_scale
from brdflab.math import warps

WEIGHT_RTOL = 1e-5
PDF_RTOL = 1e-6
RECIPROCITY_RTOL = 1e-6


def _vec(v) -> str:
    return "(" + ", ".join(f"{x:.6g}" for x in np.ravel(v)[:3]) + ")"


@dataclass
class ConsistencyResult:
    """Outcome of the consistency checks for one BSDF and incident angle.

    Attributes
    ----------
    name, theta
        The BSDF and θ_i (degrees).
    max_weight_error
        Largest relative |w − f cos θ_o / p|.
    pdf_integral, pdf_integral_error
        ∫ p dω by quadrature and its error estimate.
    valid_fraction
        Fraction of samples that did not fail (pdf > 0).
    max_reciprocity_error
        Largest relative |f(ω_i, ω_o) − f(ω_o, ω_i)|.
    negative_or_nonfinite
        Count of negative or non-finite values (0 unless the contract was broken).
    max_pdf_error
        Largest relative |sample pdf − pdf()|.
    reciprocal
        Whether reciprocity is required (the class's ``reciprocal`` attribute, default True).
    n, seed, params
        Sample count, the test's seed, the BSDF's parameters.
    fault
        A broken contract or the first offending (ω_i, ω_o) of a failed condition, or None.
    message
        One-line verdict.
    """

    name: str
    theta: float
    max_weight_error: float
    pdf_integral: float
    valid_fraction: float
    max_reciprocity_error: float
    negative_or_nonfinite: int
    max_pdf_error: float = 0.0
    pdf_integral_error: float = 0.0
    reciprocal: bool = True
    n: int = 200_000
    seed: int | None = None
    params: dict = field(default_factory=dict)
    fault: str | None = None
    message: str = ""
    problems: list = field(default_factory=list)

    @property
    def integral_tolerance(self) -> float:
        """Allowed |∫ p dω − valid fraction|: max(5 binomial σ, 2·10⁻³) + 3× the quadrature error."""
        se = np.sqrt(max(self.valid_fraction * (1 - self.valid_fraction), 1e-12) / max(self.n, 1))
        return max(5 * se, 2e-3) + 3 * self.pdf_integral_error

    @property
    def passed(self) -> bool:
        """All checks within tolerance (reciprocity only when required)."""
        return (self.fault is None and self.max_weight_error <= WEIGHT_RTOL and self.max_pdf_error <= PDF_RTOL
                and self.pdf_integral <= 1 + 1e-3 + 3 * self.pdf_integral_error
                and abs(self.pdf_integral - self.valid_fraction) <= self.integral_tolerance
                and (self.max_reciprocity_error <= RECIPROCITY_RTOL or not self.reciprocal)
                and self.negative_or_nonfinite == 0)

    def summary(self) -> str:
        """One line: verdict, the measured errors, and what failed."""
        head = f"{'PASS' if self.passed else 'FAIL'} consistency {self.name} θ_i={self.theta:g}°"
        if self.params:
            head += f" ({format_params(self.params)})"
        if self.fault and not self.problems:
            return f"{head}: {self.fault}"
        rec = f"reciprocity {self.max_reciprocity_error:.1e}" + ("" if self.reciprocal else " (not required)")
        s = (f"{head}: weight err {self.max_weight_error:.1e}, pdf err {self.max_pdf_error:.1e}, "
             f"∫p {self.pdf_integral:.4f} (valid {self.valid_fraction:.4f}), {rec}")
        return s + ("; " + "; ".join(self.problems) if self.problems else "")


def _relerr(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        e = np.abs(a - b) / np.maximum(np.maximum(np.abs(a), np.abs(b)), 1e-30)
    return np.where(a == b, 0.0, e)


def pdf_mass(bsdf, wi1: np.ndarray, pilot_wo: np.ndarray, rng: np.random.Generator, valid: float,
             shape: tuple[int, int] = (16, 24)) -> tuple[float, float]:
    """∫ p(ω_i, ·) dω over the sphere (and its error) on bins placed by ``pilot_wo`` plus uniform directions;
    about other axes when those about the normal miss mass the pilot saw against ``valid``, the fraction of
    samples that did not fail (:func:`~brdflab.judges.material.chi2.best_frame`)."""
    mix = warps.square_to_uniform_sphere(rng.random((max(len(pilot_wo) // 9, 500), 2)))

    def pdf(w):
        return bsdf.pdf(np.ascontiguousarray(np.broadcast_to(wi1, (len(w), 3))), w)

    val, err = best_frame(np.concatenate([pilot_wo, mix]), len(pilot_wo), valid, pdf, *shape,
                          bool(getattr(bsdf, "has_transmission", False)), False, 10**6)[3:5]
    return float(val.sum()), float(err.sum())


def consistency_test(bsdf, theta: float = 45.0, samples: int = 100_000, seed: int | None = None,
                     name: str | None = None, params: dict | None = None) -> ConsistencyResult:
    """Consistency of ``eval``, ``pdf`` and ``sample`` for one incident angle (see module docstring).

    Parameters
    ----------
    bsdf
        Any :class:`brdflab.BSDF`; a class attribute ``reciprocal = False`` makes reciprocity informative.
    theta
        Incident angle θ_i in degrees.
    samples
        Number of samples.
    seed
        Default: derived from the BSDF's type, parameters and θ.
    name, params
        For messages (default: the type name and the BSDF's scalar attributes).

    Returns
    -------
    ConsistencyResult

    Examples
    --------
    >>> import brdflab.judges as v
    >>> from brdflab.bsdf.roughconductor import RoughConductor
    >>> r = v.consistency_test(RoughConductor(0.9, 0.2), theta=30.0, samples=20_000)
    >>> r.passed, r.max_weight_error < 1e-12
    (True, True)
    """
    from brdflab.limits import check_test_arguments

    theta, samples, _ = check_test_arguments(theta, samples, two_sided=bool(getattr(bsdf, "two_sided", False)))
    params = dict(params if params is not None else bsdf_params(bsdf))
    name = name or describe(bsdf)
    if seed is None:
        seed = test_seed("consistency", bsdf_identity(bsdf), params, float(theta))
    b = CheckedBSDF(bsdf, name, params)
    s_obs, s_mass, s_rec = (np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(3))
    n = int(samples)
    if getattr(bsdf, "all_delta", False):  # eval and pdf are 0 by the contract: nothing here can judge it
        r = ConsistencyResult(name, float(theta), float("nan"), float("nan"), float("nan"), float("nan"), 0,
                              reciprocal=b.reciprocal, n=n, seed=seed, params=params,
                              fault="a delta BSDF (all_delta) has no density: judge it with delta_test")
        r.message = r.summary()
        return r
    try:
        return _check(b, name, float(theta), n, seed, params, s_obs, s_mass, s_rec)
    except PluginFault as fault:
        r = ConsistencyResult(name, float(theta), float("nan"), float("nan"), float("nan"), float("nan"), 0,
                              reciprocal=b.reciprocal, n=n, seed=seed, params=params, fault=str(fault))
        r.message = r.summary()
        return r


def _check(b: CheckedBSDF, name, theta, n, seed, params, rng, rng_mass, rng_rec) -> ConsistencyResult:
    from brdflab.judges.core.seeding import test_azimuth

    wi1 = incident(theta, round(test_azimuth(seed), 3))
    wi = np.ascontiguousarray(np.broadcast_to(wi1, (n, 3)))
    s = b.sample(wi, rng.random((n, 3)))
    # The samples in the density: a BSDF mixing delta and smooth lobes (has_delta, not all_delta) returns its
    # delta samples with a discrete probability as pdf and a weight that is not f·cos/p: they are left out here
    # (their frequency is the chi-square test's, their energy the furnace's).
    ok = (s.pdf > 0) if s.delta is None else (s.pdf > 0) & ~s.delta
    f = b.eval(wi, s.wo)
    p_eval = b.pdf(wi, s.wo)
    transmits = bool(getattr(b.inner, "has_transmission", False))
    cos_o = np.abs(s.wo[:, 2]) if transmits else s.wo[:, 2]  # weight = f·|cos θ_o|/p for transmission
    good = ok & (cos_o > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        expect = np.where(good[:, None], f * (cos_o / np.where(ok, s.pdf, 1.0))[:, None], 0.0)
    werr = _relerr(s.weight, expect).max(axis=1)
    if s.delta is not None:
        werr = np.where(s.delta, 0.0, werr)
    perr = np.where(ok, _relerr(s.pdf, p_eval), 0.0)
    problems = []

    def first(mask, what):
        i = int(np.argmax(mask))
        problems.append(f"{what} first at wi={_vec(wi1)}, wo={_vec(s.wo[i])}")

    if (werr > WEIGHT_RTOL).any():
        i = int(np.argmax(werr > WEIGHT_RTOL))
        first(werr > WEIGHT_RTOL, f"sample weight {_vec(s.weight[i])} ≠ eval·cos/pdf {_vec(expect[i])}")
    if (perr > PDF_RTOL).any():
        i = int(np.argmax(perr > PDF_RTOL))
        first(perr > PDF_RTOL, f"sample pdf {s.pdf[i]:.6g} ≠ pdf() {p_eval[i]:.6g}")
    pilot = s.wo[ok][: max(n // 4, 2000)]
    integral, ierr = pdf_mass(b, wi1, pilot, rng_mass, float(ok.mean()))
    # Reciprocity on uniform upper-hemisphere pairs and on the sampled pairs (where f matters).
    m = min(n, 20_000)
    pairs = warps.square_to_uniform_sphere if transmits else warps.square_to_uniform_hemisphere
    a, c = pairs(rng_rec.random((m, 2))), pairs(rng_rec.random((m, 2)))
    sw = s.wo[good][:m]
    A, C = np.concatenate([a, np.broadcast_to(wi1, sw.shape)]), np.concatenate([c, sw])
    fac, fca = b.eval(A, C), b.eval(C, A)
    if transmits:  # the radiance BTDF: f(ω_i, ω_o)·(η_o/η_i)² = f(ω_o, ω_i) (generalised reciprocity)
        fac = fac * energy_scale(b, A, C)[:, None]
        # relative to 10⁻⁹ of the largest f at least: 1 − F cancels near total internal reflection, where f → 0
        floor = 1e-9 * float(max(fac.max(), fca.max(), 0.0)) if len(fac) else 0.0
        with np.errstate(divide="ignore", invalid="ignore"):
            rec = (np.abs(fac - fca) / np.maximum(np.maximum(np.abs(fac), np.abs(fca)), max(floor, 1e-30))).max(axis=1)
    else:
        rec = _relerr(fac, fca).max(axis=1)
    if len(rec) and rec.max() > RECIPROCITY_RTOL:
        i = int(np.argmax(rec))
        what = "f(wi, wo)·(η_o/η_i)² ≠ f(wo, wi)" if transmits else "f(wi, wo) ≠ f(wo, wi)"
        problems.append(f"{what} by {rec[i]:.1e} at wi={_vec(A[i])}, wo={_vec(C[i])}"
                        + ("" if b.reciprocal else " (declared non-reciprocal: not required)"))
    r = ConsistencyResult(name, theta, float(werr.max()), integral, float(ok.mean()),
                          float(rec.max()) if len(rec) else 0.0, 0, float(perr.max()), ierr, b.reciprocal, n,
                          seed, params)
    if integral > 1 + 1e-3 + 3 * ierr:
        problems.append(f"∫ p dω = {integral:.5f} > 1")
    elif abs(integral - r.valid_fraction) > r.integral_tolerance:
        problems.append(f"∫ p dω = {integral:.5f} but {r.valid_fraction:.5f} of the samples are valid (the pdf "
                        "does not describe the sampler's mass)")
    r.problems = problems
    if problems and not (len(problems) == 1 and "not required" in problems[0]):
        r.fault = problems[0]
    r.message = r.summary()
    return r


def check_bsdf(name: str, bsdf, theta_deg: float, n: int = 200_000, seed: int | None = None,
               params: dict | None = None) -> ConsistencyResult:
    """Run the consistency checks for ``bsdf`` at incident angle ``theta_deg`` (older positional form)."""
    return consistency_test(bsdf, theta=theta_deg, samples=n, seed=seed, name=name, params=params)
