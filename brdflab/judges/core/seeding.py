"""Default seeds: every check gets its own random stream, derived from the test's identity.

``test_seed("chi2", bsdf, params, theta)`` hashes the kind of test, the BSDF's type (``type_name`` or
qualified class name), its parameters and the incident angle. Two configurations of one plugin, or two
checks of one configuration, therefore never share random numbers (formerly every API-level test used
seed 0, and six configurations of one plugin all gave p = 0.1049), while a re-run is reproducible.
"""

from __future__ import annotations

import hashlib

import numpy as np


def _canon(v) -> str:
    if isinstance(v, dict):
        return "{" + ",".join(f"{k}:{_canon(v[k])}" for k in sorted(v, key=str)) + "}"
    if isinstance(v, list | tuple):
        return "[" + ",".join(_canon(x) for x in v) + "]"
    if isinstance(v, np.ndarray):
        return _canon(v.tolist())
    if isinstance(v, float | np.floating):
        return repr(float(v))
    return repr(v)


def bsdf_identity(bsdf) -> str:
    """The BSDF's type for seeding: ``type_name`` plus the qualified class name."""
    inner = getattr(bsdf, "inner", bsdf)
    cls = type(inner)
    return f"{getattr(inner, 'type_name', '')}|{cls.__module__}.{cls.__qualname__}"


def test_seed(kind: str, *parts) -> int:
    """A reproducible 63-bit seed for one test, from its kind and identity ``parts``.

    Examples
    --------
    >>> from brdflab.judges.core.seeding import test_seed
    >>> test_seed("chi2", "phong", {"exponent": 20}, 30.0) == test_seed("chi2", "phong", {"exponent": 20}, 30.0)
    True
    >>> test_seed("chi2", "phong", {"exponent": 20}, 30.0) == test_seed("chi2", "phong", {"exponent": 5}, 30.0)
    False
    """
    digest = hashlib.sha256(_canon((kind, *parts)).encode()).digest()
    return int.from_bytes(digest[:8], "little") >> 1


test_seed.__test__ = False  # not a pytest test
