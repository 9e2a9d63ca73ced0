"""Users' own samples under the chi-square test: a file of samples from another renderer (Nori, C++).

File format
-----------
One sample per line, whitespace separated, ``#`` starts a comment, blank lines are ignored; all directions
in the local shading frame (z = normal); one line per call of the sampler, failures included:

====================================================  ==========================================================
columns                                               meaning
====================================================  ==========================================================
``wi_x wi_y wi_z wo_x wo_y wo_z``                     incident direction ω_i and the sampled ω_o
``... pdf``                                           the sampler's solid-angle pdf of ω_o
``... pdf w_r w_g w_b``                               and its weight f·cos θ_o / pdf (what ``BSDF::sample`` returns)
``x y z`` or ``x y z pdf``                            warps only: a sampled direction (and its pdf)
====================================================  ==========================================================

Every line of a file has the same number of columns. A **failed** sample (``BSDF::sample`` returned 0) is
a line with pdf 0 or with ω_o = 0 0 0: it must be written, since the test compares the fraction of failed
samples too. ``.npy`` files hold the same columns as an (N, k) array; ``.npz`` files hold it under the key
``samples`` (or as their only array). For a warp the ω_i columns may hold anything (they are ignored) and
weight columns are not allowed.

What is checked
---------------
Samples are grouped by ω_i (components equal within 10⁻⁴; several ω_i per file). For each group, with a pdf
column, the verdict does **not** assume brdflab's sampling method (docs/external-samples.md):

* **Self-consistency** (:mod:`brdflab.validate.selfconsistency`): the directions against the file's own
  pdf column (Σ r/p_k per bin against N ∫ r, r = brdflab's pdf of the reference shaping the bins); any
  correct method passes. Šidák-corrected over the groups.
* **Weight columns**: against the reference's f·cos θ_o / p with p the (self-consistent) pdf column, or the
  true density when a hint identifies it; hints name weight and pdf bugs jointly
  (:mod:`brdflab.validate.sample_hints`), and parameters left at their default that the weights fit at
  another value.
* **Same method as brdflab** (informative for a BSDF; the verdict for a warp, a file without pdf column, or
  a blind self-consistency test): the chi-square test of :mod:`brdflab.validate.chi2` of ω_o against
  brdflab's pdf (bins from a pilot of brdflab's *own* sampler; directions below the horizon count as failed
  on both sides) and the pdf column per sample (|p_file − p| / max(p_file, p) > 10⁻² for at most 0.1 %).

A malformed file raises :class:`~brdflab.errors.BrdflabError` with ``file:line``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from brdflab.errors import BrdflabError
from brdflab.validate import chi2 as c2
from brdflab.validate import sample_hints as hints
from brdflab.validate import selfconsistency as _sc
from brdflab.validate.seeding import test_seed

#: Components of ω_i equal within this tolerance form one group.
WI_TOLERANCE = 1e-4
#: Per-sample relative tolerance of the pdf and weight columns, and the fraction allowed beyond it.
COLUMN_RTOL = 1e-2
COLUMN_FRACTION = 1e-3
#: Fewest samples per ω_i group for a meaningful chi-square test.
MIN_GROUP = 50
#: Most ω_i groups one file may have (each is a chi-square test of its own).
MAX_GROUPS = 10_000

DIRECTION_WARPS = ("uniform_sphere", "uniform_hemisphere", "cosine_hemisphere", "beckmann")


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
    data, lines, ncol = read_table(path, ALLOWED, EXPECTED)
    return _columns(str(path), data, lines, ncol)


def read_table(path: str | Path, allowed: tuple[int, ...], expected: str) -> tuple[np.ndarray, np.ndarray, int]:
    """Read a numeric table in the samples-file conventions (text with ``#`` comments, ``.npy``, or ``.npz``
    with the key ``samples``): (N, k) float64 data, the file line (text) or row (arrays) of each sample, and
    k, which must be one of ``allowed`` (``expected`` says so in the error).

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
        if bad.any():
            raise BrdflabError(f"row {int(np.argmax(bad))}: non-finite value", file=path)
        return data, np.arange(len(data)), arr.shape[1]
    rows, lines, ncol, first = [], [], None, None
    try:
        text = read_input(path, "samples file").decode("utf-8", errors="strict")
    except UnicodeDecodeError:
        raise BrdflabError("not a text file (expected whitespace-separated numbers; binary data: use .npy)",
                           file=path) from None
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
        if not all(np.isfinite(vals)):
            raise BrdflabError("non-finite value (nan/inf)", file=path, line=num)
        rows.append(vals)
        lines.append(num)
    if not rows:
        raise BrdflabError("no samples (only comments or blank lines)", file=path)
    return np.array(rows), np.array(lines), ncol


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


@dataclass
class ColumnCheck:
    """Comparison of a pdf or weight column with brdflab's values."""

    column: str
    max_rel_error: float
    fraction_off: float
    worst_line: int
    worst_wo: np.ndarray
    file_value: float
    our_value: float
    hint: str = ""

    @property
    def passed(self) -> bool:
        """At most 0.1 % of the samples off by more than 10⁻² relative."""
        return self.fraction_off <= COLUMN_FRACTION

    def describe(self, path: str, hint: bool = True) -> str:
        """One line naming the worst sample and (``hint``) the hint."""
        against = "the expected f·cos/pdf" if self.column == "weight" else "brdflab"
        s = (f"{self.column} column: worst relative error {self.max_rel_error:.3g} at {path}:{self.worst_line} "
             f"(wo = {_vec(self.worst_wo)}: file {self.file_value:.6g}, {against} {self.our_value:.6g}); "
             f"{100 * self.fraction_off:.2f} % of the samples off by > {COLUMN_RTOL:g}")
        return s + (f" — {self.hint}" if self.hint and hint else "")


def _vec(v) -> str:
    return "(" + ", ".join(f"{x:.5g}" for x in np.ravel(v)[:3]) + ")"


@dataclass
class GroupResult:
    """Result for the samples of one ω_i.

    ``sc`` is the method-agnostic self-consistency test of the directions against the file's own pdf
    column (:mod:`brdflab.validate.selfconsistency`); ``chi2`` and ``pdf`` compare with brdflab's own
    sampler and pdf (they tell whether the file uses brdflab's sampling *method*; they decide the verdict
    only without a pdf column, or when the self-consistency test is blind).
    """

    wi: np.ndarray
    n: int
    first_line: int
    chi2: c2.Chi2Result | None
    pdf: ColumnCheck | None = None
    weight: ColumnCheck | None = None
    problems: list[str] = field(default_factory=list)
    sc: _sc.SelfConsistency | None = None
    #: What the pdf column is, compared with brdflab's pdf (a known bug), or "".
    pdf_identity: str = ""
    #: Corrections of the pdf column with which the samples are self-consistent (method-agnostic hints).
    pdf_fixes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    #: A warp: the target *is* brdflab's density (no other method can be right), judged as before.
    warp: bool = False

    @property
    def judged_by_self_consistency(self) -> bool:
        """True when the pdf column was tested against the directions themselves (not blind; BSDFs only)."""
        return self.sc is not None and not self.sc.blind and not self.warp

    @property
    def pdf_bug(self) -> bool:
        """The pdf column equals brdflab's pdf with a named bug (not a legitimate other method)."""
        t = self.pdf_identity
        return bool(t) and "constant" not in t and "mixes the lobes" not in t

    @property
    def distribution_ok(self) -> bool:
        """The directions follow the pdf column (self-consistency), or brdflab's pdf without a usable column."""
        if self.judged_by_self_consistency:
            return self.sc.passed and not self.pdf_bug
        return self.chi2 is None or self.chi2.passed

    @property
    def same_method(self) -> bool:
        """The directions and the pdf column are brdflab's (chi-square and pdf comparison pass)."""
        return (self.chi2 is None or self.chi2.passed) and (self.pdf is None or self.pdf.passed)

    @property
    def passed(self) -> bool:
        """Directions consistent with the pdf column, pdf column right, and weights right."""
        if self.problems:
            return False
        ok = self.distribution_ok
        if not self.judged_by_self_consistency and self.pdf is not None:
            ok = ok and self.pdf.passed
        return ok and (self.weight is None or self.weight.passed)


@dataclass
class ExternalResult:
    """Outcome of :func:`check_samples` for one file.

    Attributes
    ----------
    path, against, params
        The file, the reference (BSDF or warp name) and its parameters.
    groups
        One :class:`GroupResult` per ω_i.
    threshold
        Per-group chi-square significance (Šidák over the groups).
    """

    path: str
    against: str
    params: dict
    groups: list[GroupResult]
    threshold: float

    @property
    def passed(self) -> bool:
        """Every group passed."""
        return bool(self.groups) and all(g.passed for g in self.groups)

    #: Parameter lines (values used, defaults marked) and warnings, printed once before the groups.
    notes: list[str] = field(default_factory=list)

    def messages(self) -> list[str]:
        """One line per group (verdict), then one line per failure saying which check failed and why."""
        out = list(self.notes)
        seen = set(out)
        for g in self.groups:
            out.extend(self._group_lines(g))
            for w in g.warnings:
                if w not in seen:
                    out.append("  " + w)
                    seen.add(w)
        return out

    def _group_lines(self, g: GroupResult) -> list[str]:
        out = []
        head = f"{'PASS' if g.passed else 'FAIL'}  wi = {_vec(g.wi)} ({g.n} samples from line {g.first_line})"
        bits = []
        if g.judged_by_self_consistency:
            bits.append(f"self-consistency p = {g.sc.p_value:.4g}")
        if g.chi2 is not None:
            bits.append(f"chi2 vs brdflab p = {g.chi2.p_value:.4g}")
        if g.pdf is not None:
            bits.append(f"pdf vs brdflab worst rel. error {g.pdf.max_rel_error:.2g}")
        if g.weight is not None:
            bits.append(f"weight worst rel. error {g.weight.max_rel_error:.2g}")
        out.append(head + (": " + ", ".join(bits) if bits else ""))
        ours = f"brdflab's {self.against} pdf"
        chi_txt = "" if g.chi2 is None else (g.chi2.fault or f"chi2 p = {g.chi2.p_value:.3g}")
        if g.chi2 is None:
            pass
        elif g.judged_by_self_consistency:
            if g.sc.passed and not g.pdf_bug:
                if g.same_method:
                    out.append(f"  the directions follow the pdf written beside them, sampled as brdflab samples "
                               f"{self.against} ({chi_txt})")
                else:
                    tail = "that is fine" if g.weight is not None else \
                        "that is fine for a sampler of this BSDF, but without a weight column brdflab cannot tell " \
                        "it from a sampler of other parameters (write the weights to have them checked against f)"
                    ident = f" ({g.pdf_identity})" if g.pdf_identity else ""
                    out.append(f"  a different sampling method than brdflab's (self-consistent){ident}: the "
                               f"directions follow the pdf written beside them ({g.sc.summary()}), not {ours} "
                               f"({chi_txt}); " + tail)
            elif g.sc.passed:  # the column is brdflab's pdf with a known bug; the self-consistency test missed it
                out.append(f"  WRONG PDF COLUMN: {g.pdf_identity} (the self-consistency test alone did not see it: "
                           f"p = {g.sc.p_value:.3g})")
                if g.pdf is not None:
                    out.append("    " + g.pdf.describe(self.path, hint=False))
            else:
                why = g.sc.summary()
                if g.pdf_identity and g.chi2.passed:
                    out.append(f"  WRONG PDF COLUMN: the sampled directions are consistent with {ours} ({chi_txt}), "
                               f"but not with the pdf written beside them ({why})")
                elif g.pdf is not None and g.pdf.passed:
                    out.append(f"  WRONG DISTRIBUTION: the pdf column is brdflab's, but the sampled directions do not "
                               f"follow it ({why}; {chi_txt}): the sampling routine (warp) is wrong")
                elif g.pdf_fixes:
                    out.append(f"  WRONG PDF COLUMN: the sampled directions do not follow the pdf written beside them "
                               f"({why}), but they do follow it corrected as the hint says (whatever the sampling "
                               "method)")
                else:
                    ctx = f"nor {ours} ({chi_txt})" if not g.chi2.passed else \
                        f"(they are consistent with {ours}: {chi_txt}; then the column is the wrong part)"
                    out.append(f"  WRONG DISTRIBUTION OR PDF COLUMN: the sampled directions do not follow the pdf "
                               f"written beside them ({why}) {ctx}")
                hints = [g.pdf_identity] if g.pdf_identity else \
                    [f"{t} — with that corrected, the samples are self-consistent" for t in g.pdf_fixes[:1]]
                out.extend("    hint: " + h for h in hints)
                if g.pdf is not None and not g.pdf.passed:
                    out.append("    " + g.pdf.describe(self.path, hint=False))
        else:
            if g.warp and g.sc is not None and g.sc.passed and not g.chi2.passed:
                out.append(f"  the directions do follow the pdf written beside them ({g.sc.summary()}): a correct "
                           f"sampler of another density than brdflab's {self.against} (other parameters?)")
            elif g.sc is not None and g.sc.blind:
                out.append(f"  ({g.sc.fault}; judged against brdflab's own sampler instead)")
            elif g.pdf is None:
                out.append("  (no pdf column: only brdflab's own sampling method can be recognised; write the pdf "
                           "column to have another method judged on its own terms)")
            if not g.chi2.passed:
                why = g.chi2.fault or (f"p = {g.chi2.p_value:.3g} ≤ {g.chi2.threshold:.2g}, X² = "
                                       f"{g.chi2.statistic:.1f} for {g.chi2.dof} dof")
                out.append(f"  WRONG DISTRIBUTION: the sampled directions do not follow {ours} ({why})")
            if g.pdf is not None and not g.pdf.passed:
                out.append("  WRONG PDF COLUMN: " + g.pdf.describe(self.path))
        if g.weight is not None and not g.weight.passed:
            out.append("  WRONG WEIGHT COLUMN: " + g.weight.describe(self.path))
        out.extend("  " + p for p in g.problems)
        return out


def _reference(against, alpha: float | None, params: dict | None, make=None):
    """(name, kind, object): kind 'warp' → (sample(u), pdf(w)); kind 'bsdf' → a BSDF."""
    from brdflab.validate.battery import WARPS, resolve_bsdfs

    params = dict(params or {})
    if not isinstance(against, str):
        from brdflab.validate.guard import describe

        return describe(against), "bsdf", against
    if against in WARPS:
        w, p, takes_alpha = WARPS[against]
        if takes_alpha:
            if alpha is None:
                raise BrdflabError(f"--against {against} needs --alpha (the roughness the samples were drawn with)")
            return against, "warp", (lambda u: w(u, alpha), lambda d: p(d, alpha))
        if alpha is not None:
            raise BrdflabError(f"--alpha does not apply to the {against} warp")
        if params:
            raise BrdflabError(f"the {against} warp has no parameters (got {', '.join(params)})")
        return against, "warp", (w, p)
    try:
        entry = resolve_bsdfs([against], make)[0]
    except (KeyError, LookupError) as exc:
        raise BrdflabError(f"unknown --against '{_short(against, 40)}': not a warp ({', '.join(DIRECTION_WARPS)}) "
                           f"nor a BSDF ({exc})") from None
    if entry.takes_alpha and alpha is None and against in _builtin_names():
        raise BrdflabError(f"--against {against} needs --alpha (the roughness the samples were drawn with)")
    if not entry.takes_alpha and alpha is not None:
        raise BrdflabError(f"--alpha does not apply to {against} (it has no alpha parameter)")
    return against, "bsdf", entry.make(alpha, params)


def _builtin_names():
    from brdflab.validate.battery import BSDFS

    return BSDFS


def _column_check(column: str, file_v: np.ndarray, ours: np.ndarray, lines: np.ndarray, wo: np.ndarray,
                  hint: str) -> ColumnCheck:
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.abs(file_v - ours) / np.maximum(np.maximum(np.abs(file_v), np.abs(ours)), 1e-300)
    rel = np.where(file_v == ours, 0.0, rel)
    rel_s = rel.max(axis=1) if rel.ndim == 2 else rel
    i = int(np.argmax(rel_s))
    fv = file_v[i] if file_v.ndim == 1 else file_v[i][int(np.argmax(rel[i]))]
    ov = ours[i] if ours.ndim == 1 else ours[i][int(np.argmax(rel[i]))]
    return ColumnCheck(column, float(rel_s[i]), float((rel_s > COLUMN_RTOL).mean()), int(lines[i]), wo[i],
                       float(fv), float(ov), hint)


def _ratio_hint(ratio: np.ndarray, candidates: list[tuple[str, np.ndarray]]) -> str:
    """The first candidate explanation e with file/brdflab ≈ e (median relative deviation < 1 %), if any."""
    ok = np.isfinite(ratio) & (ratio > 0)
    if ok.sum() < 10:
        return ""
    for text, expect in candidates:
        e = expect[ok]
        good = np.isfinite(e) & (e > 0)
        if good.sum() >= 10 and np.median(np.abs(ratio[ok][good] / e[good] - 1)) < 1e-2:
            return text
    med = np.median(ratio[ok])
    if np.median(np.abs(ratio[ok] / med - 1)) < 1e-3:
        return f"the file's values are brdflab's times a constant {med:.6g} (a missing normalisation factor?)"
    return ""


def check_samples(samples: str | Path | Samples, against, *, alpha: float | None = None,
                  params: dict | None = None, seed: int | None = None, threshold: float = c2.SIGNIFICANCE,
                  make=None) -> ExternalResult:
    """Check a file of samples from another renderer against brdflab's BSDF or warp.

    Parameters
    ----------
    samples
        A path (text, ``.npy``, ``.npz``; see the module docstring) or :class:`Samples`.
    against
        A warp name (``beckmann``, ``cosine_hemisphere``, ``uniform_hemisphere``, ``uniform_sphere``), a
        BSDF name (built-in, a lobe variant such as ``roughsubstrate/specular``, or a registered plugin's
        type), or a BSDF instance.
    alpha, params
        Roughness and parameters of the reference (as used to produce the samples).
    seed
        Seed of brdflab's own pilot sample (default: derived from the file name and the reference).
    threshold
        Family-wise significance; Šidák-corrected over the ω_i groups.
    make
        ``make(name, alpha, params)`` to build BSDFs by name (default: built-ins, then the plugin registry).

    Returns
    -------
    ExternalResult
        ``passed``; ``messages()`` says per ω_i whether the distribution, the pdf column or the weights are wrong.

    Examples
    --------
    >>> import numpy as np, tempfile, pathlib
    >>> from brdflab.math import warps
    >>> wo = warps.square_to_cosine_hemisphere(np.random.default_rng(5).random((20_000, 2)))
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "cos.npy"
    >>> np.save(p, np.column_stack([wo, wo[:, 2] / np.pi]))
    >>> r = check_samples(p, "cosine_hemisphere")
    >>> r.passed, len(r.groups)
    (True, 1)
    """
    s = samples if isinstance(samples, Samples) else read_samples(samples)
    name, kind, ref = _reference(against, alpha, params, make)
    params = dict(params or {})
    if kind == "warp" and s.weight is not None:
        raise BrdflabError("weight columns are not allowed for a warp (use wi wo [pdf] or x y z [pdf])", file=s.path)
    if kind == "bsdf" and s.direction_only:
        raise BrdflabError(f"{name} is a BSDF: each line needs wi and wo (6, 7 or 10 columns), not 3 or 4",
                           file=s.path)
    if seed is None:
        seed = test_seed("external", Path(s.path).name, name, alpha, params)
    groups = [np.arange(len(s.wo))] if kind == "warp" else group_by_wi(s.wi)
    if len(groups) > MAX_GROUPS:  # bounded work, and each test needs MIN_GROUP samples of one ω_i
        raise BrdflabError(f"{len(groups):,} distinct ω_i; at most {MAX_GROUPS:,} can be tested, each with at least "
                           f"{MIN_GROUP} samples: write many samples per ω_i (e.g. 10⁴ for each of a few ω_i)",
                           file=s.path)
    thr = c2.sidak(threshold, len(groups))
    notes, fit = _parameters(against, kind, alpha, params, make)
    out = []
    for gi, idx in enumerate(groups):
        out.append(_check_group(s, idx, name, kind, ref, int(np.random.SeedSequence([seed, gi]).generate_state(1)[0]),
                                thr, fit))
    res = ExternalResult(s.path, name, {"alpha": alpha, **params} if alpha is not None else params, out, thr)
    res.notes = notes
    return res


def _parameters(against, kind: str, alpha: float | None, params: dict, make) -> tuple[list[str], tuple | None]:
    """The parameter line (values used, defaults marked) and (make, defaults, given) for fitting defaults."""
    if kind != "bsdf" or not isinstance(against, str):
        return ([f"parameters: alpha={alpha:g}"] if alpha is not None else []), None
    from brdflab.validate.battery import resolve_bsdfs
    from brdflab.validate.guard import format_params

    try:
        from brdflab.plugins import bsdf_parameters

        defaults = bsdf_parameters(against.partition("/")[0])
    except Exception:  # noqa: BLE001 - a BSDF given only through `make`: no parameter list to show
        return [], None
    shown = {"alpha": alpha} if alpha is not None else {}
    shown.update({k: params[k] for k in params})
    left = {k: v for k, v in defaults.items() if k not in params and k != "alpha"}

    def fmt(v):
        a = np.ravel(np.asarray(v)) if isinstance(v, list | tuple | np.ndarray) else None
        if a is not None and a.size > 1:
            return f"{float(a[0]):g}" if np.ptp(a) == 0 else ",".join(f"{float(x):g}" for x in a)
        return f"{v:g}" if isinstance(v, float) else str(v)

    line = f"parameters of {against}: " + ", ".join(
        [format_params({k: v for k, v in shown.items() if not isinstance(v, np.ndarray)})]
        + [f"{k}={fmt(v)}" for k, v in shown.items() if isinstance(v, np.ndarray)]
        + [f"{k}={fmt(v)} (default)" for k, v in left.items()]).strip(", ")
    entry = resolve_bsdfs([against], make)[0]
    return [line], ((lambda p: entry.make(alpha, p)), defaults, dict(params))


def _check_group(s: Samples, idx: np.ndarray, name: str, kind: str, ref, seed: int, thr: float,
                 fit: tuple | None = None) -> GroupResult:
    """Check one ω_i group: self-consistency, brdflab's own sampler and pdf, weights, hints.

    ``fit`` is (make(params) → BSDF, defaults, given params) for the parameter-default warnings, or None.
    """
    from brdflab.validate.guard import CheckedBSDF, PluginFault

    wo = s.wo[idx]
    lines = s.lines[idx]
    norm = np.sqrt((wo * wo).sum(axis=1))
    failed = norm == 0
    if s.pdf is not None:
        failed |= s.pdf[idx] <= 0
    wi1 = s.wi[idx].mean(axis=0)
    wi1 = wi1 / max(np.linalg.norm(wi1), 1e-300) if kind == "bsdf" else wi1
    g = GroupResult(wi1, len(idx), int(lines[0]), None, warp=kind == "warp")
    if kind == "bsdf" and abs(np.linalg.norm(s.wi[idx[0]]) - 1) > 1e-3:
        g.problems.append(f"{s.path}:{lines[0]}: wi = {_vec(s.wi[idx[0]])} is not a unit vector")
    bad = ~failed & (np.abs(norm - 1) > 1e-3)
    if bad.any():
        i = int(np.argmax(bad))
        g.problems.append(f"{s.path}:{lines[i]}: wo = {_vec(wo[i])} is not a unit vector (|wo| = {norm[i]:.4g}); "
                          f"{int(bad.sum())} such samples")
    wo_n = np.where(failed[:, None], 0.0, wo / np.where(norm > 0, norm, 1.0)[:, None])
    if len(idx) < MIN_GROUP:
        g.problems.append(f"only {len(idx)} samples for this wi (at least {MIN_GROUP} are needed; wi components equal "
                          f"within {WI_TOLERANCE:g} are grouped)")
        return g
    valid = ~failed
    s_pilot, s_mix, s_sc = np.random.SeedSequence(seed).spawn(3)
    n_pilot = max(len(idx) // 2, 4000)
    b = None
    try:
        if kind == "warp":
            sample_w, pdf_w = ref
            pilot = sample_w(np.random.default_rng(s_pilot).random((n_pilot, 2)))
            pilot = pilot[pdf_w(pilot) > 0]
            pdf_fn = pdf_w
            obs = wo_n[valid]
            ours = pdf_w(wo_n) if s.pdf is not None else None
        else:
            b = CheckedBSDF(ref, name)
            wi_p = np.ascontiguousarray(np.broadcast_to(wi1, (n_pilot, 3)))
            r = b.sample(wi_p, np.random.default_rng(s_pilot).random((n_pilot, 3)))
            pilot = r.wo[(r.pdf > 0) & (r.wo[:, 2] > 0)]

            def pdf_fn(w):
                p = b.pdf(np.ascontiguousarray(np.broadcast_to(wi1, (len(w), 3))), w)
                return np.where(w[:, 2] > 0, p, 0.0)  # below the horizon counts as failed (module docstring)

            obs = wo_n[valid & (wo_n[:, 2] > 0)]
            wi_all = np.ascontiguousarray(np.broadcast_to(wi1, (len(idx), 3)))
            ours = b.pdf(wi_all, wo_n) if s.pdf is not None else None
        g.chi2 = c2.directions_test(f"{name} (file)", obs, len(idx), pdf_fn, pilot, seed=seed,
                                    params={"wi": tuple(np.round(wi1, 6))}, threshold=thr,
                                    mix_rng=np.random.default_rng(s_mix))
        cmp = valid & (wo_n[:, 2] > 0) if kind == "bsdf" else valid
        p_true = None  # the true density of the sampled directions at the compared samples, when known
        if s.pdf is not None and cmp.any():
            fp = s.pdf[idx][cmp]
            # Method-agnostic: the directions against their own pdf column (brdflab's pdf only shapes the bins).
            binning = _sc.make_binning(wo_n[cmp], len(idx), pdf_fn, pilot, np.random.default_rng(s_sc))
            g.sc = _sc.self_consistency_test(wo_n[cmp], fp, len(idx), pdf_fn, pilot, threshold=thr, binning=binning)
            if g.sc.blind and not g.chi2.passed and kind == "bsdf":  # another method, far from brdflab's
                alt = _sc.rescue(wo_n[cmp], fp, len(idx), thr, np.random.default_rng(s_sc))
                if alt is not None:
                    g.sc, binning = alt
            g.pdf_identity = hints.pdf_identity(fp, ours[cmp], wi1, wo_n[cmp], ref if kind == "bsdf" else None,
                                                kind == "bsdf")
            # The true density of the directions, from the strongest evidence: a self-consistent column; the
            # column identified as brdflab's pdf with a bug while the directions are consistent with brdflab's;
            # a correction of the column that makes it self-consistent; brdflab's pdf (chi-square not rejected).
            fixes = []
            if not g.sc.passed and not g.sc.blind:
                fixes = hints.pdf_corrections(binning, fp, wi1, wo_n[cmp], kind == "bsdf", g.sc.mass_ratio, thr)
                g.pdf_fixes = [t for t, _ in fixes]
            if g.sc.passed:
                p_true = fp
            elif g.pdf_identity and g.chi2.passed:
                p_true = ours[cmp]
            elif fixes:
                p_true = fp * fixes[0][1]
            elif g.chi2.passed:
                p_true = ours[cmp]
            g.pdf = _column_check("pdf", fp, ours[cmp], lines[cmp], wo_n[cmp], g.pdf_identity)
            if not g.pdf.passed and fit is not None and kind == "bsdf" and not g.pdf_bug:
                make_p, defaults, given = fit  # a parameter of the pdf left at its default (say intIOR)
                g.warnings = hints.fit_defaults(make_p, defaults, given, wi1, wo_n[cmp], fp, fp, column="pdf")
            if not g.pdf.passed and not g.pdf.hint and g.chi2.passed and not g.judged_by_self_consistency:
                g.pdf.hint = "the sampled directions follow brdflab's pdf: only the pdf written with them is wrong"
        if kind == "bsdf" and s.weight is not None and cmp.any():
            k = int(cmp.sum())
            wi_k = np.ascontiguousarray(np.broadcast_to(wi1, (k, 3)))
            f = b.eval(wi_k, wo_n[cmp])
            # The weight must be f·cos θo / (the density of the sampled directions): the file's pdf column when
            # it is right, whatever the method; brdflab's pdf without a usable column.
            p_w = p_true if p_true is not None else (s.pdf[idx][cmp] if s.pdf is not None else b.pdf(wi_k, wo_n[cmp]))
            with np.errstate(divide="ignore", invalid="ignore"):
                ow = np.where(p_w[:, None] > 0, f * (wo_n[cmp][:, 2] / p_w)[:, None], 0.0)
            fw = s.weight[idx][cmp]
            lum = hints.LUMINANCE
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                ratio = (fw @ lum) / np.where(ow @ lum > 0, ow @ lum, np.nan)
                fix = None
                if s.pdf is not None and p_true is not None and not np.allclose(p_true, s.pdf[idx][cmp], rtol=1e-3):
                    fix = p_true / np.where(s.pdf[idx][cmp] > 0, s.pdf[idx][cmp], np.nan)
            g.weight = _column_check("weight", fw, ow, lines[cmp], wo_n[cmp],
                                     hints.weight_hint(ratio, wi1, wo_n[cmp], fix))
            if not g.weight.passed and fit is not None:
                make_p, defaults, given = fit
                g.warnings = g.warnings or hints.fit_defaults(make_p, defaults, given, wi1, wo_n[cmp], p_w, fw)
                if g.warnings and "constant" in g.weight.hint:
                    g.weight.hint = "see the warning on parameters below"
    except PluginFault as fault:
        g.problems.append(str(fault))
    return g
