"""``pointlight``: an isotropic point source (spec §9.2).

==============  =======  ============  ==========================================================
parameter       tag      default       meaning
==============  =======  ============  ==========================================================
``position``    point    (0, 100, 0)   world-space position p
``radiance``    color    (1, 1, 1)     radiant **intensity** I (W/sr), despite its name
==============  =======  ============  ==========================================================

Incident radiance contribution at x: I/‖p − x‖² along ω = (p − x)/‖p − x‖; no 4π, no cosine at the light.
A delta light: pdf 1 by convention, never hit by rays, MIS weight 1.
"""

from __future__ import annotations

import numpy as np

from brdflab.emitter.area import LUMINANCE
from brdflab.emitter.base import Emitter, EmitterSample
from brdflab.math.frame import dot
from brdflab.scene.properties import PropertyList


class PointLight(Emitter):
    """Isotropic point light of intensity ``intensity`` at ``position``."""

    type_name = "pointlight"
    is_delta = True
    KNOWN = {"position": "point", "radiance": "color"}

    def __init__(self, position: np.ndarray, intensity: np.ndarray) -> None:
        self.position = np.asarray(position, dtype=np.float64)
        self.intensity = np.asarray(intensity, dtype=np.float64)

    @classmethod
    def from_properties(cls, props: PropertyList) -> PointLight:
        """Build from an ``<emitter type="pointlight">`` property list."""
        props.check_known(cls.KNOWN)
        pos = props.get_point("position", np.array([0.0, 100.0, 0.0]))
        if not np.all(np.isfinite(pos)):
            raise props.error("position", "'position' must be finite")
        return cls(pos, props.nonnegative_color("radiance", np.ones(3)))

    def sample(self, ref_p: np.ndarray, u: np.ndarray) -> EmitterSample:
        """Deterministic 'sample': the direction to the light, I/r², pdf 1."""
        delta = self.position - ref_p
        dist2 = dot(delta, delta)
        dist = np.sqrt(dist2)
        ok = dist > 0
        wi = delta / np.where(ok, dist, 1.0)[:, None]
        radiance = np.where(ok[:, None], self.intensity / np.where(ok, dist2, 1.0)[:, None], 0.0)
        return EmitterSample(wi, dist, radiance, np.ones(len(ref_p)))

    def power(self) -> float:
        """Luminance of the intensity (spec §8)."""
        return float(LUMINANCE @ self.intensity) * 4 * np.pi
