"""The built-in scene-object types (the registry's fixed part, :mod:`brdflab.plugins` holds the users' part):
tag → type name → ``"module:Class"``, imported on first use, and the Nori plugins brdflab leaves out."""

from __future__ import annotations

#: Built-in scene-object types: tag → type name → ``"module:Class"`` (imported on first use).
BUILTIN: dict[str, dict[str, str]] = {
    "bsdf": {
        "diffuse": "brdflab.bsdf.diffuse:Diffuse",
        "roughconductor": "brdflab.bsdf.roughconductor:RoughConductor",
        "roughsubstrate": "brdflab.bsdf.roughsubstrate:RoughSubstrate",
        "measured": "brdflab.bsdf.measured:Measured",
        "mirror": "brdflab.bsdf.mirror:Mirror",
        "dielectric": "brdflab.bsdf.dielectric:Dielectric",
        "roughdielectric": "brdflab.bsdf.roughdielectric:RoughDielectric",
    },
    "emitter": {
        "area": "brdflab.emitter.area:AreaEmitter",
        "pointlight": "brdflab.emitter.point:PointLight",
        "environment": "brdflab.emitter.environment:EnvironmentEmitter",
    },
    "integrator": {
        "normals": "brdflab.integrator.normals:NormalsIntegrator",
        "direct_ems": "brdflab.integrator.direct_ems:DirectEMS",
        "direct_mats": "brdflab.integrator.direct_mats:DirectMATS",
        "direct_mis": "brdflab.integrator.direct_mis:DirectMIS",
        "direct_whitted": "brdflab.integrator.direct_whitted:DirectWhitted",
        "path": "brdflab.integrator.path:PathBSDF",
        "path_nee": "brdflab.integrator.path:PathNEE",
        "path_mis": "brdflab.integrator.path:PathMIS",
    },
}
#: Nori plugins brdflab deliberately leaves out.
UNSUPPORTED = {
    "bsdf": (),
    "integrator": ("depth", "vpl"),
}


def is_builtin_class(cls: type) -> bool:
    """True for the classes of :data:`BUILTIN` BSDF types (not their subclasses)."""
    return any(f"{cls.__module__}:{cls.__qualname__}" == t for t in BUILTIN["bsdf"].values())
