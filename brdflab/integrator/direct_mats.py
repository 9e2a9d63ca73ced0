"""``direct_mats``: direct illumination by BSDF sampling (spec §13.2.4, seed equation (10)).

No parameters.

At the first hit x (not an emitter), one direction ω ~ p_bsdf(· | ω_i) is traced:

    L = w · L_e(y → x),   w = f(ω_i, ω) cos θ / p_bsdf(ω)   (the BSDF sample weight)

where L_e is the radiance of the emitter mesh the ray hits (one-sided), or the environment when it
escapes, and 0 otherwise. Misses of the camera ray return the background; camera hits on an emitter
return its L_e and stop. Point lights cannot be found this way (their contribution is 0 here). A delta
material (mirror, dielectric) works unchanged: its sample's weight is the whole throughput factor.
"""

from __future__ import annotations

import numpy as np

from brdflab.integrator.common import (
    Integrator,
    accumulate,
    any_positive,
    emission_along,
    point_uniforms,
    sample_bsdfs,
    trace_camera,
)
from brdflab.kernels import compiled, load
from brdflab.math.frame import take_rows


def bsdf_rays(scene, sp, u: np.ndarray):
    """Sample the BSDF at every shading point and trace the rays that carry weight.

    Returns
    -------
    (live, weight, pdf_bsdf, Le, pdf_light)
        ``live`` indexes the shading points whose sample has a non-zero weight; the other arrays are
        restricted to them: BSDF weight f·cos/p, BSDF pdf, radiance found along the ray, and the
        solid-angle pdf with which light sampling would pick that direction (selection included). A sample
        from a delta lobe (mirror, dielectric) has pdf_bsdf = ∞ (a Dirac delta's density), so the MIS
        weights of ``direct_mis`` give it 1 (spec §13.2.5) and light sampling 0.
    """
    wo, weight, pdf, delta = sample_bsdfs(scene, sp, u, with_delta=True)
    if delta is not None:
        pdf = np.where(delta, np.inf, pdf)
    live, d, o, weight, pdf = spawn_rays(scene, sp, wo, weight, pdf)
    Le, pdf_light = emission_along(scene, o, d)
    return live, weight, pdf, Le, pdf_light


def spawn_rays(scene, sp, wo: np.ndarray, weight: np.ndarray, pdf: np.ndarray):
    """The rays of the BSDF samples (local ``wo``) that carry weight: (live, world d, origins (float32, off the
    surface on the side d leaves toward: reflected and transmitted rays alike), weight[live], pdf[live])."""
    g = scene.geometry
    if compiled():
        return load("direct").bsdf_ray_batch(g, sp, wo, weight, pdf)
    live = np.flatnonzero(any_positive(weight))
    if len(live) == len(wo):
        # Every sample carries weight (e.g. diffuse surfaces only): the gathers would copy every row.
        d, p, ng = sp.world(wo), sp.p, sp.ng
    else:
        d = sp.world(take_rows(wo, live), live)
        p, ng, weight, pdf = (take_rows(sp.p, live), take_rows(sp.ng, live), take_rows(weight, live),
                              np.take(pdf, live))
    d /= np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2])[:, None]
    o = g.offset_origin(p, ng, d, f32=True)
    return live, d, o, weight, pdf


class DirectMATS(Integrator):
    """BSDF sampling, one BSDF sample per camera sample."""

    type_name = "direct_mats"

    def li(self, scene, o, d, tmax, rng: np.random.Generator) -> np.ndarray:
        """Radiance along camera rays (see module docstring)."""
        L, sp = trace_camera(scene, o, d, tmax)
        if len(sp.index) == 0:
            return L
        live, weight, _, Le, _ = bsdf_rays(scene, sp, point_uniforms(rng, len(o), sp, 3))
        accumulate(L, sp.index[live], weight, Le)
        return L
