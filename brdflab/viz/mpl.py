"""One setting for every brdflab figure: user text is never mathtext, and log axes still read 10⁻².

Figures carry user text — file names, BSDF type names, parameters — and a ``$`` in it made matplotlib parse
mathtext and crash (``Failed to parse``). :func:`safe_figures` turns mathtext parsing off for all text
(``text.parse_math``) and, because matplotlib's log-axis tick labels are mathtext (``$\\mathdefault{10^{-2}}$``),
gives log scales (axes and colour bars) a formatter that writes the same labels in plain Unicode (10⁻², 2×10³).
Call it before drawing; it is idempotent.
"""

from __future__ import annotations

import re

_SUP = str.maketrans("0123456789-+.", "⁰¹²³⁴⁵⁶⁷⁸⁹⁻⁺·")
_MATH = re.compile(r"^\$\\mathdefault\{(.*)\}\$$")
_POW = re.compile(r"(?:(?P<m>[-0-9.]+)\\times\s*)?(?P<b>\d+)\^\{(?P<e>[-+0-9.]+)\}")
_installed = False


def plain_label(text: str) -> str:
    """A matplotlib mathtext tick label (``$\\mathdefault{2\\times10^{-3}}$``) in plain Unicode (``2×10⁻³``)."""
    m = _MATH.match(text)
    if m is None:
        return text
    inner = m.group(1)
    p = _POW.fullmatch(inner)
    if p is None:
        return inner.replace("\\times", "×").replace("\\mathdefault", "").strip("{}")
    head = f"{p.group('m')}×" if p.group("m") else ""
    return f"{head}{p.group('b')}{p.group('e').translate(_SUP)}"


def safe_figures() -> None:
    """Agg backend, no mathtext for any text, and Unicode log tick labels (module docstring)."""
    global _installed
    import matplotlib

    matplotlib.use("Agg")
    matplotlib.rcParams["text.parse_math"] = False
    if _installed:
        return
    import matplotlib.scale as mscale
    import matplotlib.ticker as mticker

    class PlainLogFormatter(mticker.LogFormatterSciNotation):
        """:class:`~matplotlib.ticker.LogFormatterSciNotation` with plain Unicode labels."""

        def __call__(self, x, pos=None):
            return plain_label(super().__call__(x, pos))

    mscale.LogFormatterSciNotation = PlainLogFormatter
    _installed = True
