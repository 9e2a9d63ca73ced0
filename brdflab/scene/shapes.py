"""Procedural meshes for the bundled scenes and benchmarks, and an OBJ writer.

All generators are vectorised and return ``(positions, faces, normals, uvs)`` with counter-clockwise
winding seen from the side the normals point to (geometric normal = (p1 − p0) × (p2 − p0)).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def uv_sphere(center=(0.0, 0.0, 0.0), radius: float = 1.0, n_theta: int = 24, n_phi: int = 48,
              bumps: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A latitude/longitude sphere (y up) with outward normals and (u, v) ∈ [0, 1]²; 2·n_θ·n_φ triangles.

    ``bumps`` displaces the radius by bumps·sin(7θ)cos(9φ) (used for benchmark meshes).
    """
    th = np.linspace(0.0, np.pi, n_theta + 1)
    ph = np.linspace(0.0, 2.0 * np.pi, n_phi + 1)
    T, P = np.meshgrid(th, ph, indexing="ij")
    r = radius * (1.0 + bumps * np.sin(7 * T) * np.cos(9 * P))
    n = np.stack([np.sin(T) * np.cos(P), np.cos(T), -np.sin(T) * np.sin(P)], axis=-1).reshape(-1, 3)
    v = n * r.reshape(-1, 1) + np.asarray(center, dtype=np.float64)
    uv = np.stack([P / (2 * np.pi), 1.0 - T / np.pi], axis=-1).reshape(-1, 2)
    i, j = np.meshgrid(np.arange(n_theta), np.arange(n_phi), indexing="ij")
    a = (i * (n_phi + 1) + j).ravel()
    b, c, d = a + n_phi + 1, a + n_phi + 2, a + 1
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    # Drop the degenerate triangles at the poles.
    area2 = np.linalg.norm(np.cross(v[faces[:, 1]] - v[faces[:, 0]], v[faces[:, 2]] - v[faces[:, 0]]), axis=1)
    keep = area2 > 1e-9 * radius * radius
    return v, faces[keep], n, uv


def quad(p0, p1, p2, p3) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A planar quad p0 p1 p2 p3 (counter-clockwise seen from the normal side) with uv (0,0)…(0,1)."""
    v = np.array([p0, p1, p2, p3], dtype=np.float64)
    nrm = np.cross(v[1] - v[0], v[2] - v[0])
    nrm /= np.linalg.norm(nrm)
    return v, np.array([[0, 1, 2], [0, 2, 3]]), np.tile(nrm, (4, 1)), np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]])


def merge(*parts) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Concatenate meshes (positions, faces, normals, uvs)."""
    vs, fs, ns, us = [], [], [], []
    off = 0
    for v, f, n, u in parts:
        vs.append(v)
        fs.append(f + off)
        ns.append(n)
        us.append(u)
        off += len(v)
    return np.concatenate(vs), np.concatenate(fs), np.concatenate(ns), np.concatenate(us)


def write_obj(path: str | Path, positions: np.ndarray, faces: np.ndarray, normals: np.ndarray | None = None,
              uvs: np.ndarray | None = None, comment: str = "") -> None:
    """Write a triangle mesh as OBJ (1-based ``f p/t/n``), vectorised with ``np.savetxt``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    f1 = faces + 1
    with open(path, "w") as f:
        if comment:
            f.write("".join(f"# {line}\n" for line in comment.splitlines()))
        np.savetxt(f, positions, fmt="v %.6f %.6f %.6f")
        if uvs is not None:
            np.savetxt(f, uvs, fmt="vt %.6f %.6f")
        if normals is not None:
            np.savetxt(f, normals, fmt="vn %.6f %.6f %.6f")
        if uvs is not None and normals is not None:
            np.savetxt(f, np.repeat(f1, 3, axis=1), fmt="f %d/%d/%d %d/%d/%d %d/%d/%d")
        elif normals is not None:
            np.savetxt(f, np.repeat(f1, 2, axis=1), fmt="f %d//%d %d//%d %d//%d")
        elif uvs is not None:
            np.savetxt(f, np.repeat(f1, 2, axis=1), fmt="f %d/%d %d/%d %d/%d")
        else:
            np.savetxt(f, f1, fmt="f %d %d %d")
