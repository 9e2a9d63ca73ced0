"""The vectorised emitter interface (spec §8–9).

* ``sample(ref_p, u)`` → :class:`EmitterSample` for N reference points ``ref_p`` (N, 3) world space and
  uniforms ``u`` (N, 3): unit direction ``wi`` from the reference point toward the light, distance
  ``dist`` (``inf`` for the environment), incident radiance ``radiance`` (for a point light I/r²), and
  ``pdf``, the solid-angle density at the receiver **without** the emitter-selection probability
  (1 for delta lights by convention).
* Area lights and the environment can also be *hit* by BSDF-sampled rays; they implement the extra
  queries documented on their classes (``eval``/``pdf`` of hits or directions) used by ``direct_mats``
  and ``direct_mis``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class EmitterSample(NamedTuple):
    """Result of :meth:`Emitter.sample` for N reference points."""

    wi: np.ndarray
    """(N, 3) unit world directions from the reference point toward the sampled light point."""
    dist: np.ndarray
    """(N,) distance to the light point (``inf`` for environment lights)."""
    radiance: np.ndarray
    """(N, 3) radiance arriving at the reference point (0 where it faces away)."""
    pdf: np.ndarray
    """(N,) solid-angle density at the reference point, selection probability excluded."""


class Emitter:
    """Base class of emitters."""

    type_name: str = ""
    #: Delta lights (point lights) cannot be hit by rays; MIS gives their samples weight 1.
    is_delta: bool = False
    #: True for the environment (infinitely distant, the background of escaping rays).
    is_environment: bool = False

    def sample(self, ref_p: np.ndarray, u: np.ndarray) -> EmitterSample:
        """Sample N light directions as seen from ``ref_p``."""
        raise NotImplementedError

    def power(self) -> float:
        """A luminance-based power estimate, used for power-proportional emitter selection."""
        raise NotImplementedError
