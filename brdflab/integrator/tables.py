"""Per-scene lookup tables of the integrators, built once per scene (:func:`scene_tables`): what a camera ray
does at each triangle (shade it with its material family, return an emitter's L_e, or the background for a
miss), each triangle's emitter, and each triangle's material within its family.

Indexed by Embree's primID with one extra last entry, so that a miss (primID −1) reads it without a test.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from brdflab.bsdf.family import BSDFFamilies


@dataclass
class SceneTables:
    """Per-scene lookups the integrators build once (see :func:`scene_tables`)."""

    bsdf_families: BSDFFamilies
    tri_emitter: np.ndarray
    """(triangles + 1,) emitter index of each triangle's mesh, −1 for none; the extra last entry (−1) is
    what a miss (primID −1) reads."""
    tri_code: np.ndarray
    """(triangles + 1,) what a camera ray that hits the triangle does: shade it (code 2·family + smooth ≥ 0,
    with the material family of its mesh and smooth = 1 when the mesh interpolates vertex normals, see
    :class:`~brdflab.scene.geometry.Geometry`), return L_e (:data:`CODE_EMITTER`) or, in the extra last
    entry, :data:`CODE_MISS`."""
    codes: list[int]
    """The shading codes (≥ 0) that occur in :attr:`tri_code`, ascending."""
    bsdf_uv: bool
    """True when some material has a texture, so shading points need their uvs."""
    has_emitter_meshes: bool
    """True when some mesh emits (camera rays can hit an emitter)."""
    tri_member: np.ndarray | None = None
    """(triangles,) index of each triangle's material within its family (``BSDFFamilies.mesh_member`` per
    triangle), or None when no family has members with different constants (:attr:`BSDFFamilies.any_tables`)."""
    tri_tangent: np.ndarray | None = None
    """(triangles,) True where the triangle's material is anisotropic (``BSDF.anisotropic``) and its mesh has
    uvs: its shading frames follow the uv tangent (:meth:`~brdflab.math.frame.NormalFrames.with_uv_tangents`);
    None when no triangle does (every frame is Duff's)."""
    dpdu: np.ndarray | None = None
    """(3, triangles) dp/du of each triangle (:meth:`~brdflab.scene.geometry.Geometry.dpdu_cols`) when
    :attr:`tri_tangent` is set, else None."""


#: :attr:`SceneTables.tri_code` of triangles on emitters and of misses.
CODE_EMITTER, CODE_MISS = -1, -2


def scene_tables(scene) -> SceneTables:
    """The scene's :class:`SceneTables` (built on first use)."""
    tab = scene.__dict__.get("_tables")
    if tab is None:
        tri_mesh = scene.geometry.tri_mesh
        fams = BSDFFamilies.build(scene.bsdfs, scene.mesh_bsdf)
        mesh_emitter = np.asarray(scene.mesh_emitter, np.int64)
        tri_emitter = np.append(mesh_emitter[tri_mesh] if len(tri_mesh) else np.zeros(0, np.int64), -1)
        mesh_code = np.where(mesh_emitter >= 0, CODE_EMITTER, 2 * fams.mesh_family[: len(mesh_emitter)] +
                             scene.geometry.mesh_smooth)
        tri_code = np.append(mesh_code[tri_mesh] if len(tri_mesh) else np.zeros(0, np.int64), CODE_MISS)
        codes = sorted(int(c) for c in set(mesh_code.tolist()) if c >= 0)
        bsdf_uv = any(not getattr(b, slot).constant for b in scene.bsdfs for slot in b.texture_slots)
        tri_member = np.take(fams.mesh_member, tri_mesh).astype(np.int64) if fams.any_tables else None
        tab = SceneTables(fams, tri_emitter, tri_code, codes, bsdf_uv, bool(np.any(mesh_emitter >= 0)), tri_member)
        tab.tri_tangent, tab.dpdu = tangent_table(scene, mesh_emitter)
        scene.__dict__["_tables"] = tab
    return tab


def tangent_table(scene, mesh_emitter: np.ndarray) -> tuple[np.ndarray | None, np.ndarray | None]:
    """(:attr:`SceneTables.tri_tangent`, :attr:`SceneTables.dpdu`): which triangles shade in the uv tangent's
    frame, and the geometry's dp/du; (None, None) when none do (no anisotropic material on a mesh with uvs)."""
    g = scene.geometry
    aniso = np.array([bool(getattr(b, "anisotropic", False)) for b in scene.bsdfs], bool)
    nm = len(mesh_emitter)
    if not nm or not aniso.any() or g.dpdu_cols() is None:
        return None, None
    mesh_tangent = aniso[np.asarray(scene.mesh_bsdf, np.int64)[:nm]] & (mesh_emitter < 0) & g.mesh_has_uvs[:nm]
    if not mesh_tangent.any():
        return None, None
    return np.ascontiguousarray(mesh_tangent[g.tri_mesh]), g.dpdu_cols()
