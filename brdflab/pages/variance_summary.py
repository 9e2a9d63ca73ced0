"""What a variance study says: speed-ups and error ratios with intervals, times to reach an error, the equal-time
pick, the bias flags and the summary lines (statements only where an interval or a Holm-corrected test supports
them). The study itself is :mod:`brdflab.pages.variance`, its page :mod:`brdflab.pages.variance_page`.
"""

from __future__ import annotations

import math

import numpy as np

from brdflab.pages.variance import (
    BIAS_ALPHA,
    LEVEL,
    REF_NOISE_WARN,
    Row,
    Study,
    label,
    time_to_reach,
    untested_for_bias,
)


# -- statements -----------------------------------------------------------------------------------------
def _fmt_ci(ci, scale: float = 1.0, fmt: str = ".3g", why: str = "one run", unit: str = "") -> str:
    """``lo … hi`` (times ``scale``, with ``unit``), or why there is no interval."""
    lo, hi = ci
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return f"no interval ({why})"
    return f"{format(scale * lo, fmt)} … {format(scale * hi, fmt)}{unit}"


def products(study: Study, name: str, spp: int) -> np.ndarray:
    """Per-run relMSE · seconds of one integrator at ``spp`` (the inverse efficiency)."""
    return np.array([c.relmse * c.seconds for c in study.checkpoints if c.integrator == name and c.spp == spp])


def speedup(study: Study, a: str, b: str, spp: int | None = None) -> tuple[float, float, float]:
    """How many times more efficient ``a`` is than ``b`` at ``spp`` (default: the largest): the ratio of
    mean relMSE·seconds of b to a, with its 95 % interval (delta method on log scale)."""
    from brdflab.stats.intervals import log_ratio_interval

    spp = spp or max(study.spp)
    return log_ratio_interval(products(study, b, spp), products(study, a, spp), LEVEL)


def relmse_ratio(study: Study, a: str, b: str, spp: int | None = None) -> tuple[float, float, float]:
    """relMSE of ``b`` over ``a`` at equal spp (default the largest) with its 95 % interval (time-free)."""
    from brdflab.stats.intervals import log_ratio_interval

    spp = spp or max(study.spp)
    get = lambda n: np.array([c.relmse for c in study.checkpoints if c.integrator == n and c.spp == spp])  # noqa: E731
    return log_ratio_interval(get(b), get(a), LEVEL)


def times_to_reach(study: Study, name: str, target: float) -> list[float | None]:
    """Per run: seconds to reach relMSE ≤ ``target`` (None when a run does not)."""
    return [time_to_reach(study.curve(name, k), target) for k in range(study.runs)]


def equal_time(study: Study) -> tuple[float, dict[str, Row]]:
    """The largest mean time budget every integrator reaches, and each one's last row within it."""
    rows = {n: sorted((r for r in study.all_rows if r.integrator == n), key=lambda r: r.spp)
            for n in study.integrators}
    budget = min(rs[-1].seconds for rs in rows.values())
    picks = {}
    for n, rs in rows.items():
        within = [r for r in rs if r.seconds <= budget * 1.0001]
        picks[n] = within[-1] if within else rs[0]
    return budget, picks


def biased(study: Study) -> dict[str, Row]:
    """Integrators with a significant bias (Holm-corrected) and their most significant row."""
    out = {}
    for n in study.integrators:
        sig = [r for r in study.rows if r.integrator == n and r.bias_significant]
        if sig:
            out[n] = min(sig, key=lambda r: r.bias_p)
    return out


def reference_warning(study: Study) -> str | None:
    """A warning when the reference's own noise is a noticeable part of the error at the largest spp."""
    top = [r for r in study.rows if r.spp == max(study.spp)]
    if not top or not np.isfinite(study.reference_noise):
        return None
    best = min(r.relmse for r in top)
    if best > 0 and study.reference_noise > REF_NOISE_WARN * best:
        return (f"The reference's own noise (relMSE ≈ {study.reference_noise:.3g}) is "
                f"{100 * study.reference_noise / best:.0f} % of the smallest error at {max(study.spp)} spp "
                f"({best:.3g}): errors there are overstated; use a reference with more samples.")
    return None


def summary(study: Study) -> list[str]:
    """Automatically written findings; every comparison with its 95 % interval, claims only when significant."""
    top = max(study.spp)
    finals = {r.integrator: r for r in study.rows if r.spp == top}
    lines = []
    best = min(finals.values(), key=lambda r: r.relmse)
    lines.append(f"At {top} spp ({study.runs} runs each) the lowest error is {label(best.integrator)} "
                 f"(relMSE {best.relmse:.3g}, 95 % CI {_fmt_ci(best.relmse_ci)}); " + ", ".join(
                     f"{label(n)} {r.relmse:.3g} ({_fmt_ci(r.relmse_ci)})" for n, r in finals.items()
                     if n != best.integrator) + ".")
    if study.runs >= 2:
        lead = max(finals, key=lambda n: finals[n].efficiency)
        for n in finals:
            if n == lead:
                continue
            ratio, lo, hi = speedup(study, lead, n)
            if lo > 1:
                lines.append(f"{label(lead)} is {ratio:.2g}× faster than {label(n)} (efficiency 1/(relMSE·time) at "
                             f"{top} spp, 95 % CI {lo:.2g}–{hi:.2g}×).")
            else:
                lines.append(f"{label(lead)} and {label(n)} do not differ significantly in efficiency at {top} spp "
                             f"(ratio {ratio:.2g}, 95 % CI {lo:.2g}–{hi:.2g}).")
        ordered = sorted(r.relmse for r in finals.values())
        target = ordered[-2] if len(ordered) >= 2 else ordered[-1]
        for n in finals:
            ts = times_to_reach(study, n, target)
            if all(t is not None for t in ts):
                m, lo, hi = _log_t([t for t in ts if t is not None])
                lines.append(f"{label(n)} reaches relMSE {target:.3g} in {m:.3g} s (95 % CI {_fmt_ci((lo, hi))} s).")
            else:
                reached = sum(t is not None for t in ts)
                lines.append(f"{label(n)} reaches relMSE {target:.3g} in {reached} of {study.runs} runs within "
                             f"{top} spp.")
    flagged = biased(study)
    for n, r in flagged.items():
        lines.append(f"{label(n)} is biased: its image mean differs from the reference by {100 * r.bias:+.2f} % "
                     f"(95 % CI {_fmt_ci(r.bias_ci, 100, '+.2f')} %) at {r.spp} spp, p = {r.bias_p:.2g} "
                     f"(significant after Holm's correction over {len(study.rows)} comparisons, α = {BIAS_ALPHA}).")
    untested = untested_for_bias(study)
    tested = [r for r in study.rows if r.integrator not in untested]
    if not flagged and study.runs >= 2 and tested:
        lines.append(f"No integrator's image mean differs significantly from the reference (Holm over "
                     f"{len(tested)} comparisons, α = {BIAS_ALPHA}).")
    for n in untested:
        lines.append(f"{label(n)} is not tested for bias: the reference is brdflab's own {n} (independent seeds), "
                     "so a bias they share cannot show; give --ref (a reference from another renderer) to test it.")
    warn = reference_warning(study)
    if warn:
        lines.append(warn)
    budget, picks = equal_time(study)
    best_eq = min(picks.values(), key=lambda r: r.relmse)
    line = (f"With an equal budget of {budget:.3g} s, {label(best_eq.integrator)} has the lowest error "
            f"(relMSE {best_eq.relmse:.3g}, 95 % CI {_fmt_ci(best_eq.relmse_ci)} at {best_eq.spp} spp)")
    if study.runs >= 2 and len(picks) > 1:
        from brdflab.stats.intervals import log_ratio_interval

        second = sorted(picks.values(), key=lambda r: r.relmse)[1]
        get = lambda r: np.array([c.relmse for c in study.checkpoints  # noqa: E731
                                  if c.integrator == r.integrator and c.spp == r.spp])
        ratio, lo, hi = log_ratio_interval(get(second), get(best_eq), LEVEL)
        line += (f"; {ratio:.2g}× lower than {label(second.integrator)} (95 % CI {lo:.2g}–{hi:.2g})" if lo > 1
                 else f"; not significantly lower than {label(second.integrator)} (ratio {ratio:.2g}, "
                      f"95 % CI {lo:.2g}–{hi:.2g})")
    lines.append(line + ".")
    return lines


def _log_t(values: list[float]) -> tuple[float, float, float]:
    """Geometric mean of positive values with a t interval on log scale."""
    from brdflab.stats.intervals import t_interval

    logs = np.log(np.asarray(values, dtype=np.float64))
    m, lo, hi = t_interval(logs, LEVEL)
    return math.exp(m), math.exp(lo) if np.isfinite(lo) else math.nan, math.exp(hi) if np.isfinite(hi) else math.nan
