"""The data behind every BRDF view, computed with one vectorised ``eval`` per BSDF and view.

Values are the **luminance** Y = 0.2127 R + 0.7152 G + 0.0722 B of f(ω_i, ω_o) (Rec. 709 weights, as
the furnace check), without the cosine unless a function says otherwise; for a grey material (e.g.
``R0 = 0.9``) Y equals each channel. Directions follow :mod:`brdflab.viz.coords`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from brdflab.texture import LUMINANCE
from brdflab.viz import coords

#: Incident angles (degrees) of the directional-albedo curves.
ALBEDO_THETAS = tuple(float(t) for t in range(0, 90, 4))


def luminance(rgb: np.ndarray) -> np.ndarray:
    """Y of (…, 3) linear RGB."""
    return np.asarray(rgb) @ LUMINANCE


def eval_luminance(bsdf, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """Y of f(ω_i, ω_o) for one ω_i (3,) or (N, 3) and directions ω_o (N, 3); non-finite values → 0."""
    wi = np.ascontiguousarray(np.broadcast_to(wi, wo.shape), dtype=float)
    y = luminance(bsdf.eval(wi, np.ascontiguousarray(wo, dtype=float)))
    return np.where(np.isfinite(y), y, 0.0)


def polar(bsdfs: list, theta_i: float, phi_i: float = 0.0, n: int = 721) -> tuple[np.ndarray, np.ndarray]:
    """f in the plane of incidence: (θ_o in degrees (n,), values (K, n)), θ_o signed from −90° to 90°."""
    theta_o = np.linspace(-90.0, 90.0, n)
    wo = coords.plane_directions(theta_o, phi_i)
    wi = coords.incident(theta_i, phi_i)
    return theta_o, np.array([eval_luminance(b, wi, wo) for b in bsdfs])


@dataclass
class Lobe:
    """f over the upper hemisphere for one incidence: a (θ_o, φ_o) grid and its directions."""

    theta_o_deg: np.ndarray
    """(T,) polar angles of the grid."""
    phi_o_deg: np.ndarray
    """(P,) azimuths of the grid (0 … 360 inclusive, so surfaces close)."""
    directions: np.ndarray
    """(T, P, 3) ω_o."""
    values: np.ndarray
    """(K, T, P) Y of f."""


def lobe(bsdfs: list, theta_i: float, phi_i: float = 0.0, n_theta: int = 46, n_phi: int = 73) -> Lobe:
    """f(ω_i, ω_o) on a (θ_o, φ_o) grid of the upper hemisphere (θ_o ∈ [0°, 90°])."""
    t = np.linspace(0.0, 90.0, n_theta)
    p = np.linspace(0.0, 360.0, n_phi)
    T, P = np.meshgrid(np.radians(t), np.radians(p), indexing="ij")
    wo = coords.spherical(T, P)
    wi = coords.incident(theta_i, phi_i)
    vals = np.array([eval_luminance(b, wi, wo).reshape(T.shape) for b in bsdfs])
    return Lobe(t, p, wo.reshape(*T.shape, 3), vals)


def half_diff_slice(bsdfs: list, phi_d: float = 90.0, n: int = 128) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """f on a θ_h × θ_d grid at fixed φ_d (degrees; φ_h = 0): (θ_h°, θ_d°, values (K, n_d, n_h)).

    Cells whose ω_i or ω_o lies below the horizon are NaN (outside the BRDF's domain).
    """
    th = np.linspace(0.0, 90.0, n)
    td = np.linspace(0.0, 90.0, n)
    TD, TH = np.meshgrid(np.radians(td), np.radians(th), indexing="ij")
    wi, wo = coords.half_diff_to_io(TH, 0.0, TD, np.radians(phi_d))
    inside = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    out = []
    for b in bsdfs:
        y = eval_luminance(b, wi, wo)
        out.append(np.where(inside, y, np.nan).reshape(TD.shape))
    return th, td, np.array(out)


def albedo_quadrature(bsdf, theta_i: float) -> float:
    """ρ(θ_i) = ∫ f cos θ_o dω_o (Y) by quadrature.

    The built-in microfacet materials use the furnace check's half-vector quadrature
    (:func:`brdflab.judges.material.furnace.albedo_quadrature`), as the validation battery does. Any other BSDF
    (diffuse, plugins, textured roughness) is integrated over the hemisphere in (cos θ_o, φ_o), where
    dω_o = d cos θ_o dφ_o, with the adaptive tensor Gauss–Legendre rule of the chi-square test
    (:func:`brdflab.judges.material.chi2.adaptive_integrate`, cells split where 4- and 8-point rules disagree),
    so narrow lobes of unknown shape are still resolved.
    """
    from brdflab.bsdf.roughconductor import RoughConductor
    from brdflab.bsdf.roughsubstrate import RoughSubstrate
    from brdflab.judges.material import chi2, furnace

    if type(bsdf) in (RoughConductor, RoughSubstrate) and bsdf.alpha.constant:
        return furnace.albedo_quadrature(bsdf, theta_i, bsdf.alpha_value)
    wi = coords.incident(theta_i)

    def integrand(mu, phi):
        wo = coords.spherical(np.arccos(np.clip(mu, -1.0, 1.0)), phi)
        return eval_luminance(bsdf, wi, wo) * mu

    from brdflab import effort

    cells = chi2.adaptive_integrate(integrand, np.linspace(0.0, 1.0, 9), np.linspace(0.0, 2 * np.pi, 17),
                                    n=10**6, max_depth=effort.current().view_depth)
    return float(cells.sum())


@dataclass
class Albedo:
    """Directional albedo curves of K BSDFs at T incident angles."""

    theta_deg: np.ndarray
    quadrature: np.ndarray
    """(K, T)."""
    monte_carlo: np.ndarray
    """(K, T) mean sample weight f cos θ_o / p (Y)."""
    mc_stderr: np.ndarray
    """(K, T) its standard error."""
    samples: int


def albedo(bsdfs: list, thetas=ALBEDO_THETAS, n: int = 20_000, seed: int = 0) -> Albedo:
    """ρ(θ_i) by quadrature and by Monte Carlo with its standard error (the furnace check's estimators).

    Each (BSDF, θ_i) pair draws from its own random stream (``seed``, BSDF index, angle index).
    """
    from brdflab.judges.material import furnace

    th = np.asarray(thetas, float)
    q = np.array([[albedo_quadrature(b, t) for t in th] for b in bsdfs])
    mc = np.zeros_like(q)
    se = np.zeros_like(q)
    for k, b in enumerate(bsdfs):
        for j, t in enumerate(th):
            s = int(np.random.SeedSequence([seed, k, j]).generate_state(1)[0])
            mc[k, j], se[k, j] = furnace.albedo_monte_carlo(b, float(t), n, seed=s)
    return Albedo(th, q, mc, se, n)
