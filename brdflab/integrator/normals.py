"""``normals``: |shading normal| per component as RGB at the first hit; black on a miss (spec §13.2.1).

No parameters. A debugging view.
"""

from __future__ import annotations

import numpy as np

from brdflab.integrator.common import Integrator


class NormalsIntegrator(Integrator):
    """Shows the absolute shading normal."""

    type_name = "normals"
    needs_emitters = False

    def li(self, scene, o, d, tmax, rng: np.random.Generator) -> np.ndarray:
        """|n_s| at the first hit, 0 on a miss."""
        hits = scene.geometry.intersect(o, d, tmax)
        return np.where(hits.valid[:, None], np.abs(hits.ns), 0.0)
