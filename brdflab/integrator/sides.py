"""Which side of a surface light may come from: the cosine factor of an emitter sample (spec §10.1, CONTRACT §3).

A one-sided material reflects only (f = 0 unless cos θ_i > 0 and cos θ_o > 0), so the light term's factor is
max(cos θ_o, 0): the clamp keeps a user's BSDF that returns a value below the horizon from adding light there.
A material with ``has_transmission`` (roughdielectric) scatters into the whole sphere: light arriving through
the surface counts with |cos θ_o|.
"""

from __future__ import annotations

import numpy as np

from brdflab.integrator.tables import scene_tables


def transmitting(scene, groups) -> list:
    """The slices of ``groups`` ((family, slice) of :class:`~brdflab.integrator.common.ShadingPoints`) whose
    material declares ``has_transmission``."""
    families = scene_tables(scene).bsdf_families.families
    return [sel for g, sel in groups if getattr(families[g].members[0], "has_transmission", False)]


def transmitted_cos(scene, sp, wo: np.ndarray) -> np.ndarray:
    """``wo`` (local directions of the points ``sp``) with z replaced by |z| at the points on transmitting
    materials, so that max(z, 0) is |cos θ_o| there; ``wo`` itself when there are none.

    Examples
    --------
    >>> import numpy as np, brdflab as bl
    >>> from pathlib import Path
    >>> from brdflab.integrator.common import trace_camera
    >>> scene = bl.load_scene(Path(bl.__file__).parents[1] / "scenes" / "cbox" / "cbox_diffuse.xml")
    >>> _, sp = trace_camera(scene, np.array([[0.0, 1.0, 3.5]]), np.array([[0.0, 0.0, -1.0]]), np.array([np.inf]))
    >>> wo = np.array([[0.0, 0.6, -0.8]])
    >>> transmitted_cos(scene, sp, wo) is wo  # diffuse walls reflect only: max(cos θ_o, 0) stays
    True
    """
    through = transmitting(scene, sp.groups)
    if not through:
        return wo
    wo = np.array(wo, order="F")
    for sel in through:
        np.abs(wo[sel, 2], out=wo[sel, 2])
    return wo
