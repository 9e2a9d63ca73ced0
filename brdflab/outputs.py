"""Output safety: what brdflab may write, and where.

* :func:`check_outputs` refuses an output path that is one of the run's inputs (a scene named
  ``scene.png`` whose render would replace it, ``-o sky.exr`` naming the environment map, a heatmap
  named like the reference image). Paths are compared after resolving links, and by inode when both exist.
* :func:`output_folder` checks that a folder named by ``-o`` is not an existing file, and tells whether
  brdflab is the one creating it.
* :func:`index_root` decides where the ``index.html`` listing the reports may go: only into a folder
  brdflab owns (the default ``reports/``, or a parent that brdflab itself created for this run) — never
  into the parent of a folder the user named, where it could replace the user's own ``index.html``.
* :func:`brdflab.report.index.write_index` additionally never replaces an ``index.html`` that brdflab
  did not generate.
"""

from __future__ import annotations

import os
from pathlib import Path

from brdflab.errors import BrdflabError, clean

#: The folder reports go to when no ``-o`` is given (brdflab owns it and its index).
DEFAULT_REPORTS = Path("reports")


def _key(path: Path) -> tuple:
    try:
        st = os.stat(path)
        return ("inode", st.st_dev, st.st_ino)
    except (OSError, ValueError):
        return ("path", os.path.normcase(os.path.abspath(os.path.realpath(path))))


def check_outputs(outputs: list[str | Path], inputs: list[str | Path]) -> None:
    """Raise :class:`BrdflabError` if any of ``outputs`` is the same file as any of ``inputs``, or an existing
    folder (checked before a run, so that no work is lost at the end)."""
    for out in outputs:
        if Path(out).is_dir():
            raise BrdflabError(f"'{clean(out, 100)}' is a folder; expected an image file name")
    keys = {}
    for p in inputs:
        keys.setdefault(_key(Path(p)), Path(p))
    for out in outputs:
        hit = keys.get(_key(Path(out)))
        if hit is not None:
            raise BrdflabError(f"refusing to write '{clean(out, 100)}': it is an input of this run "
                               f"('{clean(hit, 100)}'); choose another output name with -o")


def output_folder(path: str | Path, option: str = "-o") -> bool:
    """Check that ``path`` can be used as an output folder; return True when it does not exist yet.

    An existing file (or anything that is not a directory) is refused with a one-line error.
    """
    path = Path(path)
    for p in (path, *path.parents):
        try:
            if p.exists() and not p.is_dir():
                raise BrdflabError(f"{option} '{clean(path, 100)}': '{clean(p, 100)}' is an existing file, "
                                   "not a folder")
        except OSError as exc:
            raise BrdflabError(f"{option} '{clean(path, 100)}': {clean(exc.strerror or exc, 80)}") from None
    return not path.exists()


def index_root(out: Path, explicit: bool, parent_created: bool) -> Path | None:
    """Where the reports index may be written for a report in ``out``, or None (write no index).

    ``explicit``: the user named ``out`` (``-o``); ``parent_created``: ``out.parent`` did not exist before
    this run (brdflab created it).
    """
    if not explicit or parent_created:
        return out.parent
    return None
