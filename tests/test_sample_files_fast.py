"""Text sample files: NumPy's parser for well-formed tables gives exactly what the line-by-line reader gives
(values, file lines of each sample, column count); malformed files still get the located message."""

from __future__ import annotations

import numpy as np
import pytest

from brdflab.errors import BrdflabError
from brdflab.judges.samples import tables as sf


def _slow(path):
    """The line-by-line reader alone (the fast path switched off)."""
    orig = sf._read_text_fast
    sf._read_text_fast = lambda text, allowed, nonfinite_ok=False: None
    try:
        return sf.read_table(path, sf.ALLOWED, sf.EXPECTED)
    finally:
        sf._read_text_fast = orig


def test_fast_text_path_equals_the_line_by_line_reader(tmp_path):
    rng = np.random.default_rng(3)
    rows = rng.normal(size=(50, 7))
    lines = ["# wi wo pdf", ""]
    for k, r in enumerate(rows):
        lines.append(" ".join(f"{v:.17g}" for v in r) + ("   # a comment" if k % 7 == 0 else ""))
        if k % 10 == 3:
            lines += ["", "   # indented comment"]
    p = tmp_path / "s.txt"
    p.write_text("\n".join(lines) + "\n")
    fast = sf.read_table(p, sf.ALLOWED, sf.EXPECTED)
    slow = _slow(p)
    assert np.array_equal(fast[0], slow[0]) and np.array_equal(fast[1], slow[1]) and fast[2] == slow[2] == 7
    assert fast[1][0] == 3  # the first sample is on line 3


@pytest.mark.parametrize("bad, message", [("0 0 1 0 0 1 x\n", "'x' is not a number"),
                                          ("0 0 1 0 0 1 nan\n", "non-finite"),
                                          ("0 0 1 0 0 1\n", "6 columns, but line 1 has 7")])
def test_malformed_files_keep_their_located_messages(tmp_path, bad, message):
    p = tmp_path / "s.txt"
    p.write_text("0 0 1 0 0 1 0.3\n" + bad)
    with pytest.raises(BrdflabError, match=message) as exc:
        sf.read_table(p, sf.ALLOWED, sf.EXPECTED)
    assert exc.value.line == 2
