"""A shaded 3D lobe as flat polygons: the surface r(ω_o) = f·cos θ_o (scaled to its maximum) over the upper
hemisphere, cut into quads of the (θ_o, φ_o) grid, projected orthographically for a view (azimuth, elevation),
Lambert-shaded by a light fixed to the viewer, and sorted back to front (painter's algorithm) so that a 2D
canvas (Bokeh's ``patches``) draws it as a solid surface. Pure NumPy, no loop per quad.

View frame: the viewer sits along d = (cos el cos az, cos el sin az, sin el) and looks back at the origin; the
screen axes are e_x = (−sin az, cos az, 0) and e_y = d × e_x, whose z component is cos el ≥ 0, so the surface
normal +z points up on the screen for every elevation in [−90°, 90°] (and e_x × e_y = d: right-handed).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ProjectedLobe:
    """Quads of the lobe, back to front: screen vertices ``xs``/``ys`` (Q, 4), a shade in [0, 1] (Q,)."""

    xs: np.ndarray
    ys: np.ndarray
    shade: np.ndarray
    depth: np.ndarray


def view_axes(azimuth_deg: float, elevation_deg: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Screen x, screen y and the direction towards the viewer, orthonormal, for a view (degrees)."""
    az, el = np.radians(azimuth_deg), np.radians(elevation_deg)
    d = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    ex = np.array([-np.sin(az), np.cos(az), 0.0])
    ey = np.cross(d, ex)
    return ex, ey, d


def surface(directions: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Points of the lobe surface: ω_o · r / max r (a zero lobe stays at the origin)."""
    r = np.where(np.isfinite(radius), np.maximum(radius, 0.0), 0.0)
    top = r.max() if r.size and r.max() > 0 else 1.0
    return directions * (r / top)[..., None]


def project(points: np.ndarray, azimuth_deg: float, elevation_deg: float) -> ProjectedLobe:
    """Project the (T, P, 3) surface grid as (T−1)(P−1) quads, shaded and sorted back to front.

    Shade = 0.25 + 0.75 |n · l| with n the quad's normal (cross product of its diagonals) and l the
    direction towards the viewer tilted up and to the left (a head light).
    """
    ex, ey, d = view_axes(azimuth_deg, elevation_deg)
    a, b = points[:-1, :-1], points[:-1, 1:]
    c, e = points[1:, 1:], points[1:, :-1]
    quads = np.stack([a, b, c, e], axis=2).reshape(-1, 4, 3)
    n = np.cross(quads[:, 2] - quads[:, 0], quads[:, 3] - quads[:, 1])
    norm = np.linalg.norm(n, axis=1)
    light = d + 0.4 * ey - 0.3 * ex
    light /= np.linalg.norm(light)
    lam = np.abs(n @ light) / np.where(norm > 0, norm, 1.0)
    shade = np.where(norm > 0, 0.25 + 0.75 * lam, 0.25)
    depth = quads.mean(axis=1) @ d
    order = np.argsort(depth, kind="stable")  # farthest (smallest d·p) first
    return ProjectedLobe((quads @ ex)[order], (quads @ ey)[order], shade[order], depth[order])


def shade_colours(shade: np.ndarray, rgb: tuple[int, int, int] = (44, 160, 44)) -> list[str]:
    """Hex colours of a base colour scaled by ``shade``."""
    c = np.clip(np.outer(shade, rgb), 0, 255).astype(int)
    return [f"#{r:02x}{g:02x}{b:02x}" for r, g, b in c]
