"""``path``, ``path_nee``, ``path_mis``: unidirectional path tracers (spec §13.2.6–8, assignment 4).

==============  =======  =======  ======================================================================
parameter       tag      default  meaning
==============  =======  =======  ======================================================================
``maxDepth``    integer  −1       segments of the longest path (1: emitters seen by the camera, 2: direct
                                  light, …); −1 = no limit, the unbiased default. A limit biases (drops
                                  the longer paths), identically for all three estimators.
``rrDepth``     integer  3        the first vertex at which Russian roulette may end a path (≥ 1)
==============  =======  =======  ======================================================================

All three estimate the rendering equation's solution L = L_e + ∫ f L cos θ dω (Kajiya 1986; Veach 1997, §10.3)
along camera rays, on arrays of live paths (:mod:`brdflab.integrator.wavefront`):

* ``path``: BSDF sampling only. At each vertex one direction ω ~ p_bsdf; emission found along it (an emitter,
  or the environment for an escaping ray) is added with the path throughput β and the path ends there (the
  emitter-hit rule).
* ``path_nee``: at every non-delta vertex one emitter sample as in ``direct_ems``,
  β · L_e f |cos θ_o| / (p_sel p_ω) · V; continue by BSDF sampling; emission found by BSDF sampling counts only
  after a delta sample (mirror, dielectric) or from the camera — elsewhere light sampling already counted it.
* ``path_mis``: both at every vertex, combined by the balance heuristic (Veach 1997, eq. 9.13) with densities in
  solid angle, the light's including its selection probability: w_l = p_l / (p_l + p_bsdf(ω_l)),
  w_b = p_b / (p_b + p_l(ω_b)); delta BSDF samples and delta lights weight 1. Emission found by a BSDF ray is
  counted once, MIS-weighted (not again by the next vertex: the path ends at an emitter).

Russian roulette from vertex ``rrDepth`` on: survival probability s = min(0.95, max_c β_c), survivors' β
divided by s (unbiased; every path ends with probability 1). The student bugs of spec §13.2.7–8 (NEE at delta
vertices only, uncompensated roulette, BSDF emission counted twice) are the tests' negative controls.
"""

from __future__ import annotations

import numpy as np

from brdflab.integrator.common import Integrator
from brdflab.integrator.wavefront import trace_paths
from brdflab.scene.properties import PropertyList


class PathBSDF(Integrator):
    """``path``: BSDF sampling only (see module docstring).

    Examples
    --------
    >>> import brdflab as bl
    >>> from pathlib import Path
    >>> scene = Path(bl.__file__).parents[1] / "scenes" / "cbox" / "cbox_diffuse.xml"
    >>> img = bl.render(bl.load_scene(scene, integrator="path_mis", width=16, height=12), spp=4, workers=1)
    >>> img.shape
    (12, 16, 3)
    """

    type_name = "path"
    KNOWN = {"maxDepth": "integer", "rrDepth": "integer"}
    #: The estimator of :func:`~brdflab.integrator.wavefront.trace_paths`.
    mode = "bsdf"

    def __init__(self, max_depth: int = -1, rr_depth: int = 3) -> None:
        self.max_depth = int(max_depth)
        self.rr_depth = int(rr_depth)

    @classmethod
    def from_properties(cls, props: PropertyList) -> PathBSDF:
        """Build from an ``<integrator type="path…">`` property list (``maxDepth``, ``rrDepth``)."""
        props.check_known(cls.KNOWN)
        max_depth = props.get_int("maxDepth", -1)
        if max_depth == 0 or max_depth < -1:
            raise props.error("maxDepth", f"'maxDepth' must be -1 (no limit) or ≥ 1, got {max_depth}")
        return cls(max_depth, props.int_in_range("rrDepth", 3, 1, 1_000_000))

    def li(self, scene, o, d, tmax, rng: np.random.Generator) -> np.ndarray:
        """Radiance along camera rays (see module docstring)."""
        return trace_paths(scene, o, d, tmax, rng, self.mode, self.max_depth, self.rr_depth)


class PathNEE(PathBSDF):
    """``path_nee``: next-event estimation (see module docstring)."""

    type_name = "path_nee"
    mode = "nee"


class PathMIS(PathBSDF):
    """``path_mis``: emitter and BSDF sampling combined by the balance heuristic (see module docstring)."""

    type_name = "path_mis"
    mode = "mis"
