"""What ``brdflab chi2 --samples FILE --against NAME`` found, per ω_i group and for the file: the column checks
(weights against NAME's f·cos/pdf, pdf against NAME's), the self-consistency and chi-square verdicts with their
hints, the messages the command prints and the JSON. The checks themselves are
:mod:`brdflab.judges.samples.bsdf_checks`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from brdflab.judges.material import chi2 as c2
from brdflab.judges.samples import selfconsistency as _sc

#: Per-sample relative tolerance of the pdf and weight columns, and the fraction allowed beyond it.
COLUMN_RTOL = 1e-2


COLUMN_FRACTION = 1e-3


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
    column (:mod:`brdflab.judges.samples.selfconsistency`); ``chi2`` and ``pdf`` compare with brdflab's own
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
    def pdf_matches(self) -> bool:
        """The pdf column equals brdflab's pdf (the column check passed): no hint may then call it wrong."""
        return self.pdf is not None and self.pdf.passed

    @property
    def pdf_bug(self) -> bool:
        """The pdf column equals brdflab's pdf with a named bug (not a legitimate other method)."""
        t = self.pdf_identity
        return bool(t) and "constant" not in t and "mixes the lobes" not in t and not self.pdf_matches

    @property
    def settled_by_chi2(self) -> bool:
        """The self-consistency test failed, but the pdf column is brdflab's pdf and the directions pass brdflab's
        chi-square: one hypothesis, and the chi-square's expected counts are exact quadratures of that very pdf,
        so it decides (a self-consistency failure alone, there, is a false alarm or rounding, never a bug)."""
        return (self.judged_by_self_consistency and not self.sc.passed and self.pdf_matches
                and self.chi2 is not None and self.chi2.passed)

    @property
    def distribution_ok(self) -> bool:
        """The directions follow the pdf column (self-consistency), or brdflab's pdf without a usable column."""
        if self.judged_by_self_consistency:
            return (self.sc.passed or self.settled_by_chi2) and not self.pdf_bug
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
        """Every group passed, and the sampler wrote no NaN or infinity."""
        return bool(self.groups) and all(g.passed for g in self.groups) and not self.nonfinite

    #: Parameter lines (values used, defaults marked) and warnings, printed once before the groups.
    notes: list[str] = field(default_factory=list)
    #: NaN/inf values the sampler wrote (:func:`brdflab.judges.samples.tables.nonfinite_summary`), a finding.
    nonfinite: dict | None = None

    def nonfinite_lines(self) -> list[str]:
        """The finding about NaN/inf values, with where they are and the usual cause."""
        f = self.nonfinite
        if not f:
            return []
        cols = ", ".join(f"{k} {v:,}" for k, v in f["columns"].items())
        where = ", ".join(str(v) for v in f["lines"])
        out = [f"FAIL  {f['count']:,} of {f['total']:,} samples have a non-finite value ({f['nan']:,} NaN; by column: "
               f"{cols}), first at line(s) {where}"]
        if f["below_surface"]:
            out.append(f"  hint: {f['below_surface']:,} of them have ω_o below the surface: a 0/0 where the sample "
                       "failed — return weight 0 (and pdf 0) there; a renderer that drops NaN samples loses their "
                       "light silently")
        else:
            out.append("  hint: a division by a zero pdf or cosine, or a sqrt/acos of a value outside its domain; they "
                       "are counted as failed samples in the checks below")
        return out

    def messages(self) -> list[str]:
        """One line per group (verdict), then one line per failure saying which check failed and why."""
        out = list(self.notes) + self.nonfinite_lines()
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
        if getattr(g.chi2, "delta", False):  # a delta BSDF's samples: the delta judge's line says it all
            conv = getattr(g.chi2, "convention", "")
            return [head, "  " + g.chi2.message + (f"; refraction weights {conv}" if conv else ""),
                    *("  " + p for p in g.problems)]
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
            elif g.settled_by_chi2:
                out.append(f"  the directions follow {ours} ({chi_txt}), which the pdf column equals; the "
                           f"self-consistency test alone disagreed ({g.sc.summary()}): with the column equal to "
                           "brdflab's pdf the chi-square decides (its expected counts are exact), so this is no bug")
            else:
                why = g.sc.summary()
                if g.pdf_identity and g.chi2.passed and not g.pdf_matches:
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
                if g.pdf_matches:  # never contradict the evidence printed beside a hint: the column is right
                    hints = []
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
