"""The OBJ fast path (NumPy over the bytes, one ``loadtxt`` per statement kind) gives exactly the arrays of
the general line-by-line parser, takes only the files it can read exactly, and keeps the load of a large
mesh within a memory budget per triangle."""

from __future__ import annotations

import numpy as np
import pytest

from brdflab.scene.obj import _assemble, _parse_general, _scan_fast, load_obj
from brdflab.scene.shapes import uv_sphere, write_obj


def _general(path):
    return _assemble(path, _parse_general(path, path.read_text(errors="replace")), None, report=True)


def _same(a, b):
    for k in ("positions", "faces", "normals", "uvs"):
        x, y = getattr(a, k), getattr(b, k)
        assert (x is None) == (y is None), k
        if x is not None:
            assert x.dtype == y.dtype and x.shape == y.shape, k
            np.testing.assert_array_equal(x, y, err_msg=k)


_V = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0.5\n"
_VT = "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
_VN = "vn 0 0 1\nvn 0 0.6 0.8\nvn 1 0 0\nvn 0 1 0\n"
#: name → (text, fast path expected)
FILES = {
    "p": (_V + "f 1 2 3\nf 1 3 4\n", True),
    "p_t": (_V + _VT + "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n", True),
    "p__n": (_V + _VN + "f 1//1 2//2 3//3\nf 1//1 3//3 4//4\n", True),
    "p_t_n": (_V + _VT + _VN + "f 1/1/4 2/2/3 3/3/2\nf 1/4/1 3/3/3 4/2/2\n", True),
    "negative": (_V + "f -4 -3 -2\nv 2 2 2\nf -5 -2 -1\n", True),
    "quads": (_V + "f 1 2 3 4\n", True),
    "crlf_comments_groups": ("# c\r\no x\r\n" + _V.replace("\n", "\r\n") + "g a\r\nusemtl m\r\nf 1 2 3\r\ns 1\r\n",
                             True),
    "extra_vt_component_trailing_space": (_V + "vt 0 0 0 \nvt 1 0 0\nvt 1 1 0\nf 1/1 2/2 3/3  \n", True),
    "blank_lines_interleaved": (_V + "\nf 1 2 3\n\nv 3 3 3\nf 1 3 5\n", True),
    "precise_floats": ("v 0.1234567890123456789 -1e-310 3.5E+2\nv 12345.678901234567 -0.0 1\n"
                       "v 2 1 7\nf 1 2 3\n", True),
    "no_final_newline": (_V + "f 1 2 3", True),
    "unused_vertices": ("v 5 5 5\n" + _V + "v 9 9 9\nf 2 3 5\nf 5 3 2\n", True),
    # The general parser decides (mixed polygon sizes, indentation, tabs after keywords, non-ASCII).
    "mixed_polygons": (_V + "v 2 0 0\nf 1 2 3\nf 1 3 4 5\n", False),
    "indented": ("  " + _V + "f 1 2 3\n", False),
    "tab_after_keyword": (_V + "v\t2 2 2\nf 1 2 3\n", False),
    "non_ascii_comment": ("# café\n" + _V + "f 1 2 3\n", False),
}


@pytest.mark.parametrize("name", list(FILES))
def test_fast_path_equals_general_parser(tmp_path, name):
    text, fast = FILES[name]
    path = tmp_path / f"{name}.obj"
    path.write_text(text, newline="")
    assert (_scan_fast(path.read_bytes()) is not None) == fast
    _same(load_obj(path), _general(path))


def test_vertices_are_the_unique_referenced_positions(tmp_path):
    """Position-only meshes keep the referenced positions in index order, as np.unique of the indices
    gives them (the loader counts instead of sorting)."""
    rng = np.random.default_rng(5)
    pos = rng.random((50, 3))
    tri = np.array([rng.choice(np.arange(0, 50, 2), 3, replace=False) for _ in range(40)])  # odd ones unused
    path = tmp_path / "m.obj"
    lines = [f"v {float(x)!r} {float(y)!r} {float(z)!r}\n" for x, y, z in pos]
    lines += [f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in tri]
    path.write_text("".join(lines))
    m = load_obj(path)
    uniq, inv = np.unique(tri.ravel(), return_inverse=True)
    np.testing.assert_array_equal(m.positions, pos[uniq])
    np.testing.assert_array_equal(m.faces, inv.reshape(-1, 3))


@pytest.mark.parametrize("text, message", [
    (_V + "f 1 2 9\n", "face references position 9"),
    (_V + "f 1 2\n", "at least 3 vertices"),
    (_V + "f 1/1 2 3\n", "does not match the form"),
    ("v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "not finite"),
    (_V + "v 1 2\nf 1 2 3\n", "'v' statement"),
    (_V + "f 1 2 3\nvn\n", "'vn' statement"),  # a bare keyword is a statement, not a line to skip
    (_V + _VN + "f 1 2 3\n", "every face vertex must reference one"),
])
def test_files_with_errors_get_the_general_parsers_message(tmp_path, text, message):
    from brdflab.errors import MeshError

    path = tmp_path / "bad.obj"
    path.write_text(text)
    with pytest.raises(MeshError, match=message):
        load_obj(path)


def test_large_mesh_fast_path_and_memory(tmp_path):
    """A 200 k-triangle sphere: the fast path gives the general parser's arrays; loading it and building
    the scene geometry (tables + BVH) adds at most 400 bytes of peak memory per triangle (measured in a fresh
    process: about 300 at 1 M triangles, 810 before the fast path)."""
    import json
    import subprocess
    import sys

    v, f, _, _ = uv_sphere(n_theta=200, n_phi=500, bumps=0.05)
    path = tmp_path / "sphere.obj"
    write_obj(path, v, f)
    assert _scan_fast(path.read_bytes()) is not None
    _same(load_obj(path), _general(path))
    probe = f"""
import json, resource
from brdflab.scene.geometry import Geometry
from brdflab.scene.obj import load_obj
import embreex.rtcore_scene, embreex.mesh_construction
r0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
g = Geometry([load_obj({str(path)!r})])
print(json.dumps({{"bytes": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 - r0, "tris": g.triangle_count}}))
"""
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    rec = json.loads(out.stdout.strip().splitlines()[-1])
    assert rec["tris"] == len(f)
    assert rec["bytes"] / rec["tris"] < 400, rec["bytes"] / rec["tris"]
