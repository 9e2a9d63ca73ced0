"""Temporary stand-in for :mod:`brdflab.plugins` (built-ins only) until the registry lands."""

from __future__ import annotations

import numpy as np

from brdflab.errors import BrdflabError


def _value(key: str, text: str):
    try:
        parts = [float(x) for x in str(text).split(",")]
    except ValueError:
        raise BrdflabError(f"parameter {key}: expected a number, got '{text}'") from None
    if not all(np.isfinite(parts)):
        raise BrdflabError(f"parameter {key}: expected a finite number, got '{text}'")
    return np.array(parts * 3 if len(parts) == 1 else parts) if len(parts) in (1, 3) else parts[0]


def bsdf_names() -> list[str]:
    return ["diffuse", "roughconductor", "roughsubstrate"]


def make_bsdf(name: str, params: dict | None = None, alpha: float | None = None):
    from brdflab.bsdf.diffuse import Diffuse
    from brdflab.bsdf.roughconductor import RoughConductor
    from brdflab.bsdf.roughsubstrate import RoughSubstrate

    p = {k: _value(k, v) for k, v in (params or {}).items()}
    if alpha is not None:
        p.setdefault("alpha", alpha)
    a = float(np.mean(p.get("alpha", 0.1)))
    if name == "diffuse":
        return Diffuse(p.get("albedo", 0.5))
    if name == "roughconductor":
        return RoughConductor(p.get("R0", 0.5), a)
    if name == "roughsubstrate":
        return RoughSubstrate(p.get("kd", 0.5), a, float(np.mean(p.get("intIOR", 1.5046))),
                              float(np.mean(p.get("extIOR", 1.000277))))
    raise BrdflabError(f"unknown BSDF '{name}'; valid: {', '.join(bsdf_names())}")


def load_plugin(spec: str) -> list[str]:
    raise BrdflabError("plugins need brdflab.plugins (not landed yet)")
