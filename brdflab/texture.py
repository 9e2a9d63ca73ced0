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

#: Rec. 709 / sRGB luminance weights (sum 1, so a grey value is its own luminance).
LUMINANCE = np.array([0.212671, 0.715160, 0.072169])


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

    def luminance(self, uv: np.ndarray) -> np.ndarray | float:
        """Luminance Y (Rec. 709 / sRGB weights) per uv: (N,), or a float for a constant texture."""
        return self.eval(uv) @ LUMINANCE

    def scaled(self, uv: np.ndarray | None, w: np.ndarray) -> np.ndarray:
        """``eval(uv) · w[:, None]``, (N, 3) Fortran-ordered (``uv`` may be None for constant textures)."""
        vals = self.eval(uv)
        out = np.empty((len(w), 3), order="F")
        for j in range(3):
            np.multiply(vals[:, j], w, out=out[:, j])
        return out


class ConstantTexture(Texture):
    """A constant colour."""

    constant = True

    def __init__(self, value: np.ndarray | float) -> None:
        self.value = np.broadcast_to(np.asarray(value, dtype=np.float64), (3,)).copy()

    def eval(self, uv: np.ndarray) -> np.ndarray:
        """Return the constant colour broadcast to (N, 3)."""
        return np.broadcast_to(self.value, (len(uv), 3))

    def scaled(self, uv: np.ndarray | None, w: np.ndarray) -> np.ndarray:
        """``value · w[:, None]``, (N, 3) Fortran-ordered (no broadcast array)."""
        out = np.empty((len(w), 3), order="F")
        for j in range(3):
            np.multiply(w, self.value[j], out=out[:, j])
        return out

    def mean(self) -> np.ndarray:
        """Return the colour itself."""
        return self.value

    def luminance(self, uv: np.ndarray | None = None) -> float:
        """The constant's luminance (``uv`` is ignored)."""
        return float(LUMINANCE @ self.value)


class PointValues(Texture):
    """Per-point values for one batch of N shading points, in batch order (not a function of uv).

    A family of materials that differ only in constant parameters is evaluated as one batch, each point
    with its own material's constant (see :mod:`brdflab.bsdf.family`). The values are gathered from the
    members' constants on first use.

    Parameters
    ----------
    table
        (3, K) the K members' colours.
    lum
        (K,) their luminances (the members' own :meth:`ConstantTexture.luminance`, so a grey roughness is
        bit-identical to the per-member evaluation).
    index
        (N,) member index of each point.
    """

    def __init__(self, table: np.ndarray, lum: np.ndarray, index: np.ndarray) -> None:
        self.table, self.lum, self.index = table, lum, index
        self._values: np.ndarray | None = None
        self._luminance: np.ndarray | None = None

    def eval(self, uv: np.ndarray) -> np.ndarray:
        """(N, 3) colours of the batch's points (``uv`` only fixes the batch size)."""
        if len(uv) != len(self.index):
            raise ValueError(f"PointValues holds {len(self.index)} points, asked for {len(uv)}")
        return self._gathered()

    def scaled(self, uv: np.ndarray | None, w: np.ndarray) -> np.ndarray:
        """Each point's colour times ``w``, (N, 3) Fortran-ordered (one gather per channel)."""
        if self._values is not None:
            return super().scaled(uv, w)
        out = np.empty((len(self.index), 3), order="F")
        for j in range(3):
            np.take(self.table[j], self.index, out=out[:, j])
            out[:, j] *= w
        return out

    def _gathered(self) -> np.ndarray:
        if self._values is None:
            v = np.empty((len(self.index), 3), order="F")
            for j in range(3):
                np.take(self.table[j], self.index, out=v[:, j])
            self._values = v
        return self._values

    def mean(self) -> np.ndarray:
        """Mean colour over the batch's points."""
        return self._gathered().mean(axis=0)

    def luminance(self, uv: np.ndarray) -> np.ndarray:
        """(N,) luminances of the batch's points."""
        if self._luminance is None:
            self._luminance = np.take(self.lum, self.index)
        return self._luminance


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
        # Beyond 2^31 squares the pattern aliases to noise and u·scale leaves the int64 range.
        return cls(props.int_in_range("scalex", 1, -(2**31), 2**31), props.int_in_range("scaley", 1, -(2**31), 2**31))

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
