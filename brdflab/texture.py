"""Textures: constant colours and Nori's ``checker`` (spec §12).

=============  ===========  =======  ==============================================================
parameter      tag          default  meaning
=============  ===========  =======  ==============================================================
``scalex``     integer      1        checker squares along u
``scaley``     integer      1        checker squares along v
=============  ===========  =======  ==============================================================

Checker: p_x = trunc(u·scalex), p_y = trunc(v·scaley); the value is 0.9 where p_x mod 2 = p_y mod 2
(C remainder, sign follows the operand) and 0.1 otherwise. The two colours are fixed, as in Nori (its
``color`` property is ambiguous, so brdflab rejects it).
"""

from __future__ import annotations

import numpy as np

from brdflab.scene.properties import PropertyList


class Texture:
    """A spatially varying colour looked up by surface uv."""

    #: True when the value does not depend on uv (lets materials skip the lookup).
    constant: bool = False

    def eval(self, uv: np.ndarray) -> np.ndarray:
        """Return colours of shape (N, 3) for uv coordinates of shape (N, 2)."""
        raise NotImplementedError

    def mean(self) -> np.ndarray:
        """Average colour (3,), used for emitter power and reports."""
        raise NotImplementedError


class ConstantTexture(Texture):
    """A constant colour."""

    constant = True

    def __init__(self, value: np.ndarray | float) -> None:
        self.value = np.broadcast_to(np.asarray(value, dtype=np.float64), (3,)).copy()

    def eval(self, uv: np.ndarray) -> np.ndarray:
        """Return the constant colour broadcast to (N, 3)."""
        return np.broadcast_to(self.value, (len(uv), 3))

    def mean(self) -> np.ndarray:
        """Return the colour itself."""
        return self.value


class CheckerTexture(Texture):
    """Nori's two-colour checkerboard (spec §12)."""

    KNOWN = {"scalex": "integer", "scaley": "integer"}

    def __init__(self, scalex: int = 1, scaley: int = 1) -> None:
        self.scalex = scalex
        self.scaley = scaley
        self.colors = np.array([[0.1] * 3, [0.9] * 3])

    @classmethod
    def from_properties(cls, props: PropertyList) -> CheckerTexture:
        """Build from a ``<texture type="checker">`` property list."""
        props.check_known(cls.KNOWN)
        return cls(props.get_int("scalex", 1), props.get_int("scaley", 1))

    def eval(self, uv: np.ndarray) -> np.ndarray:
        """Return 0.9 or 0.1 grey per uv (C-style truncation and remainder)."""
        px = np.trunc(uv[:, 0] * self.scalex).astype(np.int64)
        py = np.trunc(uv[:, 1] * self.scaley).astype(np.int64)
        same = np.fmod(px, 2) == np.fmod(py, 2)
        return self.colors[same.astype(np.intp)]

    def mean(self) -> np.ndarray:
        """Return the average of the two colours."""
        return self.colors.mean(axis=0)


def as_texture(value: Texture | np.ndarray | float) -> Texture:
    """Wrap a colour or scalar as a :class:`ConstantTexture`; pass textures through."""
    return value if isinstance(value, Texture) else ConstantTexture(value)
