"""``mirror``: a perfect specular reflector, one-sided (spec §10.3; PBR §8.2.2).

=============  ======  =======  ==============================================================
parameter      tag     default  meaning
=============  ======  =======  ==============================================================
(none)                          Nori's mirror takes no parameters
=============  ======  =======  ==============================================================

f(ω_i, ω_o) = δ(ω_o − R(ω_i)) / |cos θ_o| with R(ω_i) = (−ω_i,x, −ω_i,y, ω_i,z) (PBR eq. 8.7, reflectance 1).

* ``sample``: ω_o = R(ω_i), ``delta`` = True, weight f·cos θ_o/p = 1 and ``pdf`` = 1 (the discrete
  probability of the only lobe). One-sided: where cos θ_i ≤ 0 the sample fails (weight 0, pdf 0).
* ``eval`` and ``pdf`` return 0: a delta has measure zero, a direction given from outside never hits it.
"""

from __future__ import annotations

import numpy as np

from brdflab.bsdf.base import BSDF, BSDFSample
from brdflab.scene.properties import PropertyList


def mirror_direction(w: np.ndarray) -> np.ndarray:
    """Reflection about the shading normal z: (−x, −y, z)."""
    return w * np.array([-1.0, -1.0, 1.0])


class Mirror(BSDF):
    """Perfect mirror (see module docstring).

    Examples
    --------
    >>> import numpy as np
    >>> from brdflab import Mirror
    >>> s = Mirror().sample(np.array([[0.6, 0.0, 0.8]]), np.full((1, 3), 0.5))
    >>> s.wo.tolist(), s.weight.tolist(), s.pdf.tolist(), s.delta.tolist()
    ([[-0.6, -0.0, 0.8]], [[1.0, 1.0, 1.0]], [1.0], [True])
    """

    type_name = "mirror"
    KNOWN: dict[str, str] = {}
    has_delta = True
    all_delta = True

    @classmethod
    def from_properties(cls, props: PropertyList) -> Mirror:
        """Build from a ``<bsdf type="mirror">`` property list (no parameters)."""
        props.check_known(cls.KNOWN)
        return cls()

    def eval(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None = None) -> np.ndarray:
        """0 (N, 3): the delta lobe has measure zero."""
        return np.zeros((len(wi), 3))

    def pdf(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None = None) -> np.ndarray:
        """0 (N,): no solid-angle density."""
        return np.zeros(len(wi))

    def sample(self, wi: np.ndarray, u: np.ndarray, uv: np.ndarray | None = None) -> BSDFSample:
        """The mirror direction, weight 1 and pdf 1 where cos θ_i > 0 (0 below: one-sided)."""
        ok = wi[:, 2] > 0
        weight = np.where(ok[:, None], 1.0, 0.0) * np.ones((1, 3))
        return BSDFSample(mirror_direction(wi), weight, ok.astype(np.float64), np.ones(len(wi), dtype=bool))
