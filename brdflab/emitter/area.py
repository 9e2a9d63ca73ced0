"""Mesh ``area`` emitter: one-sided, uniform over the mesh surface (spec §9.1).

=============  ========================================  =========  ==============================
parameter      tag                                       default    meaning
=============  ========================================  =========  ==============================
``radiance``   color, or child ``texture name=radiance`` (1, 1, 1)  emitted radiance L_e
``scale``      float                                     1          multiplies the radiance
=============  ========================================  =========  ==============================

Emission: L_e(y → x) = radiance(uv)·scale if n_l·(y − x) < 0, else 0, with n_l the **shading** normal
at y (interpolated ``vn``, renormalised; else the winding normal). A light whose vertex normals are constant
over each triangle (flat, or mirrored so that they oppose the winding normal) keeps one normal per triangle,
or one for the whole light when it is planar, and is sampled without interpolating them.

Sampling: a triangle with probability A_k / A (:class:`DiscreteChooser`: CDF inversion, or Walker's alias
method for more than 8 triangles), a uniform
point in it by the folding warp with barycentrics (ξ1, ξ2, 1 − ξ1 − ξ2), area density 1/A, converted to
solid angle at the receiver x: p_ω = ‖y − x‖² / (A |n_l·ω|) (PBR eq. 13.x, change of variables dω =
|cos θ_l| dA / r²). A planar light made of two triangles that tile a parallelogram (the usual quad light)
is sampled as y = c + ξ1·e1 + ξ2·e2 instead: the same density 1/A, without the triangle choice, the fold
or the table gather (half the sampling time on the Cornell box).
"""

from __future__ import annotations

import numpy as np

from brdflab.emitter.base import Emitter, EmitterSample
from brdflab.kernels import twin
from brdflab.math.distribution import AliasTable
from brdflab.math.frame import dot, sparse_combination
from brdflab.scene.geometry import interp_cols
from brdflab.scene.properties import MAX_COMPONENT, PropertyList
from brdflab.texture import LUMINANCE, Texture, as_texture


class AreaEmitter(Emitter):
    """A one-sided diffuse emitter attached to one mesh of the scene geometry.

    Parameters
    ----------
    radiance
        Emitted radiance (colour or texture).
    scale
        Multiplier of the radiance.
    """

    type_name = "area"
    #: Compiled twin in :mod:`brdflab.kernels.emitter` (own body only: subclasses stay on NumPy).
    kernel = "area"
    texture_slots = ("radiance",)
    KNOWN = {"radiance": "color", "scale": "float"}

    def __init__(self, radiance: Texture | np.ndarray | float = 1.0, scale: float = 1.0) -> None:
        self.radiance = as_texture(radiance)
        self.scale = float(scale)
        self.mesh_index = -1

    @classmethod
    def from_properties(cls, props: PropertyList) -> AreaEmitter:
        """Build from an ``<emitter type="area">`` property list."""
        props.check_known(cls.KNOWN)
        scale = props.positive_float("scale", 1.0, allow_zero=True)
        radiance = props.nonnegative_color("radiance", np.ones(3))
        if np.any(radiance * scale > MAX_COMPONENT):
            raise props.error("scale", f"'scale' × 'radiance' = {(radiance * scale).tolist()} overflows the float32 "
                              f"image (at most {MAX_COMPONENT:g})")
        return cls(radiance, scale)

    def set_texture(self, slot: str, texture: Texture) -> None:
        """Attach the ``radiance`` texture."""
        self.radiance = texture

    def attach(self, geometry, mesh_index: int) -> None:
        """Bind to mesh ``mesh_index`` of ``geometry`` and build the triangle distribution.

        The emitter keeps compact copies of its own triangles (p0, p1 − p0, p2 − p0, the normal data and,
        for textured radiance, the uvs), so sampling gathers from a few small tables instead of
        reconstructing full hit records.
        """
        self.geometry = geometry
        self.mesh_index = mesh_index
        self.tris = np.flatnonzero(geometry.tri_mesh == mesh_index)
        areas = geometry.tri_area[self.tris]
        self.area = float(areas.sum())
        self.chooser = DiscreteChooser(areas) if self.area > 0 else None
        tris = self.tris
        # Column per triangle (:func:`~brdflab.scene.geometry.interp_cols`): p0, p1 − p0, p2 − p0; vertex
        # normals; uvs. Row per triangle: the face normal.
        self._pos = geometry.tri_pos[:, tris]
        self._face_n = geometry.face_normals[tris]
        nrm = geometry.tri_nrm[:, tris] if geometry.tri_nrm is not None else None
        # Interpolated shading normals only where they vary over a triangle (flat lights skip it). Where the
        # three vertex normals of every triangle are equal but not the face normal (a light mirrored by its
        # toWorld, e.g. ``scale 1,1,-1``: the winding normal points up, the vn lines down), the light's
        # normal table holds that vertex normal, renormalised exactly as the interpolation would.
        flat = nrm is None or (np.allclose(nrm[0:3], self._face_n.T, rtol=0, atol=1e-12)
                               and np.allclose(nrm[3:9], 0.0, rtol=0, atol=1e-12))
        if not flat and not nrm[3:9].any():
            n0 = nrm[0:3].T
            ln = np.sqrt(n0[:, 0] * n0[:, 0] + n0[:, 1] * n0[:, 1] + n0[:, 2] * n0[:, 2])
            if np.all(ln > 0):
                self._face_n = n0 / ln[:, None]
                flat = True
        self._nrm = None if flat else nrm
        # A planar light (a quad, a disc) has one normal: no per-sample normal gather.
        planar = flat and np.allclose(self._face_n, self._face_n[:1], rtol=0, atol=1e-12)
        self._normal = self._face_n[0].copy() if planar else self._face_n
        # A planar parallelogram (the usual quad light) is sampled directly (:func:`sample_parallelogram`).
        self._quad = (parallelogram(geometry.positions[geometry.faces[tris]], self.area) if planar and
                      self.area > 0 else None)
        self._uv = (geometry.tri_uv[:, tris] if geometry.tri_uv is not None
                    else np.array([[0.0, 0.0, 1.0, 0.0, 0.0, 1.0]]).T.repeat(len(tris), axis=1))

    def _choose_triangles(self, u: np.ndarray) -> np.ndarray:
        """Triangle index (into the emitter's own list) with probability A_k / A."""
        return self.chooser.sample(u)

    def le(self, uv: np.ndarray) -> np.ndarray:
        """Radiance (N, 3) emitted toward the front side at surface coordinates ``uv``."""
        return self.radiance.eval(uv) * self.scale

    @twin("emitter", "sample_emitter")
    def sample(self, ref_p: np.ndarray, u: np.ndarray) -> EmitterSample:
        """Sample a point uniformly by area and return the solid-angle sample seen from ``ref_p``."""
        n = len(u)
        textured = not self.radiance.constant
        if self._quad is not None and not textured:
            wi, dist, dist2, cos_l = sample_parallelogram(self._quad, self._normal, u, ref_p)
        else:
            k = self._choose_triangles(u[:, 2])
            wi, dist, dist2, cos_l, bu, bv = sample_triangle_points(self._pos, self._normal, self._nrm, k, u, ref_p)
        # p_ω = ‖y − x‖² / (A |n_l·ω|) for front-facing light points, else 0. The test 0 < p_ω < ∞ also
        # rejects back faces (cos θ_l ≤ 0 gives p_ω ≤ 0, ∞ or NaN).
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            pdf = dist2 / (self.area * cos_l)
        ok = (pdf > 0) & (pdf < np.inf)
        pdf = np.where(ok, pdf, 0.0)
        radiance = np.empty((n, 3), order="F")
        if not textured:
            value = self.radiance.value * self.scale
            for j in range(3):
                np.multiply(ok, value[j], out=radiance[:, j])
        else:
            uv = interp_cols(self._uv, k, bu, bv, 2)
            radiance[:] = 0.0
            sel = np.flatnonzero(ok)
            radiance[sel] = self.le(uv[sel])
        return EmitterSample(wi, dist, radiance, pdf)

    def eval_hit(self, ns: np.ndarray, uv: np.ndarray, d: np.ndarray) -> np.ndarray:
        """Radiance arriving along rays of direction ``d`` that hit this emitter (shading normal ``ns``)."""
        front = dot(ns, d) < 0
        return np.where(front[:, None], self.le(uv), 0.0)

    def pdf_hit(self, dist: np.ndarray, ns: np.ndarray, d: np.ndarray) -> np.ndarray:
        """Solid-angle density with which :meth:`sample` would produce the hit at ``dist`` along ``d``."""
        cos_l = -dot(ns, d)
        with np.errstate(divide="ignore", invalid="ignore"):
            pdf = np.where(cos_l > 0, dist * dist / (self.area * np.abs(cos_l)), 0.0)
        return np.where(np.isfinite(pdf), pdf, 0.0)

    def power(self) -> float:
        """Luminance of the mean radiance times the area (spec §8)."""
        return float(LUMINANCE @ (self.radiance.mean() * self.scale)) * self.area * np.pi


class DiscreteChooser:
    """Index k with probability weights[k] / Σ weights, for one uniform each.

    Up to 8 outcomes: CDF inversion by counting the CDF entries ≤ u (:func:`invert_cdf`); more: Walker's
    alias method (:class:`~brdflab.math.distribution.AliasTable`), O(1) per sample where a binary search
    over thousands of light triangles cost 67 ns.
    """

    kernel = "emitter"  # short CDFs: the compiled engine's kernels.emitter.choose

    def __init__(self, weights: np.ndarray) -> None:
        w = np.asarray(weights, dtype=np.float64)
        self.pmf = w / w.sum()
        self.cdf = np.cumsum(self.pmf)
        self.cdf[-1] = 1.0
        self.alias = AliasTable(w) if len(w) > 8 else None

    @twin("emitter", "choose")
    def sample(self, u: np.ndarray) -> np.ndarray:
        """Indices (N,) for uniforms ``u`` (N,) in [0, 1)."""
        return self.alias.sample(u) if self.alias is not None else invert_cdf(self.cdf, u)


def invert_cdf(cdf: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Index k with cdf[k−1] ≤ u < cdf[k] for a short CDF, by counting the entries ≤ u (one comparison
    each: several times faster than a binary search per element for a handful of entries)."""
    k = np.zeros(len(u), np.intp)
    for c in cdf[:-1]:
        k += u >= c
    return k


def sample_triangle_points(pos: np.ndarray, face_n: np.ndarray, nrm: np.ndarray | None, k: np.ndarray,
                           u: np.ndarray, ref_p: np.ndarray):
    """Uniform points on triangles ``k`` (packed tables) seen from ``ref_p``; ``face_n`` is the (K, 3)
    table of face normals, or one (3,) normal shared by all triangles.

    Folding warp (spec §9.1): barycentrics (ξ1, ξ2, 1 − ξ1 − ξ2) of (p0, p1, p2) after folding the square
    onto the triangle, i.e. y = p0 + bu(p1 − p0) + bv(p2 − p0) with bu = ξ2, bv = 1 − ξ1 − ξ2.

    Returns
    -------
    (wi, dist, dist², cos θ_l, bu, bv)
        Unit directions x → y (N, 3), distances, squared distances, n_l·(x − y)/‖x − y‖ with n_l the
        shading normal at y, and the barycentrics.
    """
    u0, u1 = u[:, 0], u[:, 1]
    fold = u0 + u1 > 1.0
    b0 = np.where(fold, 1.0 - u0, u0)
    bu = np.where(fold, 1.0 - u1, u1)
    bv = 1.0 - b0
    bv -= bu
    wi, dist, dist2 = _toward(interp_cols(pos, k, bu, bv, 3), ref_p)
    if nrm is None and face_n.ndim == 1:
        return wi, dist, dist2, _cos_light(face_n, wi), bu, bv
    if nrm is None:
        g = np.take(face_n, k, axis=0)
        nx, ny, nz = g[:, 0], g[:, 1], g[:, 2]
    else:
        nl = interp_cols(nrm, k, bu, bv, 3)
        nx, ny, nz = nl[:, 0], nl[:, 1], nl[:, 2]
        ln = np.sqrt(nx * nx + ny * ny + nz * nz)
        ln[~(ln > 0)] = 1.0
        nx, ny, nz = nx / ln, ny / ln, nz / ln
    cos_l = -(nx * wi[:, 0] + ny * wi[:, 1] + nz * wi[:, 2])
    return wi, dist, dist2, cos_l, bu, bv


def sample_parallelogram(quad: tuple[np.ndarray, np.ndarray, np.ndarray], normal: np.ndarray, u: np.ndarray,
                         ref_p: np.ndarray):
    """Uniform points y = c + ξ1·e1 + ξ2·e2 on the parallelogram ``quad`` = (c, e1, e2) (unit normal
    ``normal``) seen from ``ref_p``: the same density 1/A as choosing one of its two triangles by area
    and folding, without the choice or a table gather.

    Returns
    -------
    (wi, dist, dist², cos θ_l)
        As :func:`sample_triangle_points`.
    """
    c, e1, e2 = quad
    u0, u1 = u[:, 0], u[:, 1]
    y = np.empty((len(u), 3), order="F")
    for j in range(3):
        sparse_combination((u0, u1), (e1[j], e2[j]), c[j], out=y[:, j])  # axis-aligned quads skip zeros
    wi, dist, dist2 = _toward(y, ref_p)
    return wi, dist, dist2, _cos_light(normal, wi)


def _cos_light(normal: np.ndarray, wi: np.ndarray) -> np.ndarray:
    """−n·ω for one normal (3,) and directions (N, 3) (zero components skipped)."""
    return sparse_combination((wi[:, 0], wi[:, 1], wi[:, 2]), -normal)


def _toward(y: np.ndarray, ref_p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit directions ``ref_p`` → ``y`` (0 where the points coincide), distances and squared distances."""
    dx, dy, dz = y[:, 0] - ref_p[:, 0], y[:, 1] - ref_p[:, 1], y[:, 2] - ref_p[:, 2]
    dist2 = dx * dx
    dist2 += dy * dy
    dist2 += dz * dz
    dist = np.sqrt(dist2)
    inv = 1.0 / np.maximum(dist, np.finfo(np.float64).tiny)  # coincident points: 0 · 1/tiny = 0
    wi = np.empty((len(y), 3), order="F")
    np.multiply(dx, inv, out=wi[:, 0])
    np.multiply(dy, inv, out=wi[:, 1])
    np.multiply(dz, inv, out=wi[:, 2])
    return wi, dist, dist2


def parallelogram(corners: np.ndarray, area: float) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """(c, e1, e2) when two triangles ``corners`` (2, 3, 3) tile the parallelogram c + [0, 1]²·(e1, e2)
    (they share an edge, which is its diagonal, and the diagonals bisect each other), else None."""
    if corners.shape[0] != 2:
        return None
    t0, t1 = corners
    size = max(float(np.abs(corners).max()), 1.0)
    same = np.array([[np.allclose(a, b, rtol=0, atol=1e-9 * size) for b in t1] for a in t0])
    if same.sum() != 2 or same.sum(axis=1).max() > 1:
        return None
    w0 = t0[np.flatnonzero(~same.any(axis=1))[0]]
    w1 = t1[np.flatnonzero(~same.any(axis=0))[0]]
    a, b = t0[same.any(axis=1)]
    if not np.allclose(w0 + w1, a + b, rtol=0, atol=1e-9 * size):
        return None
    e1, e2 = a - w0, b - w0
    if not np.isclose(np.linalg.norm(np.cross(e1, e2)), area, rtol=1e-9):
        return None
    return w0, e1, e2


class AreaLightSet:
    """All emitters of a scene fused into one triangle distribution, when every one of them is an area
    light of constant radiance (the common case): choosing emitter e (pmf p_e) and then its triangle k
    (A_k / A_e) is the same as choosing triangle k with probability p_e A_k / A_e, so one vectorised
    sample serves all emitters — no grouping of shading points by emitter.

    The solid-angle pdf, selection included, is p_e ‖y − x‖² / (A_e |n_l·ω|), as for the emitters one by
    one.
    """

    #: Compiled twin in :mod:`brdflab.kernels.emitter`.
    kernel = "arealightset"

    def __init__(self, emitters: list[AreaEmitter], pmf: np.ndarray) -> None:
        self.emitters = emitters
        pos, face_n, nrm, rad, scale, prob = [], [], [], [], [], []
        use_nrm = any(e._nrm is not None for e in emitters)
        for e, p_e in zip(emitters, pmf, strict=True):
            m = len(e.tris)
            pos.append(e._pos)
            face_n.append(e._face_n)
            if use_nrm:
                nrm.append(e._nrm if e._nrm is not None else np.concatenate([e._face_n.T, np.zeros((6, m))]))
            rad.append(np.repeat((e.radiance.value * e.scale)[:, None], m, axis=1))
            scale.append(np.full(m, p_e / e.area if e.area > 0 else 0.0))
            areas = e.geometry.tri_area[e.tris]
            prob.append(p_e * areas / e.area if e.area > 0 else np.zeros(m))
        self._pos = np.concatenate(pos, axis=1)
        self._face_n = np.concatenate(face_n)
        self._nrm = np.concatenate(nrm, axis=1) if use_nrm else None
        self._radiance = np.ascontiguousarray(np.concatenate(rad, axis=1))
        # Per emitter: radiance (3, E) and p_e / A_e, for rays that hit an emitter.
        self._emitter_radiance = np.stack([e.radiance.value * e.scale for e in emitters], axis=1)
        self._emitter_pdf_scale = np.array([p_e / e.area for e, p_e in zip(emitters, pmf, strict=True)])
        self._pdf_scale = np.concatenate(scale)
        self.chooser = DiscreteChooser(np.concatenate(prob))

    @staticmethod
    def applies(emitters: list) -> bool:
        """True when every emitter is an area light with constant radiance and positive area."""
        return bool(emitters) and all(isinstance(e, AreaEmitter) and e.radiance.constant and e.area > 0
                                      for e in emitters)

    @twin("emitter", "sample_light_set")
    def sample(self, ref_p: np.ndarray, u: np.ndarray) -> EmitterSample:
        """One light sample per reference point: ``u[:, 0]`` picks the triangle, ``u[:, 1:3]`` the point.

        The returned pdf **includes** the selection probability.
        """
        n = len(u)
        k = self.chooser.sample(u[:, 0])
        wi, dist, dist2, cos_l, _, _ = sample_triangle_points(self._pos, self._face_n, self._nrm, k, u[:, 1:3], ref_p)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            pdf = dist2 * np.take(self._pdf_scale, k) / cos_l
        ok = (pdf > 0) & (pdf < np.inf)  # also rejects back faces (see AreaEmitter.sample)
        pdf = np.where(ok, pdf, 0.0)
        radiance = np.empty((n, 3), order="F")
        for j in range(3):
            np.multiply(np.take(self._radiance[j], k), ok, out=radiance[:, j])
        return EmitterSample(wi, dist, radiance, pdf)

    def eval_pdf_hit(self, emitter: np.ndarray, dist: np.ndarray, ns: np.ndarray,
                     d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Radiance and light-sampling pdf (selection included) of rays ``d`` that hit emitters
        ``emitter`` at distance ``dist`` with shading normal ``ns`` (as :meth:`AreaEmitter.eval_hit` and
        :meth:`AreaEmitter.pdf_hit` times p_e, for all emitters at once)."""
        cos_l = -(ns[:, 0] * d[:, 0] + ns[:, 1] * d[:, 1] + ns[:, 2] * d[:, 2])
        front = cos_l > 0
        le = np.empty((len(d), 3), order="F")
        for j in range(3):
            np.multiply(np.take(self._emitter_radiance[j], emitter), front, out=le[:, j])
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            pdf = dist * dist * np.take(self._emitter_pdf_scale, emitter) / cos_l
        return le, np.where(front & (pdf < np.inf), pdf, 0.0)
