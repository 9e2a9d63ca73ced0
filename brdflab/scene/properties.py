"""Typed property lists of Nori scene objects (spec §2.4).

A :class:`PropertyList` holds the ``<integer>``, ``<float>``, ``<boolean>``, ``<string>``, ``<point>``,
``<vector>``, ``<color>`` and ``<transform>`` tags of one object. Getters check the tag type strictly,
as Nori does, and :meth:`PropertyList.check_known` rejects property names a plugin does not know, listing
the valid ones.
"""

from __future__ import annotations

from dataclasses import dataclass
from difflib import get_close_matches
from typing import Any

import numpy as np

from brdflab.errors import SceneError, clean

#: Largest colour component accepted: radiance times the filter weights must stay inside the float32 image.
MAX_COMPONENT = 1e30

_REQUIRED = object()


@dataclass
class Property:
    """One parsed property tag: its tag type, value and where it was written."""

    kind: str
    value: Any
    file: str | None
    line: int | None


class PropertyList:
    """The properties of one scene object, with type-checked getters.

    Parameters
    ----------
    owner
        Human-readable owner, e.g. ``'bsdf "roughconductor"'``, used in messages.
    file, line
        Where the owning object tag starts (for messages about missing properties).
    """

    def __init__(self, owner: str = "object", file: str | None = None, line: int | None = None) -> None:
        self.owner = owner
        self.file = file
        self.line = line
        self._props: dict[str, Property] = {}

    # -- construction -------------------------------------------------------------------------------
    def set(self, name: str, kind: str, value: Any, file: str | None = None, line: int | None = None) -> None:
        """Add a property; a duplicate name replaces the earlier value (Nori warns and keeps the later)."""
        self._props[name] = Property(kind, value, file, line)

    def __contains__(self, name: str) -> bool:
        return name in self._props

    def names(self) -> list[str]:
        """Names of all properties, in insertion order."""
        return list(self._props)

    def where(self, name: str) -> tuple[str | None, int | None]:
        """Return (file, line) of property ``name`` or, if absent, of the owning object."""
        p = self._props.get(name)
        if p is None:
            return self.file, self.line
        return p.file, p.line

    def error(self, name: str | None, message: str) -> SceneError:
        """Build a :class:`SceneError` located at property ``name`` (or at the owner)."""
        file, line = self.where(name) if name else (self.file, self.line)
        return SceneError(f"{self.owner}: {message}", file, line)

    # -- validation ---------------------------------------------------------------------------------
    def check_known(self, known: dict[str, str] | list[str]) -> None:
        """Raise if a property name is not among ``known`` (name → expected tag), listing valid names."""
        names = list(known)
        for name, prop in self._props.items():
            if name not in known:
                hint = get_close_matches(name, names, n=1)
                extra = f" (did you mean '{hint[0]}'?)" if hint else ""
                valid = ", ".join(
                    f"<{known[n]} name=\"{n}\">" if isinstance(known, dict) else n for n in names
                ) or "none"
                raise SceneError(
                    f"{self.owner}: unknown property '{clean(name)}'{extra}; valid properties: {valid}",
                    prop.file,
                    prop.line,
                )

    # -- getters ------------------------------------------------------------------------------------
    def _get(self, name: str, kinds: tuple[str, ...], default: Any) -> Any:
        p = self._props.get(name)
        if p is None:
            if default is _REQUIRED:
                raise self.error(None, f"missing required property <{kinds[0]} name=\"{name}\">")
            return default
        if p.kind not in kinds:
            raise SceneError(
                f"{self.owner}: property '{name}' must be given as <{kinds[0]}>, not <{p.kind}>",
                p.file,
                p.line,
            )
        return p.value

    def get_float(self, name: str, default: Any = _REQUIRED) -> float:
        """Return a ``<float>`` property."""
        return float(self._get(name, ("float",), default))

    def get_int(self, name: str, default: Any = _REQUIRED) -> int:
        """Return an ``<integer>`` property."""
        return int(self._get(name, ("integer",), default))

    def get_bool(self, name: str, default: Any = _REQUIRED) -> bool:
        """Return a ``<boolean>`` property."""
        return bool(self._get(name, ("boolean",), default))

    def get_string(self, name: str, default: Any = _REQUIRED) -> str:
        """Return a ``<string>`` property."""
        return str(self._get(name, ("string",), default))

    def _triple(self, name: str, kind: str, default: Any) -> np.ndarray:
        v = self._get(name, (kind,), default)
        return np.array(v, dtype=np.float64).reshape(3)

    def get_color(self, name: str, default: Any = _REQUIRED) -> np.ndarray:
        """Return a ``<color>`` property as a float64 array of shape (3,)."""
        return self._triple(name, "color", default)

    def get_point(self, name: str, default: Any = _REQUIRED) -> np.ndarray:
        """Return a ``<point>`` property as a float64 array of shape (3,)."""
        return self._triple(name, "point", default)

    def get_vector(self, name: str, default: Any = _REQUIRED) -> np.ndarray:
        """Return a ``<vector>`` property as a float64 array of shape (3,)."""
        return self._triple(name, "vector", default)

    def get_transform(self, name: str, default: Any = _REQUIRED) -> Any:
        """Return a ``<transform>`` property (a :class:`brdflab.math.transform.Transform`)."""
        return self._get(name, ("transform",), default)

    # -- value checks -------------------------------------------------------------------------------
    def positive_float(self, name: str, default: float, *, allow_zero: bool = False) -> float:
        """Return a finite float property that must be > 0 (or ≥ 0 with ``allow_zero``)."""
        v = self.get_float(name, default)
        ok = np.isfinite(v) and (v >= 0 if allow_zero else v > 0)
        if not ok:
            raise self.error(name, f"'{name}' must be a finite number {'≥' if allow_zero else '>'} 0, got {v}")
        return v

    def nonnegative_color(self, name: str, default: Any = _REQUIRED) -> np.ndarray:
        """Return a ``<color>`` whose components must be finite, ≥ 0 and ≤ :data:`MAX_COMPONENT`."""
        c = self.get_color(name, default)
        if not np.all(np.isfinite(c)) or np.any(c < 0):
            raise self.error(name, f"'{name}' must have finite, non-negative components, got {c.tolist()}")
        if np.any(c > MAX_COMPONENT):
            raise self.error(name, f"'{name}' has components above {MAX_COMPONENT:g} (they overflow the float32 "
                             f"image), got {c.tolist()}")
        return c

    def reflectance(self, name: str, default: Any = _REQUIRED) -> np.ndarray:
        """A non-negative ``<color>`` that should be ≤ 1: larger components are legal but create energy,
        so they get a located warning."""
        c = self.nonnegative_color(name, default)
        if np.any(c > 1):
            self.warn(name, f"'{name}' = {c.tolist()} has components above 1: the material reflects more light "
                      "than it receives (it creates energy)")
        return c

    def finite_float(self, name: str, default: Any = _REQUIRED, lo: float = -np.inf, hi: float = np.inf) -> float:
        """Return a ``<float>`` that must be finite and within [lo, hi]."""
        v = self.get_float(name, default)
        if not (np.isfinite(v) and lo <= v <= hi):
            rng = "" if (lo == -np.inf and hi == np.inf) else f" in [{lo:g}, {hi:g}]"
            raise self.error(name, f"'{name}' must be a finite number{rng}, got {v}")
        return v

    def int_in_range(self, name: str, default: Any, lo: int, hi: int) -> int:
        """Return an ``<integer>`` that must be within [lo, hi]."""
        v = self.get_int(name, default)
        if not lo <= v <= hi:
            raise self.error(name, f"'{name}' must be in [{lo:,}, {hi:,}], got {clean(v, 30)}")
        return v

    def warn(self, name: str | None, message: str) -> None:
        """Issue a located :class:`UserWarning` about property ``name`` (or the owner)."""
        import warnings

        file, line = self.where(name) if name else (self.file, self.line)
        loc = f"{file}:{line}: " if file and line else (f"{file}: " if file else "")
        warnings.warn(f"{loc}{self.owner}: {message}", stacklevel=3)
