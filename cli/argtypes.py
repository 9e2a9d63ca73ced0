"""Argument types for the sub-commands: every number is range-checked when it is parsed.

A value outside its range is an argparse usage error (one line, exit status 2), with the offending value
echoed through :func:`brdflab.errors.clean` (short, control characters escaped). Use these as ``type=``
of ``add_argument`` so every command checks the same way.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable

from brdflab.errors import ascii_int, clean

#: Seeds seed NumPy's SeedSequence: non-negative and below 2^64.
SEED_LIMIT = 2**64


def _int(text: str) -> int:
    v = ascii_int(text, signed=True)
    if v is None:
        raise argparse.ArgumentTypeError(f"expected an integer, got '{clean(text)}'")
    return v


def resolution(text: str) -> tuple[int, int]:
    """``WIDTHxHEIGHT`` in ASCII digits, both ≥ 1 (``--resolution``)."""
    parts = text.lower().split("x")
    dims = [ascii_int(p) for p in parts] if len(parts) == 2 else [None]
    if None in dims:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT, got '{clean(text, 40)}'")
    if min(dims) < 1 or max(dims) > 65_535:
        raise argparse.ArgumentTypeError(f"sizes must be from 1 to 65535, got '{clean(text, 40)}'")
    return dims[0], dims[1]


def count(lo: int = 1, hi: int | None = None) -> Callable[[str], int]:
    """An integer in [lo, hi] (a sample count, a number of runs or workers)."""

    def parse(text: str) -> int:
        v = _int(text)
        if v < lo or (hi is not None and v > hi):
            rng = f"at least {lo:,}" if hi is None else f"between {lo:,} and {hi:,}"
            raise argparse.ArgumentTypeError(f"must be {rng}, got {clean(text, 30)}")
        return v

    parse.__name__ = "integer"
    return parse


def seed(text: str) -> int:
    """A random seed: an integer in [0, 2^64)."""
    v = _int(text)
    if not 0 <= v < SEED_LIMIT:
        raise argparse.ArgumentTypeError(f"must be an integer in [0, 2^64), got {clean(text, 30)}")
    return v


def number(lo: float = -math.inf, hi: float = math.inf, *, open_lo: bool = False,
           open_hi: bool = False) -> Callable[[str], float]:
    """A finite float in the interval [lo, hi] (``open_lo``/``open_hi`` exclude the ends)."""

    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number, got '{clean(text)}'") from None
        ok = math.isfinite(v) and (v > lo if open_lo else v >= lo) and (v < hi if open_hi else v <= hi)
        if not ok:
            if math.isinf(hi):
                rng = f"{'>' if open_lo else '≥'} {lo:g}" if math.isfinite(lo) else ""
            elif math.isinf(lo):
                rng = f"{'<' if open_hi else '≤'} {hi:g}"
            else:
                rng = f"in {'(' if open_lo else '['}{lo:g}, {hi:g}{')' if open_hi else ']'}"
            raise argparse.ArgumentTypeError(f"must be a finite number {rng}, got {clean(text, 30)}".replace("  ", " "))
        return v

    parse.__name__ = "number"
    return parse


#: Seconds of a time limit: finite and > 0.
seconds = number(0.0, open_lo=True)
