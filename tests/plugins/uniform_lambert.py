"""A user's plugin written only against the documented contract (kept for the tests, not shipped).

``uniform_lambert``: f = albedo/π, sampled uniformly over the hemisphere (pdf 1/2π), so that its
estimator differs from the built-in cosine-weighted ``diffuse`` while the image must not.
``uniform_lambert_broken``: the same, with a warp bug (cos θ = ξ² instead of ξ) and the pdf left right.
"""

import numpy as np

import brdflab as bl


class UniformLambert(bl.BSDF):
    type_name = "uniform_lambert"

    def __init__(self, albedo=(0.5, 0.5, 0.5), scale=1.0):
        self.albedo = np.asarray(albedo, float)
        self.scale = float(scale)

    def eval(self, wi, wo, uv=None):
        up = (wi[:, 2] > 0) & (wo[:, 2] > 0)
        return (up * (self.scale / np.pi))[:, None] * self.albedo

    def pdf(self, wi, wo, uv=None):
        return np.where((wi[:, 2] > 0) & (wo[:, 2] > 0), 1.0 / (2.0 * np.pi), 0.0)

    def _warp(self, u):
        z = u[:, 0]
        r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
        phi = 2.0 * np.pi * u[:, 1]
        return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)

    def sample(self, wi, u, uv=None):
        wo = self._warp(u)
        pdf = self.pdf(wi, wo)
        f = self.eval(wi, wo)
        with np.errstate(divide="ignore", invalid="ignore"):
            w = np.where((pdf > 0)[:, None], f * (wo[:, 2] / pdf)[:, None], 0.0)
        return bl.BSDFSample(wo, w, pdf)


class BrokenUniformLambert(UniformLambert):
    type_name = "uniform_lambert_broken"

    def _warp(self, u):
        return super()._warp(np.stack([u[:, 0] ** 2, u[:, 1]], axis=1))
