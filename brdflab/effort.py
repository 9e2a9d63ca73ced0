"""How hard the quadratures of ``validate``, ``chi2`` and ``plot`` work: ``--effort quick|normal|full``.

The chi-square expected counts, the consistency check's ∫ p dω, the white furnace's and the plots' albedo are
adaptive quadratures (:func:`brdflab.judges.material.chi2.integrate_rects`): a cell is split where its 4- and
8-point Gauss–Legendre rules disagree, up to a depth and a number of cells per level. A smooth lobe converges
in a few levels; a tabulated or step-shaped one (a measured BRDF, a user's histogram lobe) keeps splitting
along every step, so the budget, not the tolerance, decides its cost. The budget is chosen here:

==========  ==========  ===============  =================  ===============================================
effort      max depth   cells per level  plot albedo depth  for
==========  ==========  ===============  =================  ===============================================
``quick``   6           15 000           5                  a first look; tabulated BSDFs in seconds
``normal``  10          60 000           8                  the default (the calibrated battery)
``full``    13          240 000          11                 a final verdict on a hard (stepped) lobe
==========  ==========  ===============  =================  ===============================================

A cell left unconverged at the budget keeps its 8-point value and its |8 − 4|-point difference is added to
the error estimate the chi-square test reports, so a lower effort is visible in the result, never silent.
The setting is process-wide (:func:`use`), inherited by forked workers through ``BRDFLAB_EFFORT``.
"""

from __future__ import annotations

import os
from contextlib import contextmanager
from dataclasses import dataclass

from brdflab.errors import BrdflabError

ENV = "BRDFLAB_EFFORT"


@dataclass(frozen=True)
class Effort:
    """A quadrature budget."""

    name: str
    max_depth: int
    max_cells: int
    view_depth: int


LEVELS = {
    "quick": Effort("quick", 6, 15_000, 5),
    "normal": Effort("normal", 10, 60_000, 8),
    "full": Effort("full", 13, 240_000, 11),
}


def current() -> Effort:
    """The effort in force (``BRDFLAB_EFFORT``, default ``normal``)."""
    name = os.environ.get(ENV, "normal")
    if name not in LEVELS:
        raise BrdflabError(f"{ENV}={name[:20]!r}: expected one of {', '.join(LEVELS)}")
    return LEVELS[name]


@contextmanager
def use(name: str):
    """Run a block at effort ``name`` (restores the previous setting afterwards)."""
    if name not in LEVELS:
        raise BrdflabError(f"effort must be one of {', '.join(LEVELS)}, got {str(name)[:20]!r}")
    previous = os.environ.get(ENV)
    os.environ[ENV] = name
    try:
        yield LEVELS[name]
    finally:
        if previous is None:
            os.environ.pop(ENV, None)
        else:
            os.environ[ENV] = previous
