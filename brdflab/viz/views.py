"""The data behind every BRDF view, computed with one vectorised ``eval`` per BSDF and view.

Values are the **luminance** Y = 0.2127 R + 0.7152 G + 0.0722 B of f(ω_i, ω_o) (Rec. 709 weights, as
the furnace check), without the cosine unless a function says otherwise; for a grey material (e.g.
``R0 = 0.9``) Y equals each channel. Directions follow :mod:`brdflab.viz.coords`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from brdflab.texture import LUMINANCE
from brdflab.viz import coords, reflectance

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


def polar(bsdfs: list, theta_i: float, phi_i: float = 0.0, n: int = 721,
          full: bool | None = None) -> tuple[np.ndarray, np.ndarray]:
    """f in the plane of incidence: (θ_o in degrees (n,), values (K, n)), θ_o signed from −90° to 90°.

    ``full`` (default: when some BSDF transmits): the whole circle, θ_o from −180° to 180° (|θ_o| > 90°: below
    the surface; a ray refracted at θ_t leaves at θ_o = 180° − θ_t, the undeflected one at 180° − θ_i), with
    ``2n − 1`` points so that the upper half keeps its resolution.
    """
    if full is None:
        full = any(reflectance.transmits(b) for b in bsdfs)
    theta_o = np.linspace(-180.0, 180.0, 2 * n - 1) if full else np.linspace(-90.0, 90.0, n)
    wo = coords.plane_directions(theta_o, phi_i)
    wi = coords.incident(theta_i, phi_i)
    return theta_o, np.array([eval_luminance(b, wi, wo) for b in bsdfs])


@dataclass
class Lobe:
    """f over the upper hemisphere (or the whole sphere) for one incidence: a (θ_o, φ_o) grid and its directions."""

    theta_o_deg: np.ndarray
    """(T,) polar angles of the grid."""
    phi_o_deg: np.ndarray
    """(P,) azimuths of the grid (0 … 360 inclusive, so surfaces close)."""
    directions: np.ndarray
    """(T, P, 3) ω_o."""
    values: np.ndarray
    """(K, T, P) Y of f."""


def lobe(bsdfs: list, theta_i: float, phi_i: float = 0.0, n_theta: int = 46, n_phi: int = 73,
         full: bool | None = None) -> Lobe:
    """f(ω_i, ω_o) on a (θ_o, φ_o) grid of the upper hemisphere (θ_o ∈ [0°, 90°]), or of the whole sphere
    (θ_o ∈ [0°, 180°], ``2 n_theta − 1`` rows) when ``full`` (default: when some BSDF transmits)."""
    if full is None:
        full = any(reflectance.transmits(b) for b in bsdfs)
    t = np.linspace(0.0, 180.0, 2 * n_theta - 1) if full else np.linspace(0.0, 90.0, n_theta)
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
    """ρ(θ_i) = ∫ f |cos θ_o| dω_o (Y; transmitted energy included) by quadrature
    (:func:`brdflab.viz.reflectance.albedo_quadrature`: the furnace check's half-vector rule for the built-in
    conductors, a fixed rule at a measured table's resolution, the adaptive tensor Gauss–Legendre rule of the
    chi-square test in (cos θ_o, φ_o) for anything else, so narrow lobes of unknown shape are still resolved)."""
    return reflectance.albedo_quadrature(bsdf, theta_i)


@dataclass
class Albedo:
    """Directional albedo curves of K BSDFs at T incident angles: R + T, and R and T apart."""

    theta_deg: np.ndarray
    quadrature: np.ndarray
    """(K, T) R + T."""
    monte_carlo: np.ndarray
    """(K, T) mean sample weight f |cos θ_o| / p (Y; below the surface × (η_o/η_i)²)."""
    mc_stderr: np.ndarray
    """(K, T) its standard error."""
    samples: int
    reflected: np.ndarray | None = None
    """(K, T) R by quadrature (the upper hemisphere, or the reflected delta lobe)."""
    transmitted: np.ndarray | None = None
    """(K, T) T by quadrature (energy: :mod:`brdflab.viz.reflectance`); 0 without transmission."""
    mc_parts: np.ndarray | None = None
    """(K, T, 2, 2) Monte Carlo (R, T) × (mean, standard error)."""

    @property
    def any_transmission(self) -> bool:
        """Does some curve transmit light (T > 0 anywhere)?"""
        return self.transmitted is not None and bool(np.any(self.transmitted > 0) or np.any(
            self.mc_parts[:, :, 1, 0] > 0))


def albedo(bsdfs: list, thetas=ALBEDO_THETAS, n: int = 20_000, seed: int = 0) -> Albedo:
    """ρ(θ_i) by quadrature and by Monte Carlo with its standard error (the furnace check's estimators), each
    also split into reflection R and transmission T (:mod:`brdflab.viz.reflectance`).

    Each (BSDF, θ_i) pair draws from its own random stream (``seed``, BSDF index, angle index).
    """
    th = np.asarray(thetas, float)
    parts = np.array([[reflectance.albedo_parts(b, t) for t in th] for b in bsdfs]).reshape(len(bsdfs), len(th), 2)
    mc = np.zeros((len(bsdfs), len(th), 3, 2))
    for k, b in enumerate(bsdfs):
        for j, t in enumerate(th):
            s = int(np.random.SeedSequence([seed, k, j]).generate_state(1)[0])
            mean, se = reflectance.monte_carlo_parts(b, float(t), n, s)
            mc[k, j] = np.stack([mean, se], axis=1)
    return Albedo(th, parts.sum(axis=2), mc[:, :, 2, 0], mc[:, :, 2, 1], n, parts[..., 0], parts[..., 1],
                  mc[:, :, :2, :])
