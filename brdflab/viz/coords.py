"""Direction parameterisations for BRDF plots.

**Plane of incidence.** ω_i has polar angle θ_i and azimuth φ_i in the local shading frame (z = normal).
A direction of the plane of incidence is given by one *signed* angle θ_o ∈ [−90°, 90°] from the normal:

    ω_o(θ_o) = (−sin θ_o cos φ_i, −sin θ_o sin φ_i, cos θ_o),

so **positive θ_o lies on the side opposite ω_i's azimuth** (the forward-scattering side, where the
mirror direction θ_o = +θ_i is) and negative θ_o on ω_i's own side (back-scattering; ω_o = ω_i at
θ_o = −θ_i). ``polar.csv`` and the polar plots use this convention.

**Half/difference angles** (Rusinkiewicz 1998, "A new change of variables for efficient BRDF
representation", §3): ω_h = normalize(ω_i + ω_o) with spherical angles (θ_h, φ_h); the difference
vector d is ω_i expressed in a frame where ω_h is the pole,

    d = R_y(−θ_h) R_z(−φ_h) ω_i,    (θ_d, φ_d) = spherical angles of d,

and conversely ω_i = R_z(φ_h) R_y(θ_h) d, ω_o = R_z(φ_h) R_y(θ_h) d̃ with d̃ = (−d_x, −d_y, d_z)
(the reflection of ω_i about ω_h). Here R_z(φ) rotates about the normal and R_y(θ) about the y axis
(the binormal), right-handed. Isotropic BRDFs depend only on (θ_h, θ_d, φ_d).
"""

from __future__ import annotations

import numpy as np


def spherical(theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Unit vectors (N, 3) with polar angle ``theta`` from +z and azimuth ``phi`` (radians)."""
    theta, phi = np.broadcast_arrays(np.asarray(theta, float), np.asarray(phi, float))
    st = np.sin(theta)
    return np.stack([st * np.cos(phi), st * np.sin(phi), np.cos(theta)], axis=-1).reshape(-1, 3)


def angles(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(θ, φ) of unit vectors (N, 3); θ ∈ [0, π], φ ∈ [0, 2π)."""
    theta = np.arccos(np.clip(w[:, 2], -1.0, 1.0))
    phi = np.mod(np.arctan2(w[:, 1], w[:, 0]), 2 * np.pi)
    return theta, phi


def incident(theta_deg: float, phi_deg: float = 0.0) -> np.ndarray:
    """ω_i (3,) at polar angle ``theta_deg`` and azimuth ``phi_deg`` (degrees)."""
    return spherical(np.radians(theta_deg), np.radians(phi_deg))[0]


def plane_directions(theta_o_deg: np.ndarray, phi_i_deg: float = 0.0) -> np.ndarray:
    """ω_o (N, 3) of signed angles ``theta_o_deg`` in the plane of incidence (module docstring)."""
    t = np.radians(np.asarray(theta_o_deg, float)).ravel()
    p = np.radians(phi_i_deg)
    return np.stack([-np.sin(t) * np.cos(p), -np.sin(t) * np.sin(p), np.cos(t)], axis=1)


def _rot_z(v: np.ndarray, phi: np.ndarray) -> np.ndarray:
    c, s = np.cos(phi), np.sin(phi)
    return np.stack([c * v[:, 0] - s * v[:, 1], s * v[:, 0] + c * v[:, 1], v[:, 2]], axis=1)


def _rot_y(v: np.ndarray, theta: np.ndarray) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([c * v[:, 0] + s * v[:, 2], v[:, 1], -s * v[:, 0] + c * v[:, 2]], axis=1)


def half_diff_to_io(theta_h, phi_h, theta_d, phi_d) -> tuple[np.ndarray, np.ndarray]:
    """(ω_i, ω_o), each (N, 3), of Rusinkiewicz angles (radians, broadcast together)."""
    theta_h, phi_h, theta_d, phi_d = (np.ravel(a) for a in np.broadcast_arrays(
        *(np.asarray(x, float) for x in (theta_h, phi_h, theta_d, phi_d))))
    d = spherical(theta_d, phi_d)
    d_mirror = d * np.array([-1.0, -1.0, 1.0])
    wi = _rot_z(_rot_y(d, theta_h), phi_h)
    wo = _rot_z(_rot_y(d_mirror, theta_h), phi_h)
    return wi, wo


def io_to_half_diff(wi: np.ndarray, wo: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Rusinkiewicz angles (θ_h, φ_h, θ_d, φ_d) in radians of direction pairs (N, 3) (ω_i + ω_o ≠ 0)."""
    h = wi + wo
    h = h / np.linalg.norm(h, axis=1, keepdims=True)
    theta_h, phi_h = angles(h)
    d = _rot_y(_rot_z(wi, -phi_h), -theta_h)
    theta_d, phi_d = angles(d)
    return theta_h, phi_h, theta_d, phi_d
