"""The external-sample reader column by column: every layout (3, 4, 6, 7, 10 columns) in text, ``.npy`` and
``.npz``, with a distinct value in every cell, so that each field is pinned to its columns and each sample to
its file line (comments and blank lines skipped); the grouping by ω_i."""

from __future__ import annotations

import numpy as np
import pytest

from brdflab.errors import BrdflabError
from brdflab.judges.samples.bsdf_checks import group_by_wi, read_samples


def _table(ncol: int, rows: int = 4) -> np.ndarray:
    return np.arange(rows * ncol, dtype=float).reshape(rows, ncol) / 8 + 0.125  # exact binary fractions


def _write(tmp_path, data: np.ndarray, kind: str):
    if kind == "npy":
        p = tmp_path / "s.npy"
        np.save(p, data)
        return p, np.arange(len(data))
    if kind == "npz":
        p = tmp_path / "s.npz"
        np.savez(p, samples=data, other=np.zeros(2))
        return p, np.arange(len(data))
    p = tmp_path / "s.txt"
    text, lines = ["# header", ""], []
    for row in data:
        text.append("  ".join(repr(float(v)) for v in row) + "   # trailing comment")
        lines.append(len(text))
        text.append("")
    p.write_text("\n".join(text) + "\n")
    return p, np.array(lines)


@pytest.mark.parametrize("kind", ["txt", "npy", "npz"])
@pytest.mark.parametrize("ncol", [3, 4, 6, 7, 10])
def test_columns_map_to_fields(tmp_path, kind, ncol):
    data = _table(ncol)
    path, lines = _write(tmp_path, data, kind)
    s = read_samples(path)
    np.testing.assert_array_equal(s.lines, lines)
    if ncol in (3, 4):
        assert s.direction_only and s.weight is None
        np.testing.assert_array_equal(s.wo, data[:, :3])
        np.testing.assert_array_equal(s.wi, np.tile([0.0, 0.0, 1.0], (len(data), 1)))
        if ncol == 4:
            np.testing.assert_array_equal(s.pdf, data[:, 3])
        else:
            assert s.pdf is None
        return
    assert not s.direction_only
    np.testing.assert_array_equal(s.wi, data[:, 0:3])
    np.testing.assert_array_equal(s.wo, data[:, 3:6])
    if ncol >= 7:
        np.testing.assert_array_equal(s.pdf, data[:, 6])
    else:
        assert s.pdf is None
    if ncol == 10:
        np.testing.assert_array_equal(s.weight, data[:, 7:10])
    else:
        assert s.weight is None


@pytest.mark.parametrize(("text", "line", "message"), [
    ("0 0 1 0 0 1 0.3\n\n# c\n0 0 1 0 0 1\n", 4, "6 columns, but line 1 has 7"),
    ("# only\n0 0 1 0 0\n", 2, "5 columns"),
    ("0 0 1 0 0 1 0.3\n0 0 1 0 0 x 0.3\n", 2, "'x' is not a number"),
    ("\n\nnan 0 1 0 0 1 0.3\n", 3, "wi is not finite"),
])
def test_errors_name_the_line(tmp_path, text, line, message):
    p = tmp_path / "bad.txt"
    p.write_text(text)
    with pytest.raises(BrdflabError, match=message) as exc:
        read_samples(p)
    assert f"bad.txt:{line}" in str(exc.value)


def test_group_by_wi_keeps_file_order_and_tolerance():
    wi = np.array([[0, 0, 1], [0.6, 0, 0.8], [0, 0, 1.00004], [0.6, 0, 0.8], [0, 0.6, 0.8], [0, 0, 0.99996]])
    groups = group_by_wi(wi)
    assert [g.tolist() for g in groups] == [[0, 2, 5], [1, 3], [4]]
    groups = group_by_wi(wi, tol=1e-6)
    assert [g.tolist() for g in groups] == [[0], [1, 3], [2], [4], [5]]
