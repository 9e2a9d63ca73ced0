"""``direct_mis``: multiple importance sampling of emitter and BSDF samples (spec §13.2.5, eq. (11)).

=============  ======  =========  ===========================================================
parameter      tag     default    meaning
=============  ======  =========  ===========================================================
``heuristic``  string  balance    ``balance`` (β = 1, as the assignment asks) or ``power`` (β = 2)
=============  ======  =========  ===========================================================

One emitter sample (ω_l, pdf p_l = p_sel·p_ω) and one BSDF sample (ω_b, pdf p_b) per camera sample
(Veach 1997, eq. 9.13, one sample per technique):

    L = L_e f cos / p_l · w_l(ω_l) + L_e f cos / p_b · w_b(ω_b),
    w_l = p_l^β / (p_l^β + p_bsdf(ω_l)^β),   w_b = p_b^β / (p_b^β + p_light(ω_b)^β)

with both densities in solid angle and p_light including the emitter-selection probability (the
student's version omits it). Delta lights get w_l = 1 (BSDF sampling cannot find them), and so do samples
of a delta BSDF lobe (mirror, dielectric: w_b = 1, light sampling cannot find those directions; ``bsdf_rays``
gives them p_b = ∞, which the heuristic maps to 1); the environment is weighted like any other emitter (no double
counting).
"""

from __future__ import annotations

import numpy as np

from brdflab.integrator.common import (
    Integrator,
    accumulate,
    light_dims,
    light_term,
    point_uniforms,
    set_rows,
    trace_camera,
)
from brdflab.integrator.direct_mats import bsdf_rays
from brdflab.scene.properties import PropertyList


def mis_weight(p_this: np.ndarray, p_other: np.ndarray, beta: float) -> np.ndarray:
    """Balance (β = 1) or power (β = 2) heuristic weight of a sample with density ``p_this``."""
    a = p_this if beta == 1 else p_this**beta
    b = p_other if beta == 1 else p_other**beta
    with np.errstate(divide="ignore", invalid="ignore"):
        w = np.where(a > 0, a / (a + b), 0.0)
    return np.where(np.isfinite(w), w, 1.0)


class DirectMIS(Integrator):
    """Emitter + BSDF sampling combined by the balance (or power) heuristic."""

    type_name = "direct_mis"
    KNOWN = {"heuristic": "string"}
    #: Which terms ``li`` returns: ``"both"`` (the estimator), or for MIS weight images only the
    #: weighted ``"emitter"`` or ``"bsdf"`` samples (camera-visible emission left out). The random numbers
    #: drawn are the same, so with one seed the two parts add up to the estimate minus that emission.
    parts = "both"

    def __init__(self, heuristic: str = "balance") -> None:
        if heuristic not in ("balance", "power"):
            from brdflab.errors import BrdflabError

            raise BrdflabError(f"direct_mis: heuristic must be 'balance' or 'power', got '{heuristic[:40]}'")
        self.heuristic = heuristic
        self.beta = 1.0 if heuristic == "balance" else 2.0

    @classmethod
    def from_properties(cls, props: PropertyList) -> DirectMIS:
        """Build from an ``<integrator type="direct_mis">`` property list."""
        props.check_known(cls.KNOWN)
        h = props.get_string("heuristic", "balance")
        if h not in ("balance", "power"):
            raise props.error("heuristic", f"'heuristic' must be 'balance' or 'power', got '{h}'")
        return cls(h)

    def li(self, scene, o, d, tmax, rng: np.random.Generator) -> np.ndarray:
        """Radiance along camera rays (see module docstring)."""
        L, sp = trace_camera(scene, o, d, tmax)
        if self.parts != "both":
            L[:] = 0.0
        m = len(sp.index)
        if m == 0:
            return L
        k = light_dims(scene)
        u = point_uniforms(rng, len(o), sp, k + 3)
        if scene.emitters and self.parts != "bsdf":
            Lsp = light_term(scene, sp, u[:, :k],
                             lambda ls, p_bsdf: np.where(ls.delta, 1.0, mis_weight(ls.pdf, p_bsdf, self.beta)))
        else:
            Lsp = np.zeros((m, 3), order="F")
        if self.parts != "emitter":
            live, weight, p_b, Le, p_l = bsdf_rays(scene, sp, u[:, k:])
            accumulate(Lsp, live, weight, Le, mis_weight(p_b, p_l, self.beta))
        set_rows(L, sp.index, Lsp)
        return L
