"""Per-triangle tangents dp/du from positions and uvs (PBR-3 §3.6.2), computed once per scene.

With the triangle's edges e1 = p1 − p0, e2 = p2 − p0 and uv differences (Δu1, Δv1) = uv1 − uv0,
(Δu2, Δv2) = uv2 − uv0, the parameterisation p(u, v) is affine on the triangle and

    e1 = Δu1 dp/du + Δv1 dp/dv,   e2 = Δu2 dp/du + Δv2 dp/dv,

so with det = Δu1 Δv2 − Δv1 Δu2 (PBR-3 eq. 3.6's system, solved by Cramer's rule):

    dp/du = (Δv2 e1 − Δv1 e2) / det,   dp/dv = (Δu1 e2 − Δu2 e1) / det.

A triangle whose uvs are degenerate (|det| ≤ 10⁻⁹ max(|Δu1 Δv2|, |Δv1 Δu2|): collinear or repeated uvs,
all zero included) or whose mesh has no uvs gets dp/du = 0, which the shading frame treats as "no tangent"
(Duff's frame, :mod:`brdflab.math.frame`). Only anisotropic materials use it.
"""

from __future__ import annotations

import numpy as np

#: Relative size of the uv determinant below which a triangle's uvs count as degenerate.
DEGENERATE_UV = 1e-9


def triangle_dpdu(tri_pos: np.ndarray, tri_uv: np.ndarray, has_uv: np.ndarray, dv: bool = False) -> np.ndarray:
    """(3, K) dp/du of each triangle (dp/dv with ``dv``), zero where ``has_uv`` (K,) is False or the uvs are
    degenerate (module docstring).

    ``tri_pos`` is the geometry's packed (9, K) table (p0, e1, e2 per column) and ``tri_uv`` its (6, K) table
    (uv0, uv1 − uv0, uv2 − uv0).

    Examples
    --------
    >>> import numpy as np
    >>> pos = np.array([0, 0, 0, 2, 0, 0, 0, 3, 0], float)[:, None]   # p0, e1 = (2,0,0), e2 = (0,3,0)
    >>> uv = np.array([0, 0, 0, 1, 1, 0], float)[:, None]             # u grows along e2, v along e1
    >>> (triangle_dpdu(pos, uv, np.array([True]))[:, 0] + 0.0).tolist()
    [0.0, 3.0, 0.0]
    >>> (triangle_dpdu(pos, uv, np.array([True]), dv=True)[:, 0] + 0.0).tolist()
    [2.0, 0.0, 0.0]
    """
    du1, dv1, du2, dv2 = tri_uv[2], tri_uv[3], tri_uv[4], tri_uv[5]
    a, b = du1 * dv2, dv1 * du2
    det = a - b
    ok = has_uv & (np.abs(det) > DEGENERATE_UV * np.maximum(np.abs(a), np.abs(b))) & np.isfinite(det)
    inv = np.divide(1.0, det, out=np.zeros_like(det), where=ok)
    c1, c2 = (-du2, du1) if dv else (dv2, -dv1)
    out = np.empty((3, tri_pos.shape[1]))
    for j in range(3):
        out[j] = c1 * tri_pos[3 + j] + c2 * tri_pos[6 + j]
        out[j] *= inv
    out[:, ~ok] = 0.0
    return out
