"""``direct_ems``: direct illumination by emitter sampling (spec §13.2.3, seed equation (9)).

No parameters.

For a camera ray whose first hit x (shading normal n_s) is not on an emitter:

    L = L_e(y → x) · f(ω_i, ω) · (n_s·ω) / (p_sel · p_ω) · V(x, y)

with one emitter chosen with probability p_sel (uniform by default) and one sample of it (direction ω,
solid-angle pdf p_ω). Misses return the background; hits on an emitter return its L_e and stop. A delta
material (mirror, dielectric) gets no contribution: f = 0 for every sampled light direction (spec §13).
"""

from __future__ import annotations

import numpy as np

from brdflab.integrator.common import Integrator, light_dims, light_term, point_uniforms, set_rows, trace_camera


class DirectEMS(Integrator):
    """Emitter sampling, one light sample per camera sample."""

    type_name = "direct_ems"

    def li(self, scene, o, d, tmax, rng: np.random.Generator) -> np.ndarray:
        """Radiance along camera rays (see module docstring)."""
        L, sp = trace_camera(scene, o, d, tmax)
        if len(sp.index) == 0 or not scene.emitters:
            return L
        set_rows(L, sp.index, light_term(scene, sp, point_uniforms(rng, len(o), sp, light_dims(scene))))
        return L
