"""Output safety: what brdflab may write, and where.

* :func:`check_outputs` refuses an output path that is one of the run's inputs (a scene named
  ``scene.png`` whose render would replace it, ``-o sky.exr`` naming the environment map, a heatmap
  named like the reference image). Paths are compared after resolving links, and by inode when both exist.
* :func:`output_folder` checks that a folder named by ``-o`` is not an existing file, and tells whether
  brdflab is the one creating it.
* :func:`index_root` decides where the ``index.html`` listing the reports may go: only into a folder
  brdflab owns (the default ``reports/``, or a parent that brdflab itself created for this run) — never
  into the parent of a folder the user named, where it could replace the user's own ``index.html``.
* :func:`brdflab.pages.index.write_index` additionally never replaces an ``index.html`` that brdflab
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


def check_outputs(outputs: list[str | Path], inputs: list[str | Path], option: str = "-o") -> None:
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
                               f"('{clean(hit, 100)}'); choose another output name with {option}")


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


# -- files brdflab did not make ------------------------------------------------------------------------------------
#: In a folder brdflab writes into, the names of the files it wrote there (one per line): what it may replace.
MANIFEST = ".brdflab-outputs"
#: The software tag of brdflab's PNG files (a ``Software`` text chunk).
PNG_SOFTWARE = "brdflab"


def _listed(path: Path) -> bool:
    try:
        with open(path.parent / MANIFEST, encoding="utf-8", errors="surrogateescape") as f:
            return path.name in f.read(1 << 20).splitlines()
    except OSError:
        return False


#: The main page of each kind of output folder; a folder whose page brdflab generated, written before
#: :data:`MANIFEST` existed, is brdflab's (see :func:`made_by_brdflab`).
FOLDER_PAGES = ("index.html", "check.html", "report.html")


def _legacy_folder(path: Path) -> bool:
    folder = path.parent
    if (folder / MANIFEST).exists():
        return False  # the manifest, when there is one, is the record
    from brdflab.pages.index import _ours

    return any(path.name != page and (folder / page).is_file() and _ours(folder / page) for page in FOLDER_PAGES)


def made_by_brdflab(path: str | Path) -> bool:
    """True when the existing file ``path`` was written by brdflab: listed in its folder's manifest
    (:data:`MANIFEST`; without one, in a folder whose main page brdflab generated), or carrying brdflab's
    mark (an EXR's ``comments``/``brdflab_*`` header, a PNG's ``Software`` chunk, an HTML page's generator
    tag; a PNG beside an EXR of brdflab with the same stem is the preview of a render pair)."""
    path = Path(path)
    if _listed(path) or _legacy_folder(path):
        return True
    if not path.is_file():
        return False
    suffix = path.suffix.lower()
    try:
        if suffix == ".exr":
            from brdflab.imageio import read_exr_header

            header = read_exr_header(path)
            return "brdflab" in str(header.get("comments", "")).lower() or any(
                str(k).startswith("brdflab_") for k in header)
        if suffix == ".png":
            from PIL import Image

            with Image.open(path) as im:
                if im.info.get("Software") == PNG_SOFTWARE:
                    return True
            sibling = path.with_suffix(".exr")
            return sibling.is_file() and made_by_brdflab(sibling)
        if suffix in (".html", ".htm"):
            from brdflab.pages.index import _ours

            return _ours(path)
    except Exception:  # unreadable or not what its suffix says: not ours
        return False
    return False


def check_replaceable(paths: list[str | Path], force: bool = False, option: str = "-o") -> None:
    """Raise :class:`BrdflabError` if any existing ``paths`` was not written by brdflab (unless ``force``):
    brdflab replaces only its own earlier outputs."""
    if force:
        return
    for p in paths:
        p = Path(p)
        if os.path.lexists(p) and not made_by_brdflab(p):
            raise BrdflabError(f"refusing to replace '{clean(p, 100)}': brdflab did not write it; choose another "
                               f"output name with {option}, or pass --force to replace it")


def check_writable(folder: str | Path, option: str = "-o") -> None:
    """Raise :class:`BrdflabError` unless a file can be created in ``folder`` (or, when it does not exist
    yet, in its nearest existing parent): a read-only folder or a full device is found before the work."""
    import tempfile

    folder = Path(folder)
    probe = next((p for p in (folder, *folder.parents) if p.exists()), Path("."))
    try:
        fd, tmp = tempfile.mkstemp(prefix=".brdflab-", suffix=".tmp", dir=probe)
        try:
            os.write(fd, b"x")  # /dev/full-like devices fail on the first write
            os.fsync(fd)
        finally:
            os.close(fd)
            os.unlink(tmp)
    except OSError as exc:
        raise BrdflabError(f"{option} '{clean(folder, 100)}': cannot write to '{clean(probe, 100)}': "
                           f"{clean(exc.strerror or exc, 80)}") from None


def prepare_folder(folder: str | Path, names: list[str], inputs: list[str | Path] = (), force: bool = False,
                   option: str = "-o") -> bool:
    """Check an output folder before a run writes ``names`` into it; return True when it does not exist yet.

    One check for every command that writes into a folder: the folder is not a file, none of the outputs
    is an input of the run (even with ``force``) or an existing folder, none replaces a file brdflab did
    not write (unless ``force``), and the folder can be written to. A name may hold ``*`` wildcards
    (``chi2_view_*.png``) for outputs whose number is known only after the run: every existing file it
    matches is checked.
    """
    folder = Path(folder)
    created = output_folder(folder, option)
    outs = _expand(folder, names)
    check_outputs(outs, list(inputs), option)
    check_replaceable(outs, force, option)
    check_writable(folder, option)
    return created


def prepare_files(paths: list[str | Path], inputs: list[str | Path] = (), force: bool = False,
                  option: str = "-o") -> None:
    """:func:`prepare_folder` for single output files (a render's EXR + PNG, a heatmap): none is an input
    or a folder, none replaces a file brdflab did not write (unless ``force``), their folders are writable."""
    paths = [Path(p) for p in paths]
    check_outputs(paths, list(inputs), option)
    check_replaceable(paths, force, option)
    for folder in dict.fromkeys(p.parent for p in paths):
        output_folder(folder, option)
        check_writable(folder, option)


def _expand(folder: Path, names: list[str]) -> list[Path]:
    """``folder / name`` for every name; a name with ``*`` gives the existing files it matches."""
    import glob

    out: list[Path] = []
    for n in names:
        if "*" in n:  # only '*' is a wildcard: '[' or '?' in a scene's stem are literal
            pattern = "*".join(glob.escape(part) for part in n.split("*"))
            out += sorted(folder.glob(pattern)) if folder.is_dir() else []
        else:
            out.append(folder / n)
    return out


def record_outputs(folder: str | Path, names: list[str]) -> None:
    """Add ``names`` (glob patterns: the files they match now) to ``folder``'s :data:`MANIFEST` (best
    effort: a failure only loses the record)."""
    folder = Path(folder)
    names = [p.name for p in _expand(folder, names) if p.exists()]
    try:
        with open(folder / MANIFEST, encoding="utf-8", errors="surrogateescape") as f:
            known = f.read(1 << 20).splitlines()
    except OSError:
        known = []
    merged = list(dict.fromkeys([*known, *names]))
    try:
        from brdflab.imageio import write_files

        data = ("\n".join(merged) + "\n").encode("utf-8", "surrogateescape")
        write_files([(folder / MANIFEST, lambda tmp: Path(tmp).write_bytes(data))])
    except BrdflabError:
        pass


def write_text(path: str | Path, text: str) -> None:
    """Write a text output atomically (a temporary beside it, then a rename); errors as one-line
    :class:`BrdflabError` (a removed folder is created again, a full disk is "No space left on device")."""
    from brdflab.imageio import write_files

    data = text.encode("utf-8", "surrogateescape")
    write_files([(path, lambda tmp: Path(tmp).write_bytes(data))])


def json_text(obj: object, **kwargs) -> str:
    """``obj`` as strict JSON: NaN and ±infinity (an undefined metric, an empty p-value) become ``null``,
    NumPy scalars and arrays plain numbers and lists, so every JSON brdflab prints or writes parses."""
    import json
    import math

    import numpy as np

    def plain(v):
        if isinstance(v, dict):
            return {str(k): plain(x) for k, x in v.items()}
        if isinstance(v, list | tuple):
            return [plain(x) for x in v]
        if isinstance(v, np.ndarray):
            return plain(v.tolist())
        if isinstance(v, np.generic):
            v = v.item()
        if isinstance(v, float) and not math.isfinite(v):
            return None
        return v

    return json.dumps(plain(obj), allow_nan=False, default=str, **kwargs)
