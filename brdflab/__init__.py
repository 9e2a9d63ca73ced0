"""brdflab — a BRDF validation and visualisation workbench.

Renders Nori scene files under direct illumination with microfacet materials (NumPy-vectorised over
embreex ray queries), validates every material and sampling routine statistically, and compares Monte
Carlo estimators as error against run time.

The public API (``import brdflab as bl``; the tutorial is ``docs/api.md``):

=========================================  =====================================================================
``bl.load_scene(path, **overrides)``       a Nori scene (``integrator``, ``spp``, ``seed``, ``width``, ``height``)
``bl.render(scene, spp, seed, workers)``   the (H, W, 3) float32 image (``return_stats=True``: also the stats)
``bl.read_exr``, ``bl.write_exr``          linear RGB OpenEXR files
``bl.Diffuse``, ``bl.RoughConductor``,     the materials, with keyword parameters named as in scene files
``bl.RoughSubstrate``, ``bl.Measured``,    (``Measured``: a MERL table, :mod:`brdflab.bsdf.measured`;
``bl.Mirror``, ``bl.Dielectric``,          ``Mirror`` and ``Dielectric`` are delta BSDFs, ``Dielectric`` and
``bl.RoughDielectric``                     ``RoughDielectric`` transmit: :mod:`brdflab.bsdf.base`)
``bl.fit(measured, model)``                least-squares fit of a model's parameters to a measured BRDF
``bl.BSDF``, ``bl.BSDFSample``             the contract a user's material implements (:mod:`brdflab.bsdf.base`)
``bl.register_bsdf``, ``bl.load_plugin``   make a user's BSDF known to scenes and every command
``bl.plugins``                             the registry (:mod:`brdflab.plugins`)
``bl.warps``                               square-to-sphere/disk/triangle warps and their pdfs
``bl.kernels``                             the engines (``bl.kernels.use_engine("numpy")``: the NumPy path)
``bl.chi2_test`` …                         the statistical checks, returning result objects
``bl.check``, ``bl.compare``, ``bl.report`` the commands' workflows (:mod:`brdflab.workflows`), returning
``bl.plot``, ``bl.validate``               the result objects the commands write as JSON
``bl.check_samples``, ``bl.bench`` …       samples from another renderer, speed, the explorer
                                           (:mod:`brdflab.workflows_extra`); ``docs/api.md`` maps every command
                                           option to its Python name
=========================================  =====================================================================

Names are imported on first use, so ``import brdflab`` stays fast.
"""

from __future__ import annotations

import importlib
from typing import Any

__version__ = "0.1.0"

#: Public name → "module:attribute" (imported lazily, PEP 562).
_EXPORTS = {
    "load_scene": "brdflab.api:load_scene",
    "render": "brdflab.api:render",
    "read_exr": "brdflab.imageio:read_exr",
    "write_exr": "brdflab.imageio:write_exr",
    "BSDF": "brdflab.bsdf.base:BSDF",
    "BSDFSample": "brdflab.bsdf.base:BSDFSample",
    "Diffuse": "brdflab.bsdf.diffuse:Diffuse",
    "RoughConductor": "brdflab.bsdf.roughconductor:RoughConductor",
    "RoughSubstrate": "brdflab.bsdf.roughsubstrate:RoughSubstrate",
    "Mirror": "brdflab.bsdf.mirror:Mirror",
    "Dielectric": "brdflab.bsdf.dielectric:Dielectric",
    "RoughDielectric": "brdflab.bsdf.roughdielectric:RoughDielectric",
    "register_bsdf": "brdflab.plugins:register_bsdf",
    "load_plugin": "brdflab.plugins:load_plugin",
    "make_bsdf": "brdflab.plugins:make_bsdf",
    "BrdflabError": "brdflab.errors:BrdflabError",
    "plugins": "brdflab.plugins",
    "warps": "brdflab.math.warps",
    "kernels": "brdflab.kernels",
    "effort": "brdflab.effort",
    "chi2_test": "brdflab.judges:chi2_test",
    "warp_chi2_test": "brdflab.judges:warp_chi2_test",
    "consistency_test": "brdflab.judges:consistency_test",
    "furnace_test": "brdflab.judges:furnace_test",
    "delta_test": "brdflab.judges:delta_test",
    "stability_test": "brdflab.judges:stability_test",
    "run_battery": "brdflab.judges:run_battery",
    "emitter_checks": "brdflab.judges:emitter_checks",
    "estimator_agreement": "brdflab.judges:estimator_agreement",
    "check": "brdflab.workflows:check",
    "compare": "brdflab.workflows:compare",
    "report": "brdflab.workflows:report",
    "plot": "brdflab.workflows:plot",
    "validate": "brdflab.workflows:validate",
    "fit": "brdflab.fitting:fit",
    "check_samples": "brdflab.workflows_extra:check_samples",
    "check_emitter_samples": "brdflab.workflows_extra:check_emitter_samples",
    "bench": "brdflab.workflows_extra:bench",
    "explore": "brdflab.workflows_extra:explore",
    "Measured": "brdflab.bsdf.measured:Measured",
}

__all__ = ["__version__", *_EXPORTS]


def __getattr__(name: str) -> Any:
    target = _EXPORTS.get(name)
    if target is None:
        raise AttributeError(f"module 'brdflab' has no attribute '{name}'")
    module, _, attr = target.partition(":")
    value = importlib.import_module(module)
    if attr:
        value = getattr(value, attr)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(__all__)
