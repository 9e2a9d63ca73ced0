"""Wavefront OBJ loading into NumPy arrays (spec §7.1).

Statements read: ``v x y z``, ``vt u v``, ``vn x y z`` and ``f`` with vertex tokens ``p``, ``p/t``,
``p//n`` or ``p/t/n``; everything else (``#``, ``o``, ``g``, ``s``, ``usemtl``, ``mtllib``) is ignored.
Polygons with n ≥ 3 vertices are triangulated as fans (0, i, i+1) — unlike Nori, which silently
truncates n-gons after 4 vertices. Indices are 1-based; negative indices count back from the most
recent element (as the OBJ standard says). Each distinct (p, t, n) index triple becomes one vertex.
If a file has any ``vn`` (or ``vt``), every face vertex must reference one, as in Nori.

Parsing is vectorised: statement lines are classified once and converted with a single NumPy call per
kind; Python touches each face line only to count its vertices.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from brdflab.errors import MeshError
from brdflab.math.transform import Transform


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
        tok = text.split()
        try:
            if len(tok) < width:
                raise ValueError
            out[i] = [float(t) for t in tok[:width]]
        except ValueError:
            raise MeshError(f"'{what}' statement: expected {width} numbers, got '{text.strip()}'",
                            path, ln) from None
    return out


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
    """
    path = Path(path)
    try:
        text = path.read_text(errors="replace")
    except FileNotFoundError:
        raise MeshError("OBJ file not found", path) from None
    except OSError as exc:
        raise MeshError(f"cannot read OBJ file: {exc.strerror}", path) from None

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
    bad = ~np.isfinite(pos).all(axis=1)
    if bad.any():
        raise MeshError("vertex position is not finite", path, kinds["v"][1][int(np.argmax(bad))])

    counts = np.fromiter((len(s.split()) for s in flines), dtype=np.int64, count=len(flines))
    if counts.min() < 3:
        k = int(np.argmax(counts < 3))
        raise MeshError(f"face needs at least 3 vertices, got {counts[k]}: 'f {flines[k].strip()}'",
                        path, fnos[k])
    tokens = " ".join(flines).split()
    nslash = tokens[0].count("/")
    if nslash > 2:
        raise MeshError(f"bad face vertex '{tokens[0]}': expected p, p/t, p//n or p/t/n", path, fnos[0])
    has_t = nslash >= 1 and "//" not in tokens[0]
    has_n = nslash == 2
    joined = " ".join(tokens)
    try:
        if joined.count("/") != nslash * len(tokens) or (has_n and not has_t and joined.count("//") != len(tokens)):
            raise ValueError
        idx = np.array(joined.replace("//", "/0/").replace("/", " ").split(), dtype=np.int64)
        idx = idx.reshape(len(tokens), nslash + 1)
    except ValueError:
        _raise_face_format(path, flines, fnos, nslash, "//" in tokens[0])
    if len(nrm) and not has_n:
        raise MeshError("the file has 'vn' normals, so every face vertex must reference one (p//n or p/t/n)",
                        path, fnos[0])
    if len(uv) and not has_t:
        raise MeshError("the file has 'vt' coordinates, so every face vertex must reference one (p/t or p/t/n)",
                        path, fnos[0])

    line_of_token = np.repeat(np.asarray(fnos), counts)
    cols = [("position", len(pos), kinds["v"][1])]
    if has_t:
        cols.append(("texture coordinate", len(uv), kinds["vt"][1]))
    if has_n:
        cols.append(("normal", len(nrm), kinds["vn"][1]))
    col_index = {"position": 0, "texture coordinate": 1, "normal": nslash}
    for name, n, deflines in cols:
        c = idx[:, col_index[name]]
        if np.any(c < 0):
            # Relative index: −1 is the most recent element defined before this face line.
            defined_before = np.searchsorted(np.asarray(deflines, dtype=np.int64), line_of_token[c < 0])
            c[c < 0] += defined_before + 1
        bad = (c < 1) | (c > n)
        if bad.any():
            k = int(np.argmax(bad))
            raise MeshError(f"face references {name} {tokens[k].split('/')[col_index[name]]}, but only "
                            f"{n} are defined (indices are 1-based)", path, int(line_of_token[k]))
        c -= 1

    # Unique (p, t, n) triples become vertices.
    key = idx[:, 0].copy()
    if has_t:
        key = key * (len(uv) + 1) + idx[:, 1]
    if has_n:
        key = key * (len(nrm) + 1) + idx[:, nslash]
    uniq, first, inv = np.unique(key, return_index=True, return_inverse=True)
    vsel = idx[first]

    # Fan triangulation of every polygon: (0, i, i+1).
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    ntri = counts - 2
    tri_poly = np.repeat(np.arange(len(counts)), ntri)
    tri_k = np.arange(int(ntri.sum())) - np.repeat(np.cumsum(ntri) - ntri, ntri)
    base = starts[tri_poly]
    faces = np.stack([inv[base], inv[base + tri_k + 1], inv[base + tri_k + 2]], axis=1).astype(np.int64)

    e1 = pos[idx[base + tri_k + 1, 0]] - pos[idx[base, 0]]
    e2 = pos[idx[base + tri_k + 2, 0]] - pos[idx[base, 0]]
    degenerate = np.flatnonzero(~(np.linalg.norm(np.cross(e1, e2), axis=1) > 0))
    if len(degenerate):
        warnings.warn(f"{path}:{fnos[tri_poly[degenerate[0]]]}: {len(degenerate)} degenerate (zero-area) "
                      f"triangle{'s' if len(degenerate) > 1 else ''}; they are kept but can never be hit",
                      stacklevel=2)
    positions = pos[vsel[:, 0]]
    uvs = uv[vsel[:, 1]] if has_t else None
    normals = nrm[vsel[:, nslash]] if has_n else None
    if to_world is not None and not to_world.is_identity():
        positions = to_world.apply_points(positions)
        if normals is not None:
            normals = to_world.apply_normals(normals)
    if normals is not None:
        ln = np.linalg.norm(normals, axis=1, keepdims=True)
        if not np.all(np.isfinite(normals)) or np.any(ln == 0):
            raise MeshError("vertex normal is zero or not finite", path)
        normals = normals / ln
    return Mesh(positions, faces, normals, uvs, str(path))


def _raise_face_format(path: Path, flines: list[str], fnos: list[int], nslash: int, double: bool) -> None:
    """Find the first face vertex whose form differs from the first one, or that is not an integer."""
    first = "p" if nslash == 0 else ("p//n" if double else ("p/t" if nslash == 1 else "p/t/n"))
    for text, ln in zip(flines, fnos, strict=True):
        for tok in text.split():
            parts = tok.split("/")
            form_ok = tok.count("/") == nslash and (("//" in tok) == double)
            try:
                [int(p) for p in parts if p != ""]
                num_ok = True
            except ValueError:
                num_ok = False
            if len(parts) > 3:
                raise MeshError(f"bad face vertex '{tok}': more than three '/'-separated parts", path, ln)
            if not num_ok:
                raise MeshError(f"bad face vertex '{tok}': indices must be integers", path, ln)
            if not form_ok:
                raise MeshError(f"face vertex '{tok}' does not match the form '{first}' used by the first "
                                "face; every face vertex must reference the same kinds of data", path, ln)
    raise MeshError("malformed face statements", path, fnos[0])
