"""``direct_whitted``: one sample of **every** emitter at the first hit (spec §13.2.2).

No parameters. L = Σ_e L_e^smp · f(ω_i, ω) · (n_s·ω) / p_ω · V, with the shadow ray limited to the
segment between the point and the light (Nori's student version, unbounded, is not copied). No emission
is added at the camera hit (Nori's Whitted skeleton). There is no mirror recursion: a delta material
(mirror, dielectric) gets nothing here (its f is 0 for every light direction); the path tracers render it.
"""

from __future__ import annotations

import numpy as np

from brdflab.integrator.common import Integrator, background, eval_bsdfs, shading_points


class DirectWhitted(Integrator):
    """Sum of one sample per emitter."""

    type_name = "direct_whitted"

    def li(self, scene, o, d, tmax, rng: np.random.Generator) -> np.ndarray:
        """Radiance along camera rays (see module docstring)."""
        g = scene.geometry
        hits = g.intersect(o, d, tmax)
        L = np.zeros((len(o), 3))
        miss = ~hits.valid
        L[miss] = background(scene, d[miss])
        idx = np.flatnonzero(hits.valid)
        if len(idx) == 0:
            return L
        sp = shading_points(scene, hits, d, idx)
        for em in scene.emitters:
            r = em.sample(sp.p, rng.random((len(idx), 3)))
            wo = sp.local(r.wi)
            f = eval_bsdfs(scene, sp, wo)
            live = np.flatnonzero((r.pdf > 0) & np.any(r.radiance * f > 0, axis=1))
            if len(live) == 0:
                continue
            origin = g.offset_origin(sp.p[live], sp.ng[live], r.wi[live])
            vis = ~g.occluded(origin, r.wi[live], g.shadow_tmax(r.dist[live]))
            c = r.radiance[live] * f[live] * (np.maximum(wo[live, 2], 0.0) / r.pdf[live] * vis)[:, None]
            L[sp.index[live]] += c
        return L
