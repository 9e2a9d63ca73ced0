"""Reading sample files (``brdflab chi2 --samples FILE``, ``--against-emitter``): numeric tables in text (``#``
comments), ``.npy`` or ``.npz``, through the one input check of :mod:`brdflab.limits` (no FIFO, device or folder,
the size limit, array headers checked before NumPy allocates, never unpickled), located errors (file, line), and
the grouping of samples by ω_i (k-d tree pairs, O(n log n)). The checks of BSDF samples are
:mod:`brdflab.judges.samples.bsdf_checks`.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from brdflab.errors import BrdflabError

#: Components of ω_i equal within this tolerance form one group.
WI_TOLERANCE = 1e-4


def _short(token: str, n: int = 20) -> str:
    s = token.encode("unicode_escape").decode("ascii")
    return s if len(s) <= n else s[: n - 3] + "..."


@dataclass
class Samples:
    """Columns read from a samples file: ``wi``/``wo`` (N, 3), ``pdf`` (N,) or None, ``weight`` (N, 3) or None."""

    path: str
    wi: np.ndarray
    wo: np.ndarray
    pdf: np.ndarray | None
    weight: np.ndarray | None
    lines: np.ndarray
    direction_only: bool = False
    nonfinite_info: dict | None = None
    """What :func:`nonfinite_summary` found (None when every value is finite)."""
    nonfinite: np.ndarray | None = None
    """(N,) True where the sampler wrote NaN or ±inf in wo, pdf or a weight (a finding about the sampler, not a
    malformed file); such rows are failed samples for the other checks, as a renderer that drops them loses them."""


def _columns(path: str, data: np.ndarray, lines: np.ndarray, ncol: int) -> Samples:
    if ncol in (3, 4):
        return Samples(path, np.tile([0.0, 0.0, 1.0], (len(data), 1)), data[:, :3],
                       data[:, 3] if ncol == 4 else None, None, lines, direction_only=True)
    return Samples(path, data[:, :3], data[:, 3:6], data[:, 6] if ncol >= 7 else None,
                   data[:, 7:10] if ncol == 10 else None, lines)


ALLOWED = (3, 4, 6, 7, 10)


EXPECTED = "6, 7 or 10 columns (wi wo [pdf [w_r w_g w_b]]), or 3/4 for a warp (x y z [pdf])"


def read_samples(path: str | Path) -> Samples:
    """Read a samples file (text, ``.npy`` or ``.npz``); see the module docstring for the format.

    Raises
    ------
    BrdflabError
        ``file:line: what was expected`` for a malformed file.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "s.txt"
    >>> _ = p.write_text("# wi wo pdf\\n0 0 1  0 0 1  0.318\\n0 0 1  0.6 0 0.8  0.2546\\n")
    >>> s = read_samples(p)
    >>> s.wo.shape, s.pdf.tolist()
    ((2, 3), [0.318, 0.2546])
    """
    data, lines, ncol = read_table(path, ALLOWED, EXPECTED, nonfinite_ok=True)
    bad = ~np.isfinite(data).all(axis=1)
    if ncol >= 6 and not np.isfinite(data[:, :3]).all():  # wi is the input, not the sampler's output
        i = int(np.argmax(~np.isfinite(data[:, :3]).all(axis=1)))
        raise BrdflabError("wi is not finite (it is the sampler's input)", file=path, line=int(lines[i]))
    info = None
    if bad.any():
        info = nonfinite_summary(data[:, 3:] if ncol >= 6 else data, lines, bad, ncol >= 6)
        data = data.copy()
        data[bad, 3 if ncol >= 6 else 0:] = 0.0  # a failed sample (wo = 0, pdf 0, weight 0): what a renderer keeps
    s = _columns(str(path), data, lines, ncol)
    s.nonfinite, s.nonfinite_info = (bad, info) if bad.any() else (None, None)
    return s


def nonfinite_summary(out: np.ndarray, lines: np.ndarray, bad: np.ndarray, has_wi: bool) -> dict:
    """How many rows hold NaN/inf, in which columns, the first lines, and how many of them have a finite ω_o below
    the surface (the usual cause: 0/0 for a failed sample)."""
    names = ["wo", "wo", "wo", "pdf", "weight", "weight", "weight"] if has_wi else ["x", "x", "x", "pdf"]
    cols = {}
    for j in range(out.shape[1]):
        k = int((~np.isfinite(out[:, j])).sum())
        if k:
            cols[names[j]] = max(cols.get(names[j], 0), k)
    wo = out[bad, :3]
    below = int((np.isfinite(wo).all(axis=1) & (wo[:, 2] <= 0)).sum()) if has_wi else 0
    return {"count": int(bad.sum()), "total": int(len(bad)), "nan": int(np.isnan(out[bad]).any(axis=1).sum()),
            "columns": cols, "lines": [int(v) for v in lines[bad][:5]], "below_surface": below}


def read_table(path: str | Path, allowed: tuple[int, ...], expected: str,
               nonfinite_ok: bool = False) -> tuple[np.ndarray, np.ndarray, int]:
    """Read a numeric table in the samples-file conventions (text with ``#`` comments, ``.npy``, or ``.npz``
    with the key ``samples``): (N, k) float64 data, the file line (text) or row (arrays) of each sample, and
    k, which must be one of ``allowed`` (``expected`` says so in the error). ``nonfinite_ok``: NaN and ±inf are
    values (the caller judges them) instead of a malformed file.

    Raises
    ------
    BrdflabError
        ``file:line: what was expected`` for a malformed file.
    """
    from brdflab.limits import check_input, read_input

    path = Path(path)
    # The one input check (limits.check_input/read_input): not found, not a regular file (a directory, a FIFO
    # that would block, /dev/zero that never ends) and BRDFLAB_MAX_INPUT_MB, before a byte is read.
    if path.suffix in (".npy", ".npz"):
        check_input(path, "samples file")
        arr = _load_array(path)
        if arr.ndim != 2 or arr.shape[1] not in allowed or not (np.issubdtype(arr.dtype, np.floating)
                                                                 or np.issubdtype(arr.dtype, np.integer)):
            raise BrdflabError(f"expected a real numeric (N, k) array with k = {expected}; got "
                               f"{_short(str(arr.dtype), 20)} shape {arr.shape}", file=path)
        data = arr.astype(np.float64)
        bad = ~np.isfinite(data).all(axis=1)
        if bad.any() and not nonfinite_ok:
            raise BrdflabError(f"row {int(np.argmax(bad))}: non-finite value", file=path)
        return data, np.arange(len(data)), arr.shape[1]
    rows, lines, ncol, first = [], [], None, None
    try:
        text = read_input(path, "samples file").decode("utf-8", errors="strict")
    except UnicodeDecodeError:
        raise BrdflabError("not a text file (expected whitespace-separated numbers; binary data: use .npy)",
                           file=path) from None
    fast = _read_text_fast(text, allowed, nonfinite_ok)
    if fast is not None:
        return fast
    for num, raw in enumerate(text.splitlines(), 1):
        tokens = raw.split("#", 1)[0].split()
        if not tokens:
            continue
        if ncol is None:
            if len(tokens) not in allowed:
                raise BrdflabError(f"{len(tokens)} columns; expected {expected}", file=path, line=num)
            ncol, first = len(tokens), num
        elif len(tokens) != ncol:
            raise BrdflabError(f"{len(tokens)} columns, but line {first} has {ncol}", file=path, line=num)
        try:
            vals = [float(t) for t in tokens]
        except ValueError:
            bad = next(t for t in tokens if not _is_float(t))
            raise BrdflabError(f"'{_short(bad)}' is not a number", file=path, line=num) from None
        if not nonfinite_ok and not all(np.isfinite(vals)):
            raise BrdflabError("non-finite value (nan/inf)", file=path, line=num)
        rows.append(vals)
        lines.append(num)
    if not rows:
        raise BrdflabError("no samples (only comments or blank lines)", file=path)
    return np.array(rows), np.array(lines), ncol


def _read_text_fast(text: str, allowed: tuple[int, ...],
                    nonfinite_ok: bool = False) -> tuple[np.ndarray, np.ndarray, int] | None:
    """NumPy's C parser for a well-formed text table (1 M rows in about a second, where the line-by-line
    reader takes ten); None for anything else — a malformed file goes through the line-by-line reader, which
    says where and what is wrong."""
    import io
    import warnings

    from brdflab.limits import check_memory

    # the parse holds the text, its lines and the float table at once: about 3 × the text plus 8 B a number
    check_memory(4 * len(text) + 8 * (len(text) // 2), "parsing the text samples file (use .npy for large ones)")
    lines = text.splitlines()
    keep = [i for i, raw in enumerate(lines, 1) if raw.split("#", 1)[0].strip()]
    if not keep:
        return None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            data = np.loadtxt(io.StringIO(text), comments="#", dtype=np.float64, ndmin=2)
    except (ValueError, TypeError, OverflowError):
        return None
    if data.shape[0] != len(keep) or data.shape[1] not in allowed or not (nonfinite_ok or np.all(np.isfinite(data))):
        return None
    return data, np.asarray(keep), data.shape[1]


def _load_array(path: Path) -> np.ndarray:
    """The array of a ``.npy`` or ``.npz`` samples file, never unpickled (an object array is refused).

    Before anything is allocated, the array's header is read and its size compared with the bytes that
    really follow it (a 1 KB file whose header claims 10⁹ rows would otherwise make NumPy allocate 48 GB)
    and with the memory limit (a zip bomb: a small ``.npz`` that decompresses to gigabytes).
    """
    import zipfile

    try:
        if path.suffix == ".npz":
            with zipfile.ZipFile(path) as z:
                infos = {i.filename[:-4] if i.filename.endswith(".npy") else i.filename: i for i in z.infolist()}
                keys = list(infos)
                key = "samples" if "samples" in keys else (keys[0] if len(keys) == 1 else None)
                if key is None:
                    raise BrdflabError(f"expected an array named 'samples' (found "
                                       f"{', '.join(_short(k) for k in keys[:5]) or 'none'})", file=path)
                with z.open(infos[key]) as f:
                    _check_array_header(f, infos[key].file_size, path, f"the array '{_short(key)}' of {path.name}")
            with np.load(path, allow_pickle=False) as z:
                return z[key]
        with open(path, "rb") as f:
            _check_array_header(f, os.fstat(f.fileno()).st_size, path, "the array")
        return np.load(path, allow_pickle=False)
    except (ValueError, OSError, EOFError, zipfile.BadZipFile, KeyError) as exc:
        raise BrdflabError(f"cannot read as {path.suffix}: {_short(str(exc), 60)}", file=path) from None


def _check_array_header(f, size: int, path: Path, what: str) -> None:
    """Check the ``.npy`` header at the start of ``f`` (``size`` bytes in all) before the array is read."""
    from numpy.lib import format as npy

    from brdflab.limits import check_memory

    version = npy.read_magic(f)
    read = npy.read_array_header_1_0 if version == (1, 0) else npy.read_array_header_2_0
    shape, _, dtype = read(f)
    if dtype.hasobject:
        raise BrdflabError(f"{what} is an object array (it would need unpickling); save numbers", file=path)
    need = int(np.prod(shape, dtype=object)) * dtype.itemsize
    if need > size - f.tell():
        raise BrdflabError(f"{what}: the header claims shape {tuple(shape)} ({need:,} bytes), but only "
                           f"{max(size - f.tell(), 0):,} bytes follow", file=path)
    check_memory(need, f"{what} (shape {tuple(shape)})")


def _is_float(t: str) -> bool:
    try:
        float(t)
        return True
    except ValueError:
        return False


def group_by_wi(wi: np.ndarray, tol: float = WI_TOLERANCE) -> list[np.ndarray]:
    """Index arrays of the samples sharing one ω_i (components equal within ``tol``), in file order.

    Distinct ω_i are cells of a grid of side ``tol``; two cells are merged when their representatives lie
    within ``tol`` of each other (a value on a cell boundary). The close pairs come from a k-d tree (each
    representative has at most 26 in neighbouring cells) and the merges are the connected components of
    that graph, so the cost is O(n log n) in the number of distinct ω_i (10⁶ distinct ω_i in seconds).
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    wi = np.asarray(wi, dtype=np.float64)
    if len(wi) == 0:
        return []
    cell = np.floor(wi / tol)
    if not np.isfinite(cell).all() or np.abs(cell).max() >= 2**52:
        raise BrdflabError(f"ω_i components must be finite and below {2**52 * tol:.3g} in magnitude")
    _, first, inv = np.unique(cell.astype(np.int64), axis=0, return_index=True, return_inverse=True)
    inv = inv.ravel()
    n = len(first)
    pairs = cKDTree(wi[first]).query_pairs(tol, p=np.inf, output_type="ndarray")
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, comp = connected_components(graph, directed=False)
    labels = comp[inv]
    # Groups in the order of their first sample in the file.
    _, first_of = np.unique(labels, return_index=True)
    order = np.argsort(first_of, kind="stable")
    sorter = np.argsort(labels, kind="stable")
    bounds = np.searchsorted(labels[sorter], np.arange(len(first_of) + 1))
    return [sorter[bounds[g]:bounds[g + 1]] for g in order]
