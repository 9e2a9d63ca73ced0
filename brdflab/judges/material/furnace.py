"""White furnace and energy conservation: directional albedo ρ(θ_i) = ∫ f(ω_i, ω_o) cos θ_o dω_o, for any BSDF.

With R0 = 1 (conductor) or k_d = 1 (substrate) a physically plausible model must keep ρ ≤ 1; the
single-scattering microfacet models lose energy at high roughness (light that would scatter between
microfacets is dropped), which the report quantifies as 1 − ρ.

Two independent estimates must agree:

* **Quadrature** (no assumption about the lobe): the upper hemisphere is cut into equal-probability bins
  placed by a pilot sample of the BSDF's own sampler (:func:`brdflab.judges.material.chi2.pilot_bins`, mixed with
  uniform directions), and luminance(f)·cos θ_o is integrated over every bin by the adaptive Gauss–Legendre
  quadrature of :func:`brdflab.judges.material.chi2.integrate_sphere_bins` (cells graded towards the lobe, split
  until the 4- and 8-point rules agree), which also gives an error estimate. The sampler only decides
  where the cells are fine; the value comes from ``eval`` alone.
* **Monte Carlo**: the mean of the BSDF's own sample weights f cos θ_o / p, with its standard error.

For a ``has_transmission`` BSDF both estimates cover the whole sphere and weigh each direction by the energy
scale (η_o/η_i)² (:func:`energy_scale`): ρ is then reflection + transmission, which must be ≤ 1.

The check fails — with a message, never silently — when ρ exceeds 1 beyond its uncertainty, or when the
two estimates differ by more than 4 combined standard errors (+ 5·10⁻⁴): then ``eval``, ``pdf`` and
``sample`` do not describe the same BSDF (e.g. a sampler that misses part of the lobe, a weight without
the cosine, an unnormalised lobe).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from brdflab.judges.core.guard import CheckedBSDF, PluginFault, describe, format_params
from brdflab.judges.core.results import CaseList
from brdflab.judges.core.seeding import bsdf_identity, test_azimuth, test_seed
from brdflab.judges.material.chi2 import incident, integrate_sphere_bins, pilot_bins, to_angles

#: Luminance weights (Rec. 709).
LUMINANCE = np.array([0.212671, 0.715160, 0.072169])


@dataclass
class AlbedoPoint:
    """Directional albedo of one BSDF at one incident angle (the furnace test's result).

    Attributes
    ----------
    name, alpha, theta
        The BSDF, its roughness (None without one) and θ_i in degrees.
    quadrature, quad_error
        ρ by adaptive quadrature and the quadrature's error estimate.
    monte_carlo, mc_stderr
        ρ as the mean sample weight and its standard error.
    seed, params
        The test's seed and the BSDF's parameters.
    delta_part, delta_stderr
        The energy of the delta lobes of a BSDF that mixes delta and smooth lobes (the mean weight of its
        delta samples; 0 otherwise): not in either estimate above (the quadrature of f cannot see a delta), but
        counted in ρ ≤ 1.
    fault
        Why the check could not run (a plugin broke its contract), or None.
    message
        One-line verdict; says which condition failed.
    """

    name: str
    alpha: float | None
    theta: float
    quadrature: float
    monte_carlo: float
    mc_stderr: float
    quad_error: float = 0.0
    seed: int | None = None
    params: dict = field(default_factory=dict)
    fault: str | None = None
    message: str = ""
    delta_part: float = 0.0
    delta_stderr: float = 0.0

    @property
    def sigma(self) -> float:
        """Combined standard error of the difference quadrature − Monte Carlo."""
        return float(np.hypot(self.mc_stderr, self.quad_error))

    @property
    def energy_ok(self) -> bool:
        """ρ ≤ 1: quadrature within 10⁻³ + 3× its error, Monte Carlo within 4σ + 10⁻³."""
        d, de = self.delta_part, self.delta_stderr
        return bool(self.quadrature + d <= 1 + 1e-3 + 3 * self.quad_error + 4 * de
                    and self.monte_carlo + d <= 1 + 4 * float(np.hypot(self.mc_stderr, de)) + 1e-3)

    @property
    def agree(self) -> bool:
        """Quadrature and Monte Carlo agree within 4 combined standard errors + 5·10⁻⁴."""
        return abs(self.quadrature - self.monte_carlo) <= 4 * self.sigma + 5e-4

    @property
    def passed(self) -> bool:
        """No fault, ρ ≤ 1 and the two estimates agree."""
        return self.fault is None and self.energy_ok and self.agree

    def summary(self) -> str:
        """One line with both estimates, their uncertainties and the verdict."""
        a = f" α={self.alpha:g}" if isinstance(self.alpha, float | int) and f"α={self.alpha:g}" not in self.name else ""
        head = f"{'PASS' if self.passed else 'FAIL'} furnace {self.name}{a} θ_i={self.theta:g}°"
        if self.fault:
            return f"{head}: {self.fault}"
        s = (f"{head}: ρ quadrature {self.quadrature:.5f} ± {self.quad_error:.1e}, Monte Carlo "
             f"{self.monte_carlo:.5f} ± {self.mc_stderr:.1e}")
        if self.delta_part:
            s += f" (smooth lobes), delta lobes {self.delta_part:.5f} ± {self.delta_stderr:.1e}"
        if not self.agree:
            s += (f"; the estimates DISAGREE by {abs(self.quadrature - self.monte_carlo) / max(self.sigma, 1e-12):.0f}σ"
                  " (eval, pdf and sample do not describe the same BSDF)")
        if not self.energy_ok:
            s += "; ρ > 1: the BSDF creates energy"
        return s


def _luminance(rgb: np.ndarray) -> np.ndarray:
    return rgb @ LUMINANCE


def albedo_quadrature_with_error(bsdf, theta_deg: float, seed: int = 0, pilot: int = 5_000,
                                 shape: tuple[int, int] = (8, 16), phi_deg: float = 0.0) -> tuple[float, float]:
    """ρ(θ_i) (luminance) by adaptive quadrature over pilot-placed bins, and its error estimate."""
    b = bsdf if isinstance(bsdf, CheckedBSDF) else CheckedBSDF(bsdf)
    wi1 = incident(theta_deg, phi_deg)
    s_pilot, s_mix = np.random.SeedSequence(seed).spawn(2)
    wi = np.ascontiguousarray(np.broadcast_to(wi1, (pilot, 3)))
    r = b.sample(wi, np.random.default_rng(s_pilot).random((pilot, 3)))
    from brdflab.math.warps import square_to_cosine_hemisphere

    transmits = bool(getattr(b.inner, "has_transmission", False))
    if transmits:  # the whole sphere, each direction's energy weighted by (η_o/η_i)² (see energy_scale)
        from brdflab.math.warps import square_to_uniform_sphere as mixer
    else:
        mixer = square_to_cosine_hemisphere
    mix = mixer(np.random.default_rng(s_mix).random((pilot // 9, 2)))
    pts = np.concatenate([r.wo[(r.pdf > 0) & ((r.wo[:, 2] != 0) if transmits else (r.wo[:, 2] > 0))], mix])
    th, ph = to_angles(pts, np.array([0.0, 0.0, 1.0]))
    te, pe = pilot_bins(th, ph, *shape, split_horizon=transmits)
    if not transmits:
        te = np.minimum(te, np.pi / 2)  # f = 0 below the horizon: those strips get zero width

    def integrand(wo):
        wi = np.ascontiguousarray(np.broadcast_to(wi1, (len(wo), 3)))
        f = b.eval(wi, wo)
        if transmits:
            return _luminance(f) * np.abs(wo[:, 2]) * energy_scale(b, wi, wo)
        return _luminance(f) * np.maximum(wo[:, 2], 0.0)

    val, err = integrate_sphere_bins(integrand, te, pe, n=10**7)
    return float(val.sum()), float(err.sum())


def albedo_quadrature(bsdf, theta_deg: float, alpha: float | None = None, seed: int = 0) -> float:
    """ρ(θ_i) by quadrature (see module docstring); ``alpha`` is unused (kept for old callers)."""
    return albedo_quadrature_with_error(bsdf, theta_deg, seed)[0]


def albedo_monte_carlo(bsdf, theta_deg: float, n: int = 100_000, seed: int = 0,
                       phi_deg: float = 0.0) -> tuple[float, float]:
    """ρ(θ_i) as the mean sample weight (luminance) and its standard error (delta lobes included)."""
    smooth, se, delta, dse = albedo_monte_carlo_parts(bsdf, theta_deg, n, seed, phi_deg)
    w_se = float(np.hypot(se, dse))  # an upper bound: the two parts of one sample are exclusive
    return smooth + delta, w_se


def albedo_monte_carlo_parts(bsdf, theta_deg: float, n: int = 100_000, seed: int = 0,
                             phi_deg: float = 0.0) -> tuple[float, float, float, float]:
    """ρ(θ_i) in two parts, each the mean of the sample weights (luminance) times the indicator of its
    samples, with its standard error: (smooth lobes, error, delta lobes, error). The smooth part is what
    ∫ f cos θ_o dω_o (:func:`albedo_quadrature`) computes; the delta part is 0 unless the BSDF mixes delta and
    smooth lobes (samples flagged ``delta``)."""
    rng = np.random.default_rng(seed)
    wi = np.ascontiguousarray(np.broadcast_to(incident(theta_deg, phi_deg), (n, 3)))
    s = bsdf.sample(wi, rng.random((n, 3)))
    w = _luminance(s.weight)
    if getattr(bsdf, "has_transmission", False):
        w = w * energy_scale(bsdf, wi, s.wo)
    d = np.zeros(n, bool) if s.delta is None else np.asarray(s.delta, bool)
    ws, wd = np.where(d, 0.0, w), np.where(d, w, 0.0)
    return (float(ws.mean()), float(ws.std(ddof=1) / np.sqrt(n)), float(wd.mean()),
            float(wd.std(ddof=1) / np.sqrt(n)))


def energy_scale(bsdf, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """(η_o/η_i)² (N,): the energy a radiance weight carries across an interface (1 for reflection).

    A transmissive BSDF's f is the radiance BTDF, whose refracted weight is (η_i/η_o)² times the transmitted
    fraction of the energy; the white furnace of such a material is reflection + transmission
    ∫ f |cos θ_o| (η_o/η_i)² dω_o ≤ 1 (= 1 for a smooth, lossless interface).
    """
    ratio = getattr(bsdf, "eta_ratio", None)  # a duck-typed plugin without it: one medium (1)
    return np.ones(len(wi)) if ratio is None else np.asarray(ratio(wi, wo), dtype=np.float64) ** 2


def furnace_point(bsdf, *, theta: float = 0.0, samples: int = 100_000, seed: int | None = None,
                  name: str | None = None, params: dict | None = None, alpha: float | None = None) -> AlbedoPoint:
    """White-furnace check of one BSDF at one incident angle: ρ by quadrature and by Monte Carlo.

    Parameters
    ----------
    bsdf
        Any :class:`brdflab.BSDF` (a user's plugin included); called through
        :class:`~brdflab.judges.core.guard.CheckedBSDF`.
    theta
        Incident angle θ_i in degrees (ω_i in the x–z plane).
    samples
        Monte Carlo samples.
    seed
        Default: derived from the BSDF's type, parameters and θ (:func:`~brdflab.judges.core.seeding.test_seed`).
    name, params, alpha
        For messages and reports.

    Returns
    -------
    AlbedoPoint
        ``passed`` is False when ρ > 1 beyond its uncertainty or the estimates disagree; ``message`` says which.

    Examples
    --------
    >>> from brdflab.bsdf.roughconductor import RoughConductor
    >>> from brdflab.judges.material.furnace import furnace_point
    >>> r = furnace_point(RoughConductor(R0=1.0, alpha=0.3), theta=30.0, samples=20_000)
    >>> r.passed, round(r.quadrature, 2)
    (True, 0.99)
    """
    from brdflab.judges.core.guard import bsdf_params

    params = dict(params if params is not None else bsdf_params(bsdf))
    name = name or describe(bsdf)
    if seed is None:
        seed = test_seed("furnace", bsdf_identity(bsdf), params, float(theta))
    b = CheckedBSDF(bsdf, name, params)
    s_quad, s_mc = np.random.SeedSequence(seed).spawn(2)
    phi = round(test_azimuth(seed), 3)  # the test's own azimuth: a sampler must rotate with ω_i
    if getattr(bsdf, "all_delta", False):  # f is 0 by the contract: the delta judge checks its energy
        p = AlbedoPoint(name, alpha, float(theta), float("nan"), float("nan"), float("nan"), float("nan"), seed,
                        params, fault="a delta BSDF (all_delta) has no f to integrate: its energy weight·(η_o/η_i)² "
                        "is checked per sample by delta_test")
        p.message = p.summary()
        return p
    try:
        q, qe = albedo_quadrature_with_error(b, theta, seed=int(s_quad.generate_state(1)[0]), phi_deg=phi)
        m, se, dm, dse = albedo_monte_carlo_parts(b, theta, samples, seed=int(s_mc.generate_state(1)[0]),
                                                  phi_deg=phi)
        p = AlbedoPoint(name, alpha, float(theta), q, m, se, qe, seed, params, delta_part=dm, delta_stderr=dse)
    except PluginFault as fault:
        p = AlbedoPoint(name, alpha, float(theta), float("nan"), float("nan"), float("nan"), float("nan"), seed,
                        params, fault=str(fault))
    p.message = p.summary()
    return p


def albedo_curve(name: str, make_bsdf, alpha: float | None, thetas: list[float], n: int = 100_000,
                 params: dict | None = None) -> list[AlbedoPoint]:
    """Directional albedo at each incident angle, by quadrature and Monte Carlo (``make_bsdf(alpha)``)."""
    out = []
    for th in thetas:
        b = make_bsdf(alpha)
        prm = {"alpha": alpha, **(params or {})} if alpha is not None else dict(params or {})
        seed = test_seed("furnace", name, bsdf_identity(b), prm, float(th))
        out.append(furnace_point(b, theta=th, samples=n, seed=seed, name=name, params=prm, alpha=alpha))
    return out


@dataclass
class FurnaceResult(CaseList):
    """Furnace results of one BSDF at several incident angles (iterable over its :class:`AlbedoPoint`s).

    Attributes
    ----------
    name, params, seed
        The BSDF, its parameters and the test's seed.
    points
        One :class:`AlbedoPoint` per angle.
    """

    name: str
    params: dict
    seed: int | None
    cases_attr: ClassVar[str] = "points"
    points: list[AlbedoPoint]


    @property
    def max_albedo(self) -> float:
        """Largest ρ (Monte Carlo) over the angles."""
        return max(p.monte_carlo for p in self.points)

    @property
    def message(self) -> str:
        """One line per angle."""
        return "\n".join(p.message for p in self.points)



def furnace_test(bsdf, thetas=(0.0, 30.0, 60.0, 85.0), samples: int = 50_000, seed: int | None = None,
                 name: str | None = None, theta: float | None = None, params: dict | None = None) -> FurnaceResult:
    """White furnace of any BSDF: ρ(θ_i) by quadrature and by Monte Carlo at each angle; energy ≤ 1.

    Parameters
    ----------
    bsdf
        Any :class:`brdflab.BSDF` (a user's plugin included).
    thetas
        Incident angles θ_i in degrees (``theta=`` for a single angle).
    samples
        Monte Carlo samples per angle.
    seed
        Default: derived from the BSDF's type and parameters (each angle then gets its own stream).
    name, params
        For messages.

    Returns
    -------
    FurnaceResult
        Iterable over one :class:`AlbedoPoint` per angle (quadrature ± error, Monte Carlo ± standard error,
        ``passed``, ``message``); ``passed`` when all pass.

    Examples
    --------
    >>> import brdflab as bl
    >>> res = bl.furnace_test(bl.RoughConductor(R0=1.0, alpha=0.3), thetas=(0.0, 60.0), samples=20_000)
    >>> res.passed, [round(p.quadrature, 2) for p in res]
    (True, [1.0, 0.92])
    """
    from brdflab.judges.core.guard import bsdf_params
    from brdflab.limits import check_test_arguments

    thetas = (theta,) if theta is not None else tuple(thetas)
    check_test_arguments(None, samples)
    two = bool(getattr(bsdf, "two_sided", False))
    thetas = tuple(check_test_arguments(t, samples, two_sided=two)[0] for t in thetas)
    params = dict(params if params is not None else bsdf_params(bsdf))
    name = name or describe(bsdf)
    base = test_seed("furnace", bsdf_identity(bsdf), params) if seed is None else seed
    alpha = getattr(bsdf, "alpha_value", None)
    pts = [furnace_point(bsdf, theta=float(t), samples=samples, seed=test_seed("furnace-angle", base, float(t)),
                         name=name, params=params, alpha=alpha) for t in thetas]
    return FurnaceResult(name, params, base, pts)


__all__ = ["AlbedoPoint", "FurnaceResult", "albedo_curve", "albedo_monte_carlo", "albedo_monte_carlo_parts",
           "albedo_quadrature", "format_params", "furnace_point", "furnace_test"]
