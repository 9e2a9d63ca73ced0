"""Wavefront OBJ loading into NumPy arrays (spec §7.1).

Statements read: ``v x y z``, ``vt u v``, ``vn x y z`` and ``f`` with vertex tokens ``p``, ``p/t``,
``p//n`` or ``p/t/n``; everything else (``#``, ``o``, ``g``, ``s``, ``usemtl``, ``mtllib``) is ignored.
Polygons with n ≥ 3 vertices are triangulated as fans (0, i, i+1) — unlike Nori, which silently
truncates n-gons after 4 vertices. Indices are 1-based; negative indices count back from the most
recent element (as the OBJ standard says). Each distinct (p, t, n) index triple becomes one vertex.
If a file has any ``vn`` (or ``vt``), every face vertex must reference one, as in Nori.

Parsing is vectorised. Files in the common form are scanned as bytes by NumPy and converted by one
``numpy.loadtxt`` call per statement kind (:func:`_scan_fast`); any other file goes through the general
parser, whose statement lines are classified once and converted with a single NumPy call per kind, Python
touching each face line only to count its vertices. Both give the same arrays.
"""

from __future__ import annotations

import io
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from brdflab.errors import MeshError, clean, quoted
from brdflab.limits import read_input
from brdflab.math.transform import Transform

#: Largest vertex coordinate accepted: Embree intersects in float32, whose products of two coordinates
#: (edge cross products) must stay finite, so |x| ≤ 1e18 (1e36 < 3.4e38).
MAX_COORDINATE = 1e18


@dataclass
class Mesh:
    """A triangle mesh in world space.

    Attributes
    ----------
    positions : (V, 3) float64 world-space vertex positions.
    faces : (F, 3) int64 vertex indices (counter-clockwise winding gives the geometric normal).
    normals : (V, 3) float64 unit vertex normals, or None.
    uvs : (V, 2) float64 texture coordinates, or None.
    path : the file it was read from.
    """

    positions: np.ndarray
    faces: np.ndarray
    normals: np.ndarray | None
    uvs: np.ndarray | None
    path: str

    def triangle_areas(self) -> np.ndarray:
        """World-space area of each triangle (F,)."""
        p = self.positions
        e1 = p[self.faces[:, 1]] - p[self.faces[:, 0]]
        e2 = p[self.faces[:, 2]] - p[self.faces[:, 0]]
        return 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1)


def _floats(path: Path, lines: list[str], linenos: list[int], width: int, what: str) -> np.ndarray:
    if not lines:
        return np.zeros((0, width))
    try:
        arr = np.array(" ".join(lines).split(), dtype=np.float64)
        if arr.size == len(lines) * width:
            return arr.reshape(-1, width)
    except ValueError:
        pass
    # Slow path: find the offending line (extra components such as 'vt u v w' are allowed).
    out = np.empty((len(lines), width))
    for i, (text, ln) in enumerate(zip(lines, linenos, strict=True)):
        tok = text.split(maxsplit=width)[:width]
        if len(tok) < width:
            raise MeshError(f"'{what}' statement: expected {width} numbers, got {len(tok)}", path, ln)
        for j, t in enumerate(tok):
            try:
                out[i, j] = float(t)
            except ValueError:
                # Only the offending token is echoed, never the rest of the line.
                raise MeshError(f"'{what}' statement: expected {width} numbers, got {quoted(t)}", path, ln) from None
    return out


@dataclass
class _Statements:
    """The parsed statements of an OBJ file, before vertices are assembled."""

    pos: np.ndarray
    uv: np.ndarray
    nrm: np.ndarray
    deflines: dict[str, np.ndarray]
    """Line numbers of the ``v``, ``vt`` and ``vn`` statements."""
    fnos: np.ndarray
    """Line number of each face."""
    counts: np.ndarray
    """Vertices of each face."""
    idx: np.ndarray
    """(face vertices, nslash + 1) int64 indices as written (1-based or negative; t = 0 for ``p//n``)."""
    nslash: int
    has_t: bool
    has_n: bool
    tokens: list[str] | None = None
    """The face-vertex tokens (general parser only; for error messages)."""


def load_obj(path: str | Path, to_world: Transform | None = None) -> Mesh:
    """Load an OBJ file and transform it to world space.

    Parameters
    ----------
    path
        The OBJ file.
    to_world
        Applied to positions (as points) and normals (inverse transpose, renormalised).

    Returns
    -------
    Mesh
        The triangulated mesh.

    Raises
    ------
    MeshError
        With file and line for unreadable files, malformed statements, out-of-range or zero indices,
        faces with fewer than 3 vertices, non-finite coordinates, or a file with no faces.

    Notes
    -----
    Files in the common form (ASCII, statements at the start of their line, every face with the same
    number of vertices) are read by :func:`_scan_fast`: NumPy on the whole byte buffer and ``numpy.loadtxt``
    per statement kind, without a Python string per line or token (measured side by side on a loaded
    machine: the course table's 2.2 MB of OBJ 1.55× faster; a 1 M-triangle sphere 2.1–2.5× faster, its
    parse peaking at 227 instead of 771 MiB). Anything else, and every
    file with something to report, goes through the general parser, which gives the same arrays (tested)
    and the error messages.
    """
    path = Path(path)
    data = read_input(path, "OBJ file", MeshError)
    st = _scan_fast(data)
    del data
    if st is not None:
        mesh = _assemble(path, st, to_world, report=False)
        if mesh is not None:
            return mesh
    text = read_input(path, "OBJ file", MeshError).decode(errors="replace")
    return _assemble(path, _parse_general(path, text), to_world, report=True)


def _parse_general(path: Path, text: str) -> _Statements:
    """Parse any OBJ text line by line (Python strings), raising a :class:`MeshError` for what is wrong."""
    kinds: dict[str, tuple[list[str], list[int]]] = {k: ([], []) for k in ("v", "vt", "vn", "f")}
    for i, line in enumerate(text.splitlines(), start=1):
        head, _, rest = line.strip().partition(" ")
        slot = kinds.get(head)
        if slot is not None:
            slot[0].append(rest)
            slot[1].append(i)

    pos = _floats(path, *kinds["v"], 3, "v")
    uv = _floats(path, *kinds["vt"], 2, "vt")
    nrm = _floats(path, *kinds["vn"], 3, "vn")
    flines, fnos = kinds["f"]
    if not flines:
        raise MeshError("OBJ file has no faces ('f' statements)", path)
    counts = np.fromiter((len(s.split()) for s in flines), dtype=np.int64, count=len(flines))
    if counts.min() < 3:
        k = int(np.argmax(counts < 3))
        raise MeshError(f"face needs at least 3 vertices, got {counts[k]}: {quoted('f ' + flines[k].strip())}",
                        path, fnos[k])
    tokens = " ".join(flines).split()
    nslash = tokens[0].count("/")
    if nslash > 2:
        raise MeshError(f"bad face vertex {quoted(tokens[0])}: expected p, p/t, p//n or p/t/n", path, fnos[0])
    has_t = nslash >= 1 and "//" not in tokens[0]
    has_n = nslash == 2
    joined = " ".join(tokens)
    try:
        if joined.count("/") != nslash * len(tokens) or (has_n and not has_t and joined.count("//") != len(tokens)):
            raise ValueError
        idx = np.array(joined.replace("//", "/0/").replace("/", " ").split(), dtype=np.int64)
        idx = idx.reshape(len(tokens), nslash + 1)
    except (ValueError, OverflowError):
        _raise_face_format(path, flines, fnos, nslash, "//" in tokens[0])
    deflines = {k: np.asarray(kinds[k][1], dtype=np.int64) for k in ("v", "vt", "vn")}
    return _Statements(pos, uv, nrm, deflines, np.asarray(fnos, dtype=np.int64), counts, idx, nslash, has_t,
                       has_n, tokens)


def _assemble(path: Path, st: _Statements, to_world: Transform | None, report: bool) -> Mesh | None:
    """Vertices, fan-triangulated faces and world-space attributes from parsed statements. A problem
    raises a :class:`MeshError` when ``report``, else returns None (the caller re-parses generally)."""
    pos, uv, nrm, idx, counts, nslash, has_t, has_n = (st.pos, st.uv, st.nrm, st.idx, st.counts, st.nslash,
                                                       st.has_t, st.has_n)
    fnos = st.fnos
    bad = ~(np.abs(pos) <= MAX_COORDINATE).all(axis=1)
    if bad.any():
        if not report:
            return None
        k = int(np.argmax(bad))
        what = "not finite" if not np.isfinite(pos[k]).all() else f"beyond ±{MAX_COORDINATE:g}"
        raise MeshError(f"vertex position is {what} (the ray tracer works in float32)", path,
                        int(st.deflines["v"][k]))
    if len(nrm) and not has_n:
        if not report:
            return None
        raise MeshError("the file has 'vn' normals, so every face vertex must reference one (p//n or p/t/n)",
                        path, int(fnos[0]))
    if len(uv) and not has_t:
        if not report:
            return None
        raise MeshError("the file has 'vt' coordinates, so every face vertex must reference one (p/t or p/t/n)",
                        path, int(fnos[0]))

    line_of_token = None
    cols = [("position", len(pos), "v")]
    if has_t:
        cols.append(("texture coordinate", len(uv), "vt"))
    if has_n:
        cols.append(("normal", len(nrm), "vn"))
    col_index = {"position": 0, "texture coordinate": 1, "normal": nslash}
    for name, n, kind in cols:
        c = idx[:, col_index[name]]
        neg = c < 0
        if neg.any():
            # Relative index: −1 is the most recent element defined before this face line.
            if line_of_token is None:
                line_of_token = np.repeat(fnos, counts)
            defined_before = np.searchsorted(st.deflines[kind], line_of_token[neg])
            c[neg] += defined_before + 1
        bad = (c < 1) | (c > n)
        if bad.any():
            if not report:
                return None
            k = int(np.argmax(bad))
            if line_of_token is None:
                line_of_token = np.repeat(fnos, counts)
            raise MeshError(f"face references {name} {clean(st.tokens[k].split('/')[col_index[name]])}, but only "
                            f"{n} are defined (indices are 1-based)", path, int(line_of_token[k]))
        c -= 1

    # Unique (p, t, n) triples become vertices. Positions only: the referenced positions in order, and
    # each face vertex's rank among them — what np.unique gives, by counting instead of sorting (all
    # positions referenced, the usual case: the positions themselves).
    vsel = None
    if not has_t and not has_n:
        used = np.bincount(idx[:, 0], minlength=len(pos)) > 0
        if used.all():
            inv = idx[:, 0]
        else:
            inv = (np.cumsum(used) - 1)[idx[:, 0]]
            vsel = np.flatnonzero(used)[:, None]
    else:
        key = idx[:, 0].copy()
        if has_t:
            key = key * (len(uv) + 1) + idx[:, 1]
        if has_n:
            key = key * (len(nrm) + 1) + idx[:, nslash]
        _, first, inv = np.unique(key, return_index=True, return_inverse=True)
        inv = inv.reshape(-1)
        vsel = idx[first]

    # Fan triangulation of every polygon: (0, i, i+1).
    if np.all(counts == 3):
        faces = inv.reshape(-1, 3).astype(np.int64)
        tri_poly = None
        corner = idx[:, 0].reshape(-1, 3)
    else:
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
        ntri = counts - 2
        tri_poly = np.repeat(np.arange(len(counts)), ntri)
        tri_k = np.arange(int(ntri.sum())) - np.repeat(np.cumsum(ntri) - ntri, ntri)
        base = starts[tri_poly]
        faces = np.stack([inv[base], inv[base + tri_k + 1], inv[base + tri_k + 2]], axis=1).astype(np.int64)
        corner = np.stack([idx[base, 0], idx[base + tri_k + 1, 0], idx[base + tri_k + 2, 0]], axis=1)
    degenerate = _degenerate(pos, corner)
    if len(degenerate):
        line = fnos[degenerate[0] if tri_poly is None else tri_poly[degenerate[0]]]
        warnings.warn(f"{path}:{line}: {len(degenerate)} degenerate (zero-area) "
                      f"triangle{'s' if len(degenerate) > 1 else ''}; they are kept but can never be hit",
                      stacklevel=3)
    positions = pos if vsel is None else pos[vsel[:, 0]]
    uvs = uv[vsel[:, 1]] if has_t else None
    normals = nrm[vsel[:, nslash]] if has_n else None
    if to_world is not None and not to_world.is_identity():
        with np.errstate(all="ignore"):
            positions = to_world.apply_points(positions)
        if not (np.abs(positions) <= MAX_COORDINATE).all():
            raise MeshError(f"'toWorld' moves vertices beyond ±{MAX_COORDINATE:g} (the ray tracer works in float32)",
                            path)
        if normals is not None:
            normals = to_world.apply_normals(normals)
    if normals is not None:
        ln = np.linalg.norm(normals, axis=1, keepdims=True)
        if not np.all(np.isfinite(normals)) or np.any(ln == 0):
            if not report:
                return None
            raise MeshError("vertex normal is zero or not finite", path)
        normals = normals / ln
    return Mesh(positions, faces, normals, uvs, str(path))


#: Triangles per block of the degenerate-triangle test (bounds its temporaries).
_BLOCK = 1 << 17


def _degenerate(pos: np.ndarray, corner: np.ndarray) -> np.ndarray:
    """Indices of the triangles (rows of position indices ``corner``) whose cross product has no length."""
    out = []
    for a in range(0, len(corner), _BLOCK):
        c = corner[a:a + _BLOCK]
        p0 = pos[c[:, 0]]
        e1 = pos[c[:, 1]] - p0
        e2 = pos[c[:, 2]] - p0
        out.append(a + np.flatnonzero(~(np.linalg.norm(np.cross(e1, e2), axis=1) > 0)))
    return np.concatenate(out) if out else np.zeros(0, np.int64)


#: Most runs of consecutive same-kind statement lines the fast scanner joins.
_MAX_RUNS = 4096
#: Bytes per block when counting tokens per line.
_CHUNK = 1 << 22
#: A statement keyword followed by a tab or alone on its line: the general parser decides what it means
#: (searched as plain substrings after a newline: a multi-line regular expression took 2.6 s on 37 MB).
_ODD_KEYWORDS = tuple(b"\n" + k + e for k in (b"v", b"vt", b"vn", b"f") for e in (b"\t", b"\n"))


def _scan_fast(data: bytes) -> _Statements | None:
    """Parse an OBJ file in the common form with NumPy, or return None when it is not in that form.

    The form: ASCII; lines end in ``\n`` (or ``\r\n``); statements start at the beginning of their line with
    their keyword and a space; every face has the same number of vertices. Each statement kind is joined
    from its runs of lines and converted by one ``numpy.loadtxt`` call; faces are checked as the general
    parser checks them (slash counts), plus their vertex count and the number of indices per line.
    """
    if not data.isascii() or any(c in data for c in (b"\x0b", b"\x0c", b"\x1c", b"\x1d", b"\x1e")):
        return None
    if b"\r" in data:
        data = data.replace(b"\r\n", b"\n")
        if b"\r" in data:
            return None
    if not data.endswith(b"\n"):
        data += b"\n"
    if data[:1] in (b" ", b"\t") or b"\n " in data or b"\n\t" in data:
        return None
    head = b"\n" + data[:4]
    if any(k in data or head.startswith(k) for k in _ODD_KEYWORDS):
        return None
    d = np.frombuffer(data, np.uint8)
    ends = np.flatnonzero(d == 10)
    starts = np.empty_like(ends)
    starts[0] = 0
    starts[1:] = ends[:-1] + 1
    last = len(d) - 1
    c0 = d[starts]
    c1 = d[np.minimum(starts + 1, last)]
    c2 = d[np.minimum(starts + 2, last)]
    v = c0 == ord("v")
    masks = {"v": v & (c1 == ord(" ")), "vt": v & (c1 == ord("t")) & (c2 == ord(" ")),
             "vn": v & (c1 == ord("n")) & (c2 == ord(" ")), "f": (c0 == ord("f")) & (c1 == ord(" "))}
    del d, c0, c1, c2, v
    blocks, lines = {}, {}
    for kind, mask in masks.items():
        li = np.flatnonzero(mask)
        runs = np.flatnonzero(np.diff(li) != 1) + 1
        if len(runs) >= _MAX_RUNS:
            return None
        lo = np.concatenate([[0], runs]) if len(li) else np.zeros(0, np.int64)
        hi = np.concatenate([runs, [len(li)]]) if len(li) else np.zeros(0, np.int64)
        blocks[kind] = b"".join(data[starts[li[a]]:ends[li[b - 1]] + 1] for a, b in zip(lo, hi, strict=True))
        lines[kind] = li + 1
    del data, starts, ends, masks
    arrays = {}
    for kind, width in (("v", 3), ("vt", 2), ("vn", 3)):
        arrays[kind] = _loadtxt(blocks.pop(kind), len(lines[kind]), width, np.float64)
        if arrays[kind] is None:
            return None
    fblock, nf = blocks.pop("f"), len(lines["f"])
    if nf == 0:
        return None
    counts = _tokens_per_line(fblock, nf) - 1
    nv = int(counts[0])
    if nv < 3 or np.any(counts != nv):
        return None
    first = fblock.split(None, 2)[1]
    nslash = first.count(b"/")
    double = b"//" in first
    if nslash > 2:
        return None
    ntok = nf * nv
    if fblock.count(b"/") != nslash * ntok or (double and fblock.count(b"//") != ntok):
        return None
    parts = nslash + 1 - int(double)
    if nslash:
        fblock = fblock.replace(b"/", b" ")
        if np.any(_tokens_per_line(fblock, nf) != 1 + nv * parts):
            return None
    idx = _loadtxt(fblock, nf, nv * parts, np.int64)
    del fblock
    if idx is None:
        return None
    idx = idx.reshape(ntok, parts)
    if double:
        idx = np.insert(idx, 1, 0, axis=1)
    deflines = {k: lines[k] for k in ("v", "vt", "vn")}
    return _Statements(arrays["v"], arrays["vt"], arrays["vn"], deflines, lines["f"],
                       np.full(nf, nv, np.int64), idx, nslash, nslash >= 1 and not double, nslash == 2)


def _loadtxt(block: bytes, nlines: int, width: int, dtype: type) -> np.ndarray | None:
    """The ``width`` numbers after the keyword of each of the ``nlines`` lines of ``block`` (None if a line
    has fewer or one is not a number; extra numbers are ignored, as the general parser ignores them)."""
    if nlines == 0:
        return np.zeros((0, width), dtype)
    try:
        arr = np.loadtxt(io.BytesIO(block), dtype=dtype, comments=None, usecols=range(1, width + 1), ndmin=2)
    except ValueError:
        return None
    return arr if arr.shape == (nlines, width) else None


def _tokens_per_line(block: bytes, nlines: int) -> np.ndarray:
    """Whitespace-separated tokens on each line of ``block`` (lines end in ``\n``), in blocks of
    :data:`_CHUNK` bytes."""
    out = np.empty(nlines, np.int64)
    line = pos = 0
    n = len(block)
    while pos < n:
        end = block.find(b"\n", min(pos + _CHUNK, n) - 1)
        b = np.frombuffer(block, np.uint8, count=end + 1 - pos, offset=pos)
        sep = (b == 32) | (b == 9) | (b == 10)
        start = ~sep
        start[1:] &= sep[:-1]
        before = np.searchsorted(np.flatnonzero(start), np.flatnonzero(b == 10))
        out[line:line + len(before)] = np.diff(before, prepend=0)
        line += len(before)
        pos = end + 1
    return out


def _raise_face_format(path: Path, flines: list[str], fnos: list[int], nslash: int, double: bool) -> None:
    """Find the first face vertex whose form differs from the first one, or that is not an integer."""
    first = "p" if nslash == 0 else ("p//n" if double else ("p/t" if nslash == 1 else "p/t/n"))
    for text, ln in zip(flines, fnos, strict=True):
        for tok in text.split():
            parts = tok.split("/")
            form_ok = tok.count("/") == nslash and (("//" in tok) == double)
            try:
                numbers = [int(p) for p in parts if p != ""]
                num_ok = True
            except ValueError:
                num_ok = False
            if len(parts) > 3:
                raise MeshError(f"bad face vertex {quoted(tok)}: more than three '/'-separated parts", path, ln)
            if not num_ok:
                raise MeshError(f"bad face vertex {quoted(tok)}: indices must be integers", path, ln)
            if any(abs(n) >= 2**63 for n in numbers):
                raise MeshError(f"face vertex {quoted(tok)}: index out of range", path, ln)
            if not form_ok:
                raise MeshError(f"face vertex {quoted(tok)} does not match the form '{first}' used by the first "
                                "face; every face vertex must reference the same kinds of data", path, ln)
    raise MeshError("malformed face statements", path, fnos[0])
