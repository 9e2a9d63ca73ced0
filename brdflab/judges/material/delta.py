"""The judge of delta BSDFs (mirror, dielectric, a user's delta plugin): lobe frequencies, directions, weights.

A chi-square test cannot see a Dirac delta (``pdf`` is 0 everywhere), so a BSDF whose class declares
``all_delta = True`` is judged here instead, for one incident direction ω_i (θ_i, at the azimuth
``test_azimuth(seed)`` as every BSDF test; above 90°: ω_i inside, for ``two_sided`` materials) and N samples on
the test's own random stream:

* **Reference model** (independent of the material's code): the mirror direction R = (−ω_x, −ω_y, ω_z); for a
  ``has_transmission`` material with indices ``int_ior``/``ext_ior`` (or ``intIOR``/``extIOR``), Fresnel's
  F = F_dielectric(cos θ_i; ext, int) (spec §11.1) and Snell's vector form T = −η ω_i + (η c − √(1 − η²(1 − c²))) n
  with n = ±z on ω_i's side, c = |cos θ_i|, η = η_i/η_t (PBR eq. 8.8, not the material's component form); a
  material without transmission reflects with probability 1. A one-sided material (``two_sided`` False) must
  fail every sample with cos θ_i ≤ 0 (weight 0).
* **Directions exact**: every valid sample is R or T within 10⁻⁹; anything else fails the test.
* **Weights exact**: 1 for R and (η_i/η_t)² for T (the radiance scale of brdflab's contract; relative 10⁻⁹);
  the sample's ``pdf`` is the lobe's probability (F or 1 − F); ``delta`` is True; ``eval`` and ``pdf`` of the
  sampled directions are 0. The energy weight·(η_o/η_i)² (:meth:`BSDF.eta_ratio`) must be ≤ 1 (white furnace:
  reflection + transmission).
* **Frequencies**: the number of reflections k of n valid samples against Binomial(n, F) by an exact two-sided
  binomial test (``scipy.stats.binomtest``); F ∈ {0, 1} (total internal reflection, a mirror) requires
  k = n·F exactly. Rejected at the battery's (Šidák-corrected) threshold.

False alarms (measured 2026-12-04, tests/test_transmission_judges.py): 23 of 2 000 correct dielectric runs at
0.01 (1.15 %; θ_i ∈ {0, 30, 60, 85, 150}°, 20 000 samples), 106 of 2 000 at 0.05; the exact checks never fired.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from brdflab.bsdf.fresnel import fresnel_dielectric
from brdflab.judges.core.guard import CheckedBSDF, PluginFault, bsdf_params, describe
from brdflab.judges.material.chi2 import SIGNIFICANCE, Chi2Result, incident
from brdflab.judges.material.furnace import energy_scale

#: Tolerances of the exact checks (float64 round-off of a few operations is ~1e-16).
DIRECTION_ATOL = 1e-9
WEIGHT_RTOL = 1e-9


@dataclass
class DeltaResult(Chi2Result):
    """Outcome of :func:`delta_test` (a :class:`Chi2Result`, so the battery, pages and CLI list it with the
    chi-square tests): ``statistic`` is the count of reflections, ``p_value`` the binomial test's.

    Attributes
    ----------
    reflected, refracted
        Counts of valid samples in each lobe.
    fresnel
        The reference probability of reflection F.
    max_direction_error, max_weight_error
        Largest |ω_o − reference| and relative weight error over the valid samples.
    energy
        Largest weight·(η_o/η_i)² (≤ 1 for a passive material).
    """

    reflected: int = 0
    refracted: int = 0
    fresnel: float = float("nan")
    max_direction_error: float = float("nan")
    max_weight_error: float = float("nan")
    energy: float = float("nan")
    delta: bool = True
    #: The radiance scale the refraction weights follow (:data:`CONVENTIONS`).
    convention: str = ""

    def summary(self) -> str:
        """One line: verdict, the binomial p-value and the exact checks."""
        head = f"{'PASS' if self.passed else 'FAIL'} delta {self.name}"
        if self.params:
            from brdflab.judges.core.guard import format_params

            head += f" ({format_params(self.params)})"
        body = (f": reflected {self.reflected} of {self.reflected + self.refracted} (F = {self.fresnel:.5g}, binomial "
                f"p = {self.p_value:.4g}, threshold {self.threshold:.2g}); direction err "
                f"{self.max_direction_error:.1e}, weight err {self.max_weight_error:.1e}, energy ≤ {self.energy:.6f}")
        return head + body + (f"; {self.fault}" if self.fault else "")


def iors(bsdf) -> tuple[float, float] | None:
    """(int, ext) indices of a transmissive delta BSDF (``int_ior``/``ext_ior`` or ``intIOR``/``extIOR``)."""
    inner = getattr(bsdf, "inner", bsdf)
    for a, b in (("int_ior", "ext_ior"), ("intIOR", "extIOR")):
        if hasattr(inner, a) and hasattr(inner, b):
            return float(getattr(inner, a)), float(getattr(inner, b))
    return None


def reference_lobes(wi1: np.ndarray, int_ior: float, ext_ior: float) -> tuple[float, np.ndarray, np.ndarray, float]:
    """(F, R, T, (η_i/η_t)²) for one ω_i: Fresnel, the mirror and the Snell direction (vector form)."""
    c = float(wi1[2])
    F = float(fresnel_dielectric(np.array([c]), ext_ior, int_ior)[0])
    eta_i, eta_t = (ext_ior, int_ior) if c >= 0 else (int_ior, ext_ior)
    eta = eta_i / eta_t
    n = np.array([0.0, 0.0, 1.0 if c >= 0 else -1.0])
    k = 1.0 - eta * eta * (1.0 - c * c)
    t = -eta * wi1 + (eta * abs(c) - np.sqrt(max(k, 0.0))) * n
    return F, wi1 * np.array([-1.0, -1.0, 1.0]), t, eta * eta


def delta_test(bsdf, theta: float = 30.0, samples: int = 100_000, seed: int | None = None, name: str | None = None,
               params: dict | None = None, threshold: float = SIGNIFICANCE) -> DeltaResult:
    """Judge a delta BSDF at one incident angle (see the module docstring).

    Parameters
    ----------
    bsdf
        A BSDF whose class declares ``all_delta = True`` (a user's plugin included).
    theta
        θ_i in degrees, in [0, 180): above 90° ω_i is inside (for two-sided materials).
    samples, seed, name, params, threshold
        As for the chi-square tests (the seed defaults to one derived from the BSDF and θ).

    Examples
    --------
    >>> import brdflab as bl
    >>> from brdflab.judges.material.delta import delta_test
    >>> r = delta_test(bl.Dielectric(intIOR=1.5, extIOR=1.0), theta=60.0, samples=20_000)
    >>> r.passed, r.max_direction_error < 1e-12, round(r.fresnel, 4)
    (True, True, 0.0892)
    """
    from brdflab.judges.core.seeding import bsdf_identity, test_azimuth, test_seed

    params = dict(params if params is not None else bsdf_params(bsdf))
    name = name or describe(bsdf)
    if seed is None:
        seed = test_seed("delta", bsdf_identity(bsdf), params, float(theta))
    b = CheckedBSDF(bsdf, name, params)
    phi = round(test_azimuth(seed), 3)  # each test at its own incident azimuth, as the chi-square tests
    shown = {**{k: v for k, v in params.items() if k != "phi"}, "theta": float(theta), "phi": phi}
    try:
        return _judge(b, float(theta), phi, int(samples), seed, name, shown, threshold)
    except PluginFault as fault:
        r = DeltaResult(name, shown, float("nan"), 0, 0.0, threshold, seed=seed, n=int(samples), fault=str(fault))
        r.message = r.summary()
        return r


def _judge(b: CheckedBSDF, theta: float, phi: float, n: int, seed: int, name: str, shown: dict,
           threshold: float) -> DeltaResult:
    wi1 = incident(theta, phi)
    wi = np.ascontiguousarray(np.broadcast_to(wi1, (n, 3)))
    s = b.sample(wi, np.random.default_rng(seed).random((n, 3)))
    problems = []
    if s.delta is None or not np.all(s.delta):
        problems.append("samples of an all_delta BSDF must have delta = True")
    valid = s.pdf > 0
    if len(s.wo[valid]):
        ev, pd = b.eval(wi[valid], s.wo[valid]), b.pdf(wi[valid], s.wo[valid])
        if np.any(ev != 0) or np.any(pd != 0):
            problems.append("eval/pdf of a delta direction must be 0")
    return judge_samples(b, wi1, s.wo, s.weight, valid, pdf=s.pdf, name=name, params=shown, seed=seed,
                         threshold=threshold, problems=problems)


#: Radiance scales at refraction accepted in a file of samples (all telescope to 1 along air–glass–air paths,
#: spec §10.4): name → weight of a refraction as a function of η = η_i/η_t. brdflab's own judge accepts the first.
CONVENTIONS = {"(η_i/η_t)² (radiance, brdflab)": lambda eta: eta * eta,
               "η_t/η_i (the course's Nori, spec §10.4)": lambda eta: 1.0 / eta,
               "1 (no radiance scale)": lambda eta: np.ones_like(eta)}


def judge_samples(b, wi1: np.ndarray, wo: np.ndarray, weight: np.ndarray | None, valid: np.ndarray, *,
                  pdf: np.ndarray | None = None, name: str = "", params: dict | None = None, seed: int | None = None,
                  threshold: float = SIGNIFICANCE, problems: list[str] | None = None,
                  direction_atol: float = DIRECTION_ATOL, weight_rtol: float = WEIGHT_RTOL,
                  conventions: int = 1) -> DeltaResult:
    """Judge samples (ω_o, weights) of a delta BSDF ``b`` for one ω_i against the reference model.

    ``valid`` marks the samples that did not fail; ``pdf`` (the lobe probabilities), ``weight`` (N, 3) may be
    None (not checked). The first ``conventions`` entries of :data:`CONVENTIONS` are accepted for refraction
    weights (the one most samples follow is named); the energy check applies to brdflab's. Used by
    :func:`delta_test` and for files of samples (:mod:`brdflab.judges.samples.bsdf_checks`).
    """
    problems = list(problems or [])
    n = len(wo)
    transmits = bool(getattr(b, "has_transmission", False))
    one_sided = not getattr(b, "two_sided", False)
    if transmits:
        ior = iors(b)
        if ior is None:
            return _fault(name, params, seed, n, threshold, "a transmissive delta BSDF needs int_ior and ext_ior "
                          "attributes for the reference (Fresnel, Snell)")
        F, R, T, w_t = reference_lobes(wi1, *ior)
    else:
        F, R, T, w_t = 1.0, wi1 * np.array([-1.0, -1.0, 1.0]), None, 1.0
    if one_sided and wi1[2] <= 0:
        if valid.any() or (weight is not None and np.any(weight != 0)):
            problems.append("a one-sided BSDF produced samples with cos θ_i ≤ 0")
        F = float("nan")
    wo = wo[valid]
    err_r = np.abs(wo - R).max(axis=1) if len(wo) else np.zeros(0)
    err_t = np.abs(wo - T).max(axis=1) if (T is not None and len(wo)) else np.full(len(wo), np.inf)
    is_r = err_r <= err_t
    dir_err = np.where(is_r, err_r, err_t)
    k, m = int(is_r.sum()), int(valid.sum())
    if len(wo) and dir_err.max() > direction_atol:
        i = int(np.argmax(dir_err))
        problems.append(f"ω_o = {_vec(wo[i])} is neither the mirror {_vec(R)} nor Snell's "
                        f"{'(none)' if T is None else _vec(T)} direction")
    w_err_max, e_max, used = 0.0, 0.0, next(iter(CONVENTIONS))
    if weight is not None and len(wo):
        w = weight[valid]
        eta = np.sqrt(w_t)
        best = None
        for label, fn in list(CONVENTIONS.items())[:max(conventions, 1)]:
            expect = np.where(is_r, 1.0, fn(eta))[:, None]
            err = np.abs(w - expect) / expect
            if best is None or (err.max(axis=1) <= weight_rtol).sum() > (best[1].max(axis=1) <= weight_rtol).sum():
                best = (label, err, expect)
        used, w_err, expect = best
        w_err_max = float(w_err.max())
        if w_err_max > weight_rtol:
            i = int(np.argmax(w_err.max(axis=1)))
            problems.append(f"weight {w[i, 0]:.6g} ≠ {expect[i, 0]:.6g} ({'reflection' if is_r[i] else 'refraction'}"
                            f"; refraction weights {used})")
        energy = w * energy_scale(b, np.broadcast_to(wi1, wo.shape), wo)[:, None] if transmits else w
        e_max = float(energy.max())
        if used == next(iter(CONVENTIONS)) and e_max > 1 + 1e-9 + weight_rtol:
            problems.append(f"weight·(η_o/η_i)² = {e_max:.6g} > 1: the material creates energy")
    if pdf is not None and len(wo):
        p_expect = np.where(is_r, F, 1.0 - F)
        p_err = np.abs(pdf[valid] - p_expect)
        if p_err.max() > max(1e-9, weight_rtol):
            i = int(np.argmax(p_err))
            problems.append(f"sample pdf {pdf[valid][i]:.6g} ≠ the lobe's probability {p_expect[i]:.6g}")
    pval = _binomial_p(k, m, F)
    if m == 0 and not (one_sided and wi1[2] <= 0):
        problems.append("no valid sample: nothing to test")
    frac = float(valid.mean()) if n else 0.0
    r = DeltaResult(name, dict(params or {}), float(k), 1, pval, threshold, integral=frac, valid_fraction=frac,
                    seed=seed, n=n, fault=problems[0] if problems else None, reflected=k, refracted=m - k,
                    fresnel=F, max_direction_error=float(dir_err.max()) if len(wo) else 0.0,
                    max_weight_error=w_err_max, energy=e_max)
    r.convention = used
    r.message = r.summary()
    return r


def _binomial_p(k: int, m: int, F: float) -> float:
    """Two-sided exact binomial p-value of k successes in m trials with probability F (1 when nothing to test
    and the sampler rightly failed, e.g. a one-sided mirror from below)."""
    if not np.isfinite(F):
        return 1.0
    if m == 0:
        return 0.0
    if F <= 0.0 or F >= 1.0:
        return 1.0 if k == round(m * F) else 0.0
    from scipy.stats import binomtest

    return float(binomtest(k, m, F).pvalue)


def _fault(name, shown, seed, n, threshold, what) -> DeltaResult:
    r = DeltaResult(name, shown, float("nan"), 0, 0.0, threshold, seed=seed, n=n, fault=what)
    r.message = r.summary()
    return r


def _vec(v) -> str:
    return "(" + ", ".join(f"{x:.6g}" for x in np.ravel(v)[:3]) + ")"
