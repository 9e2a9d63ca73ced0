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

* **Self-consistency** (:mod:`brdflab.judges.samples.selfconsistency`): the directions against the file's own
  pdf column (Σ r/p_k per bin against N ∫ r, r = brdflab's pdf of the reference shaping the bins); any
  correct method passes. Šidák-corrected over the groups.
* **Weight columns**: against the reference's f·cos θ_o / p with p the (self-consistent) pdf column, or the
  true density when a hint identifies it; hints name weight and pdf bugs jointly
  (:mod:`brdflab.judges.samples.bsdf_hints`), and parameters left at their default that the weights fit at
  another value.
* **Same method as brdflab** (informative for a BSDF; the verdict for a warp, a file without pdf column, or
  a blind self-consistency test): the chi-square test of :mod:`brdflab.judges.material.chi2` of ω_o against
  brdflab's pdf (bins from a pilot of brdflab's *own* sampler; directions below the horizon count as failed
  on both sides) and the pdf column per sample (|p_file − p| / max(p_file, p) > 10⁻² for at most 0.1 %).

A malformed file raises :class:`~brdflab.errors.BrdflabError` with ``file:line``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from brdflab.errors import BrdflabError
from brdflab.judges.core.seeding import test_seed
from brdflab.judges.material import chi2 as c2
from brdflab.judges.samples import bsdf_hints as hints
from brdflab.judges.samples import selfconsistency as _sc
from brdflab.judges.samples.bsdf_results import (  # noqa: F401 (re-exported: the module's former contents)
    COLUMN_FRACTION,
    COLUMN_RTOL,
    ColumnCheck,
    ExternalResult,
    GroupResult,
    _vec,
)
from brdflab.judges.samples.tables import (  # noqa: F401 (re-exported: the module's former contents)
    ALLOWED,
    EXPECTED,
    WI_TOLERANCE,
    Samples,
    _check_array_header,
    _columns,
    _is_float,
    _load_array,
    _short,
    group_by_wi,
    read_samples,
    read_table,
)

#: Fewest samples per ω_i group for a calibrated verdict: at 50, correct files of brdflab's own sampler failed
#: 9 in 100 (nominal 1); at 100–1000, 0–1 in 100 (benchmarks/samples_false_alarms.py, docs/benchmarks.md).
MIN_GROUP = 200
#: Most ω_i groups one file may have (each is a chi-square test of its own).
MAX_GROUPS = 10_000

DIRECTION_WARPS = ("uniform_sphere", "uniform_hemisphere", "cosine_hemisphere", "beckmann")


def _reference(against, alpha: float | None, params: dict | None, make=None):
    """(name, kind, object): kind 'warp' → (sample(u), pdf(w)); kind 'bsdf' → a BSDF."""
    from brdflab.judges.material.battery import WARPS, resolve_bsdfs

    params = dict(params or {})
    if not isinstance(against, str):
        from brdflab.judges.core.guard import describe

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
    from brdflab.judges.material.battery import BSDFS

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
        if kind == "bsdf" and getattr(ref, "all_delta", False):  # no density: the delta judge
            from brdflab.judges.samples.delta_samples import check_delta_group

            out.append(check_delta_group(s, idx, name, ref, thr))
            continue
        out.append(_check_group(s, idx, name, kind, ref, int(np.random.SeedSequence([seed, gi]).generate_state(1)[0]),
                                thr, fit))
    res = ExternalResult(s.path, name, {"alpha": alpha, **params} if alpha is not None else params, out, thr)
    res.notes = notes
    res.nonfinite = s.nonfinite_info
    return res


def _parameters(against, kind: str, alpha: float | None, params: dict, make) -> tuple[list[str], tuple | None]:
    """The parameter line (values used, defaults marked) and (make, defaults, given) for fitting defaults."""
    if kind != "bsdf" or not isinstance(against, str):
        return ([f"parameters: alpha={alpha:g}"] if alpha is not None else []), None
    from brdflab.judges.core.guard import format_params
    from brdflab.judges.material.battery import resolve_bsdfs

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
    from brdflab.judges.core.guard import CheckedBSDF, PluginFault

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
    # A transmissive reference (glass): directions below the surface are samples, not failures.
    both = kind == "bsdf" and bool(getattr(ref, "has_transmission", False))
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
            pilot = r.wo[(r.pdf > 0) & ((r.wo[:, 2] > 0) | both)]

            def pdf_fn(w):
                p = b.pdf(np.ascontiguousarray(np.broadcast_to(wi1, (len(w), 3))), w)
                return np.where((w[:, 2] > 0) | both, p, 0.0)  # below the horizon counts as failed (docstring)

            obs = wo_n[valid & ((wo_n[:, 2] > 0) | both)]
            wi_all = np.ascontiguousarray(np.broadcast_to(wi1, (len(idx), 3)))
            ours = b.pdf(wi_all, wo_n) if s.pdf is not None else None
        g.chi2 = c2.directions_test(f"{name} (file)", obs, len(idx), pdf_fn, pilot, seed=seed,
                                    params={"wi": tuple(np.round(wi1, 6))}, threshold=thr,
                                    mix_rng=np.random.default_rng(s_mix), split_horizon=both, pilot_total=n_pilot)
        cmp = valid & ((wo_n[:, 2] > 0) | both) if kind == "bsdf" else valid
        p_true = None  # the true density of the sampled directions at the compared samples, when known
        if s.pdf is not None and cmp.any():
            fp = s.pdf[idx][cmp]
            # Method-agnostic: the directions against their own pdf column (brdflab's pdf only shapes the bins).
            binning = _sc.make_binning(wo_n[cmp], len(idx), pdf_fn, pilot, np.random.default_rng(s_sc),
                                       split_horizon=both)
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
            g.pdf = _column_check("pdf", fp, ours[cmp], lines[cmp], wo_n[cmp], g.pdf_identity)
            if g.sc.passed or (g.pdf.passed and g.chi2.passed):  # self-consistent, or brdflab's pdf itself
                p_true = fp
            elif g.pdf_identity and g.chi2.passed:
                p_true = ours[cmp]
            elif fixes:
                p_true = fp * fixes[0][1]
            elif g.chi2.passed:
                p_true = ours[cmp]
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
                cos_o = np.abs(wo_n[cmp][:, 2]) if both else wo_n[cmp][:, 2]  # f·|cos θo|/p for transmission
                ow = np.where(p_w[:, None] > 0, f * (cos_o / p_w)[:, None], 0.0)
            fw = s.weight[idx][cmp]
            lum = hints.LUMINANCE
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                ratio = (fw @ lum) / np.where(ow @ lum > 0, ow @ lum, np.nan)
                fix = None
                if s.pdf is not None and p_true is not None and not np.allclose(p_true, s.pdf[idx][cmp], rtol=1e-3):
                    fix = p_true / np.where(s.pdf[idx][cmp] > 0, s.pdf[idx][cmp], np.nan)
            g.weight = _column_check("weight", fw, ow, lines[cmp], wo_n[cmp],
                                     hints.weight_hint(ratio, wi1, wo_n[cmp], fix,
                                                       model_bugs=hints.microfacet_weight_bugs(ref, wi1, wo_n[cmp])))
            if not g.weight.passed and fit is not None:
                make_p, defaults, given = fit
                g.warnings = g.warnings or hints.fit_defaults(make_p, defaults, given, wi1, wo_n[cmp], p_w, fw)
                if g.warnings and "constant" in g.weight.hint:
                    g.weight.hint = "see the warning on parameters below"
    except PluginFault as fault:
        g.problems.append(str(fault))
    return g
