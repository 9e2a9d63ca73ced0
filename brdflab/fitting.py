"""``brdflab fit``: least-squares fit of an analytic model's parameters to a measured (tabulated) BRDF.

The data are the table's nodes (:mod:`brdflab.bsdf.measured`; every 2nd θh, every 3rd θd and every 6th φd
node by default, both directions above the horizon). The residual per node and channel is

    linear:  r = (f_model − f_measured) · cos θ_i cos θ_o
    log:     r = log(1 + f_model cos θ_i cos θ_o) − log(1 + f_measured cos θ_i cos θ_o)

(the cosine weighting puts the error where it carries light; the log compresses the peak so that the lobe's
width, not only its height, is fitted — Ngan et al. 2005, "Experimental analysis of BRDF models", fit
cosine-weighted values under a compressive transform for the same reason). ``scipy.optimize.least_squares``
(trust-region reflective, bounded) minimises Σ r²; the free parameters are the model's floats and colours
(each channel a parameter) with bounds from their names (α ∈ [10⁻³, 1], reflectances and colours ∈ [0, 1],
indices of refraction ∈ [1, 3], anything else ∈ [0, 10·default]). Several starts (α ∈ {0.05, 0.2, 0.5}) guard
against a local minimum; the best is kept.

The page shows the θh × θd slice at φd = 90° of the measurement, of the fitted model and their log ratio.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from brdflab import fitting_data as fd
from brdflab.errors import BrdflabError, clean, first_line

#: Node strides (θh, θd, φd) of the data used by default.
STRIDE = (2, 3, 6)
LOSSES = ("log", "linear")
#: At least this many usable nodes (3 residuals each) per free parameter value: fewer fit anything "perfectly".
NODES_PER_PARAMETER = 10


@dataclass
class FitResult:
    """What ``fit`` found: the parameters, the residual and the fit's cost."""

    model: str
    params: dict
    loss: str
    rms: float
    """Root mean square of the residuals at the optimum."""
    relative_error: float
    """Σ|f_model − f|·cos cos / Σ f·cos cos over the data nodes."""
    nodes: int
    evaluations: int
    starts: list = field(default_factory=list)
    uncertainty: dict = field(default_factory=dict)
    """Standard error of each fitted parameter (a colour: per channel) from the Jacobian at the optimum: the
    sandwich covariance clustered by measured node (:func:`_uncertainty`); None for a parameter at a bound
    (the linear approximation fails there)."""
    correlation: dict = field(default_factory=dict)
    """``labels`` (a colour's channels as ``eta[r]`` …) and ``matrix``: the correlations of the fitted values from
    the same covariance as the standard errors (:mod:`brdflab.fitting_data`: η and k trade off)."""
    notes: list = field(default_factory=list)
    """Sentences about the fit's trust: a poor fit, anisotropy the model misses, strongly correlated values."""
    phi_h: tuple = (0.0,)
    """Half-vector azimuths (degrees) of the nodes (:mod:`brdflab.fitting_data`)."""

    def to_dict(self) -> dict:
        """Plain-dict form (colours as lists)."""
        p = {k: (np.asarray(v).tolist() if isinstance(v, np.ndarray) else v) for k, v in self.params.items()}
        return {"model": self.model, "params": p, "loss": self.loss, "rms": self.rms,
                "relative_error": self.relative_error, "nodes": self.nodes, "evaluations": self.evaluations,
                "starts": self.starts,
                "uncertainty": {k: (np.asarray(v).tolist() if v is not None else None)
                                for k, v in self.uncertainty.items()},
                "correlation": {k: (np.asarray(v).tolist() if isinstance(v, np.ndarray) else v)
                                for k, v in self.correlation.items()},
                "notes": list(self.notes), "phi_h": list(self.phi_h)}

    def summary(self, notes: bool = True) -> str:
        """One line: the parameters and the residual (and the notes, unless ``notes`` is False)."""
        shown = ", ".join(f"{k}={_fmt(v)}" for k, v in self.params.items())
        return (f"fit {self.model}: {shown}; {self.loss} residual rms {self.rms:.4g}, relative error "
                f"{100 * self.relative_error:.2f} % over {self.nodes} nodes ({self.evaluations} evaluations)"
                + "".join(f"; NOTE: {n}" for n in (self.notes if notes else ())))


def _fmt(v) -> str:
    if isinstance(v, np.ndarray | list | tuple):
        return ",".join(f"{x:.4g}" for x in np.ravel(v))
    return f"{v:.4g}" if isinstance(v, float) else str(v)


def data_nodes(table: np.ndarray, stride: tuple[int, int, int] = STRIDE, phi_h: Sequence[float] = (0.0,)):
    """(ω_i, ω_o, f, cos θ_i cos θ_o) at the table nodes used for fitting: both directions above the surface
    and a measurement there (every channel finite and ≥ 0; MERL marks unmeasured nodes negative); at each
    half-vector azimuth of ``phi_h`` (degrees) with the same measured value (:mod:`brdflab.fitting_data`)."""
    f = np.tile(table[::stride[0], ::stride[1], ::stride[2]].reshape(-1, 3), (len(phi_h), 1))
    wi, wo = fd.nodes(stride, phi_h)
    with np.errstate(invalid="ignore"):
        ok = np.all(np.isfinite(f) & (f >= 0), axis=1)
    # the directions' heights do not depend on φ_h: the same nodes are kept at every azimuth
    ok &= (wi[:, 2] > 1e-3) & (wo[:, 2] > 1e-3)
    return wi[ok], wo[ok], f[ok], (wi[ok, 2] * wo[ok, 2])


def _check_stride(stride) -> tuple[int, int, int]:
    try:
        st = tuple(stride)
    except TypeError:
        st = ()
    if len(st) != 3 or not all(isinstance(v, int | np.integer) and not isinstance(v, bool) and 1 <= v <= 180
                               for v in st):
        raise BrdflabError(f"fit: stride must be three whole numbers from 1 to 180 (θh, θd, φd), got "
                           f"{clean(stride, 40)}")
    return tuple(int(v) for v in st)


def _check_table(table: np.ndarray) -> None:
    """Refuse a table with nothing to fit: no finite non-negative value, or no positive one."""
    with np.errstate(invalid="ignore"):
        usable = np.isfinite(table) & (table >= 0)
    if not usable.any():
        raise BrdflabError("fit: the measured table has no usable value (all NaN, infinite or negative)")
    if not (table[usable] > 0).any():
        raise BrdflabError("fit: the measured table is zero wherever it is measured: there is nothing to fit")


def _model_call(model: str, params: dict, fn, bsdf=None):
    """``fn(bsdf)`` for the model at ``params`` (or the given ``bsdf``); a model that raises is the user's
    problem, said in one line."""
    from brdflab.plugins import make_bsdf

    try:
        return fn(make_bsdf(model, params) if bsdf is None else bsdf)
    except BrdflabError:
        raise
    except Exception as exc:  # a plugin's bug: one line naming it, not a traceback
        shown = ", ".join(f"{k}={_fmt(v)}" for k, v in params.items())
        raise BrdflabError(f"fit: model '{clean(model, 40)}' raised {clean(first_line(exc), 120)} "
                           f"(at {clean(shown, 100)})") from None


#: Node strides of the command line's ``--effort`` levels.
EFFORT_STRIDES = {"quick": (4, 6, 12), "normal": STRIDE, "full": (1, 2, 3)}
#: What ``fit(..., output=DIR)`` writes into DIR (:mod:`brdflab.pages.fit_page`).
FIT_FILES = ("fit.html", "fit.json", "fit_slices.png", "fit_polar.png", "fit_albedo.png", "fit_sphere.png")


def fit(measured, model: str = "roughconductor", loss: str = "log", fixed: dict | None = None,
        stride: tuple[int, int, int] | None = None, *, fix: dict | Sequence[str] | None = None,
        free: Sequence[str] | str | None = None, effort: str | None = None, output: str | Path | None = None,
        force: bool = False, plugins: Sequence[str] | str | None = None) -> FitResult:
    """Fit ``model``'s parameters to a measured BRDF.

    Parameters
    ----------
    measured
        A :class:`~brdflab.bsdf.measured.Measured` BSDF, a table (90, 90, 180, 3) or a MERL ``.binary`` path (an
        isotropic measurement); or any other BSDF (e.g. an anisotropic model as synthetic data), evaluated at
        the table's nodes at several half-vector azimuths (:mod:`brdflab.fitting_data`).
    model
        A BSDF type (built-in or registered plugin) with float and colour parameters.
    loss
        ``"log"`` (default) or ``"linear"`` (module docstring).
    fixed, fix
        Parameters held at given values (e.g. ``{"intIOR": 1.5}``, or the command line's ``["intIOR=1.5"]`` as
        ``fix``; a string parameter such as ``distribution=ggx`` too); strings are converted by kind.
    free
        The parameters to fit (names, or ``"alpha_u,alpha_v,eta,k"`` as the command line's ``--free``); by
        default the model's ``fit_parameters`` (roughconductor: ``R0``, ``alpha``) or every float and colour.
    stride, effort
        Use every (θh, θd, φd)-th node of the table (default (2, 3, 6)); or the command line's ``--effort``:
        ``"quick"`` (4, 6, 12), ``"normal"``, ``"full"`` (1, 2, 3).
    output, force
        A folder for ``fit.html``, ``fit.json`` and the slices (``-o``), checked before the work.
    plugins
        ``--plugin`` specs (a model that is a plugin's type).

    Returns
    -------
    FitResult

    Examples
    --------
    >>> import brdflab as bl
    >>> from brdflab.bsdf.measured import Measured, tabulate
    >>> truth = bl.RoughConductor(R0=[0.9, 0.6, 0.5], alpha=0.25)
    >>> res = bl.fit(tabulate(truth), "roughconductor", stride=(4, 6, 12))  # every 4th θh node, …
    >>> round(res.params["alpha"], 3), [round(float(x), 3) for x in res.params["R0"]]
    (0.25, [0.9, 0.6, 0.5])
    >>> gold = bl.RoughConductor(distribution="ggx", alpha_u=0.15, alpha_v=0.3, material="Au")
    >>> res = bl.fit(gold, fixed={"distribution": "ggx", "material": "Au"}, free="alpha_u,alpha_v", stride=(8, 10, 20))
    >>> round(res.params["alpha_u"], 3), round(res.params["alpha_v"], 3)
    (0.15, 0.3)
    """
    from scipy.optimize import least_squares

    from brdflab.bsdf.base import BSDF
    from brdflab.bsdf.measured import Measured, read_merl
    from brdflab.parameters import key_values
    from brdflab.plugins import bsdf_class, bsdf_parameters, parameter_kinds
    from brdflab.workflows import _load_plugins, _specs

    if loss not in LOSSES:
        raise BrdflabError(f"loss must be one of {', '.join(LOSSES)}, got '{clean(loss, 40)}'")
    if effort is not None and effort not in EFFORT_STRIDES:
        raise BrdflabError(f"effort must be one of {', '.join(EFFORT_STRIDES)}, got '{clean(effort, 20)}'")
    if stride is not None and effort is not None:
        raise BrdflabError("fit: give stride or effort, not both")
    stride = _check_stride(stride if stride is not None else EFFORT_STRIDES[effort or "normal"])
    if fix is not None:
        if fixed is not None:
            raise BrdflabError("fit: give fixed or fix, not both")
        fixed = fix if isinstance(fix, dict) else key_values(fix, "fix")
    _load_plugins(plugins)
    bsdf_class(model)  # an unknown model fails before the work
    kinds = parameter_kinds(bsdf_class(model))
    defaults = bsdf_parameters(model)
    fixed = dict(fixed or {})
    unknown = [k for k in fixed if k not in kinds]
    if unknown:
        raise BrdflabError(f"fit: '{model}' has no parameter '{unknown[0]}'; its parameters: {', '.join(kinds)}")
    # A class may name the parameters fitted by default (roughconductor: R0 and alpha, not its optional
    # anisotropy and η/k, which are alternatives to them); ``free`` names others.
    free = fd.free_parameters(model, bsdf_class(model), kinds, fixed, free)
    data_bsdf = measured if isinstance(measured, BSDF) and not isinstance(measured, Measured) else None
    if output is not None:
        from brdflab.outputs import prepare_folder

        inputs = [measured] if isinstance(measured, str | Path) else []
        prepare_folder(Path(output), list(FIT_FILES), [*inputs, *_specs(plugins)], force)  # before the work
    table = None
    if data_bsdf is not None:
        pass
    elif isinstance(measured, str | Path):
        table = read_merl(measured, raw=True)
    elif isinstance(measured, Measured):
        table = measured.table
    else:
        try:
            table = np.asarray(measured, dtype=np.float64)
        except (TypeError, ValueError):
            raise BrdflabError("fit: measured must be a BSDF, a MERL file or a (90, 90, 180, 3) table") \
                from None
    if table is not None:
        if table.shape != (90, 90, 180, 3):
            raise BrdflabError(f"a measured table has shape (90, 90, 180, 3), got {table.shape}")
        _check_table(table)
    anisotropic = data_bsdf is not None or any(k in free or k in fixed for k in fd.ANISOTROPIC)
    phi_h = fd.PHI_H if anisotropic else (0.0,)
    if table is not None:
        wi, wo, f_meas, cc = data_nodes(table, stride, phi_h)
    else:
        wi, wo = fd.nodes(stride, phi_h)
        f_meas = _model_call("the data", {}, lambda _: fd.bsdf_values(data_bsdf, wi, wo), data_bsdf)
        with np.errstate(invalid="ignore"):
            ok = (wi[:, 2] > 1e-3) & (wo[:, 2] > 1e-3) & np.all(np.isfinite(f_meas) & (f_meas >= 0), axis=1)
        if not ok.all():  # keep whole azimuth columns, so that the copies stay aligned node by node
            ok = np.tile(ok.reshape(len(phi_h), -1).all(axis=0), len(phi_h))
        wi, wo, f_meas = wi[ok], wo[ok], f_meas[ok]
        cc = wi[:, 2] * wo[:, 2]
        _check_table(f_meas)
    lo, hi, x0, layout = [], [], [], []
    width_of = {k: 3 if kinds[k] == "color" else 1 for k in free}
    needed = NODES_PER_PARAMETER * sum(width_of.values())
    if len(wi) // len(phi_h) < needed:
        raise BrdflabError(f"fit: {len(wi) // len(phi_h)} usable node(s) with stride {stride}, at least {needed} "
                           f"needed for {sum(width_of.values())} free parameter value(s); use a smaller stride")
    for k in free:
        default = defaults.get(k)
        if default is None:
            default = fd.STARTS.get(k)
        b = fd.bounds(k, kinds[k], 1.0 if default is None else float(np.mean(default)))
        width = width_of[k]
        d = np.broadcast_to(np.asarray(0.5 if default is None else default, float), (width,))
        layout.append((k, width))
        lo += [b[0]] * width
        hi += [b[1]] * width
        x0 += [float(np.clip(v, b[0] + 1e-6, b[1] - 1e-6)) for v in d]
    lo_a, hi_a = np.array(lo), np.array(hi)
    target = np.log1p(f_meas * cc[:, None]) if loss == "log" else f_meas * cc[:, None]
    evaluations = [0]

    def params_of(x):
        out, i = dict(fixed), 0
        for k, width in layout:
            out[k] = np.array(x[i:i + width]) if width == 3 else float(x[i])
            i += width
        return out

    def model_values(x):
        return _model_call(model, params_of(x), lambda b: np.asarray(b.eval(wi, wo), dtype=np.float64))

    def residual(x):
        evaluations[0] += 1
        fm = model_values(x) * cc[:, None]
        fm = np.where(np.isfinite(fm), fm, 1e3)  # steer the search away; the optimum itself is checked below
        r = (np.log1p(np.maximum(fm, 0.0)) if loss == "log" else fm) - target
        with np.errstate(over="ignore"):
            if not np.isfinite(np.dot(r.ravel(), r.ravel())):
                raise BrdflabError(f"fit: the {loss} residual overflowed (Σ r² = inf) at "
                                   f"{clean(', '.join(f'{k}={_fmt(v)}' for k, v in params_of(x).items()), 100)}: "
                                   "the model's values are out of range for this loss"
                                   + ("; try --loss log" if loss == "linear" else ""))
        return r.ravel()

    f0 = model_values(x0)
    _check_values(model, params_of(x0), f0)
    _check_effect(model, layout, x0, lo_a, hi_a, f0, model_values)
    best, tried = None, []
    for x in _starts(x0, layout, free):
        sol = least_squares(residual, np.array(x), bounds=(lo_a, hi_a), method="trf", x_scale="jac",
                            xtol=1e-10, ftol=1e-12, gtol=1e-12, max_nfev=400)
        tried.append({"start": {k: _plain(v) for k, v in params_of(x).items() if k in free},
                      "cost": float(sol.cost)})
        if best is None or sol.cost < best.cost:
            best = sol
    params = params_of(best.x)
    fm = model_values(best.x)
    _check_values(model, params, fm)
    rel = float(np.sum(np.abs(fm - f_meas) * cc[:, None]) / max(np.sum(f_meas * cc[:, None]), 1e-300))
    rms = float(math.sqrt(2 * best.cost / best.fun.size))
    copies = len(phi_h) if table is not None else 1  # an isotropic table's value is copied to every φ_h
    unc, cov = _uncertainty(best, layout, lo_a, hi_a, copies)
    labels, rho = fd.correlations(cov, layout) if cov is not None else ([], None)
    notes = fd.notes(rel, labels, rho, fd.anisotropy(f_meas, cc, len(phi_h)), fd.anisotropy(fm, cc, len(phi_h)))
    result = FitResult(model, params, loss, rms, rel, int(len(wi)), evaluations[0], tried, unc,
                       {"labels": labels, "matrix": rho} if rho is not None else {}, notes, tuple(phi_h))
    if output is not None:
        from brdflab.bsdf.measured import measured_values
        from brdflab.outputs import record_outputs
        from brdflab.pages.fit_page import write_fit_page

        name = (Path(measured).name if isinstance(measured, str | Path) else
                f"{getattr(measured, 'type_name', 'a BSDF')} (data)" if data_bsdf is not None else "the table")
        write_fit_page(Path(output), data_bsdf if data_bsdf is not None else measured_values(table), result,
                       title=f"brdflab fit — {name} as {model}")
        record_outputs(Path(output), list(FIT_FILES))
    return result


def _starts(x0: list, layout: list[tuple[str, int]], free: list) -> list:
    """The starting points: the defaults, and α (every roughness among alpha, alpha_u, alpha_v) at 0.05, 0.2, 0.5
    against a local minimum."""
    where = []
    i = 0
    for k, width in layout:
        if k in ("alpha", *fd.ANISOTROPIC):
            where.append(i)
        i += width
    starts = [list(x0)]
    for a in (0.05, 0.2, 0.5) if where else ():
        x = list(x0)
        for i in where:
            x[i] = a
        starts.append(x)
    return starts


def _check_effect(model: str, layout, x0, lo, hi, f0: np.ndarray, model_values) -> None:
    """A free parameter must change the model: one that does not (roughconductor's R0 with η given, α with both
    α_u and α_v) has no standard error and would only slow the search. Refused, by name."""
    i = 0
    for k, width in layout:
        x = np.array(x0, dtype=float)
        step = 0.05 * (hi[i:i + width] - lo[i:i + width])
        x[i:i + width] = np.where(x[i:i + width] + step <= hi[i:i + width], x[i:i + width] + step,
                                  x[i:i + width] - step)
        if np.array_equal(model_values(x), f0):
            raise BrdflabError(f"fit: the free parameter '{clean(k, 40)}' does not change '{clean(model, 40)}' "
                               "with the other parameters given (it is unused); fix it or leave it out of free")
        i += width


def _uncertainty(sol, layout: list[tuple[str, int]], lo: np.ndarray, hi: np.ndarray, copies: int = 1) -> tuple:
    """Standard errors of the free parameters at the optimum ``sol`` (see :attr:`FitResult.uncertainty`) and
    their covariance (None without residual degrees of freedom).

    The covariance is the sandwich (JᵀJ)⁻¹ (Σ_c g_c g_cᵀ) (JᵀJ)⁻¹, g_c = Σ_{rows of node c} J_row r_row, clustered
    by measured node (its three channels, and its ``copies`` at several φ_h, share one measurement), times
    m/(m − n): robust to residuals whose size varies from node to node (the log loss's do: r ≈ σ·f cos cos/(1 +
    f cos cos)) and to a model that does not fit exactly. The plain s²·(JᵀJ)⁻¹ covered 89 % of the values where
    95 % were due (benchmarks/fit_coverage.py, docs/benchmarks.md)."""
    m, n = sol.jac.shape
    out: dict = {}
    if m <= n:
        return {k: None for k, _ in layout}, None
    jac = np.asarray(sol.jac, dtype=np.float64)
    bread = np.linalg.pinv(jac.T @ jac)
    g = (jac * sol.fun[:, None]).reshape(copies, -1, 3, n).sum(axis=(0, 2))  # one row per measured node
    cov = (m / (m - n)) * bread @ (g.T @ g) @ bread
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    span = hi - lo
    at_bound = (np.abs(sol.x - lo) < 1e-6 * span) | (np.abs(hi - sol.x) < 1e-6 * span)
    i = 0
    for k, width in layout:
        block = slice(i, i + width)
        out[k] = None if at_bound[block].any() else (se[block].copy() if width == 3 else float(se[i]))
        i += width
    return out, cov


def _plain(v):
    return np.asarray(v).tolist() if isinstance(v, np.ndarray) else float(v) if isinstance(v, float) else v


def _check_values(model: str, params: dict, fm: np.ndarray) -> None:
    """A model must give finite, non-negative f at every data node: otherwise no residual means anything."""
    with np.errstate(invalid="ignore"):
        bad = ~np.isfinite(fm) | (fm < 0)
    if bad.any():
        shown = ", ".join(f"{k}={_fmt(v)}" for k, v in params.items())
        kind = "NaN or infinite" if (~np.isfinite(fm)).any() else "negative"
        raise BrdflabError(f"fit: model '{clean(model, 40)}' returned {kind} f at {int(bad.any(axis=1).sum())} of "
                           f"{len(fm)} data nodes (at {clean(shown, 100)}); a BSDF's eval must be finite and ≥ 0")
