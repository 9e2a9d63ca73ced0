"""Material families: materials that differ only in constants, evaluated as one batch.

A scene often has several instances of one material type with different constant parameters (the
Cornell box's three diffuse walls, the four roughsubstrate plates of the Veach scene). Evaluating them one
by one splits every batch of shading points into groups (gathers, one call each, scatters back). A
*family* instead holds each member's constants in a table, and :meth:`BSDFFamily.bind` returns one copy
of the material whose texture slots hold each point's own member's constant
(:class:`~brdflab.texture.PointValues`): the formulas are element-wise, so the result is the same as
the per-member evaluation, in one call.

Members of a family share the class and :meth:`~brdflab.bsdf.base.BSDF.scalar_parameters` and have only
constant texture slots (:meth:`~brdflab.bsdf.base.BSDF.family_key`); a textured material is a family of
its own.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from brdflab.bsdf.base import BSDF
from brdflab.texture import PointValues


class BSDFFamily:
    """Materials evaluated together (see module docstring).

    Parameters
    ----------
    members
        The materials, all with the same :meth:`~brdflab.bsdf.base.BSDF.family_key` (or a single one).
    """

    def __init__(self, members: list[BSDF]) -> None:
        self.members = members
        first = members[0]
        # Per varying slot: (3, K) constants and (K,) luminances. Slots equal in all members stay as they are.
        self.tables: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        if len(members) > 1:
            for slot in first.texture_slots:
                texs = [getattr(m, slot) for m in members]
                values = np.stack([t.value for t in texs], axis=1)
                if np.all(values == values[:, :1]):
                    continue
                self.tables[slot] = (np.ascontiguousarray(values), np.array([t.luminance() for t in texs]))

    def bind(self, member: np.ndarray | None = None) -> BSDF:
        """The material for a batch of points whose member indices are ``member`` ((N,) int).

        A family of one (or whose members are identical) returns its material itself.
        """
        if not self.tables:
            return self.members[0]
        return self.members[0].with_point_values(
            {slot: PointValues(values, lum, member) for slot, (values, lum) in self.tables.items()})


@dataclass
class BSDFFamilies:
    """A scene's materials grouped into families, with per-mesh lookups."""

    families: list[BSDFFamily]
    mesh_family: np.ndarray
    """(meshes,) family index of each mesh's material."""
    mesh_member: np.ndarray
    """(meshes,) index of each mesh's material within its family."""

    @property
    def any_tables(self) -> bool:
        """True when some family has members with different constants (points need member indices)."""
        return any(f.tables for f in self.families)

    @classmethod
    def build(cls, bsdfs: list[BSDF], mesh_bsdf: np.ndarray) -> BSDFFamilies:
        """Group ``bsdfs`` by :meth:`~brdflab.bsdf.base.BSDF.family_key`; ``mesh_bsdf`` maps mesh → bsdf."""
        keys: dict[tuple, int] = {}
        groups: list[list[int]] = []
        bsdf_family = np.zeros(len(bsdfs), np.int64)
        bsdf_member = np.zeros(len(bsdfs), np.int64)
        for b, bsdf in enumerate(bsdfs):
            key = bsdf.family_key()
            g = keys.setdefault(key, len(groups)) if key is not None else len(groups)
            if g == len(groups):
                groups.append([])
            bsdf_family[b], bsdf_member[b] = g, len(groups[g])
            groups[g].append(b)
        families = [BSDFFamily([bsdfs[b] for b in g]) for g in groups]
        mesh_bsdf = np.asarray(mesh_bsdf, np.int64)
        return cls(families, bsdf_family[mesh_bsdf], bsdf_member[mesh_bsdf])
