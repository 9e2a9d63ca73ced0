"""One wrapper for every check: :class:`CheckedBSDF` validates what a (user's) BSDF returns.

A plugin may raise, return arrays of the wrong shape, NaN or infinity, negative values or densities, or
non-unit directions. Each call through the proxy checks the contract of :mod:`brdflab.bsdf.base`:

=============  ==========================================================================================
method         required of the result
=============  ==========================================================================================
``eval``       shape (N, 3), finite, ≥ 0
``pdf``        shape (N,), finite, ≥ 0
``sample``     a :class:`~brdflab.bsdf.base.BSDFSample` (or 3-tuple): ``wo`` (N, 3) finite, unit length
               (|‖ω_o‖ − 1| ≤ 10⁻⁶) where pdf > 0; ``weight`` (N, 3) finite, ≥ 0; ``pdf`` (N,) finite, ≥ 0;
               ``delta`` None or (N,) booleans
=============  ==========================================================================================

A violation raises :class:`PluginFault`, which names the method, the BSDF's parameters and the first
offending (ω_i, ω_o) (or (ω_i, u) for ``sample``). The checks catch it and return a failed result whose
``message`` is that text — a verdict, not a traceback.
"""

from __future__ import annotations

import numpy as np

from brdflab.bsdf.base import BSDFSample


class PluginFault(Exception):
    """A BSDF broke its contract (see module docstring); ``str(fault)`` is the one-line verdict."""

    def __init__(self, method: str, name: str, params: dict, what: str, wi=None, other=None,
                 other_name: str = "wo") -> None:
        self.method, self.name, self.params, self.what = method, name, dict(params), what
        self.wi = None if wi is None else np.asarray(wi, dtype=float)
        self.other = None if other is None else np.asarray(other, dtype=float)
        where = ""
        if self.wi is not None:
            where = f" at wi={_vec(self.wi)}"
            if self.other is not None:
                where += f", {other_name}={_vec(self.other)}"
        super().__init__(f"{name}.{method}({format_params(params)}): {what}{where}")


def _vec(v: np.ndarray) -> str:
    return "(" + ", ".join(f"{x:.6g}" for x in np.ravel(v)[:3]) + ")"


def format_params(params: dict) -> str:
    """``k=v`` pairs, short (long values truncated), for messages."""
    out = []
    for k, v in params.items():
        if v is None:
            continue
        s = f"{v:g}" if isinstance(v, float) else str(v)
        out.append(f"{k}={s if len(s) <= 24 else s[:21] + '...'}")
    return ", ".join(out)


def describe(bsdf) -> str:
    """A BSDF's display name: the ``type_name`` its class declares, else the class name."""
    inner = getattr(bsdf, "inner", bsdf)
    return vars(type(inner)).get("type_name", "") or type(inner).__name__


class CheckedBSDF:
    """Proxy of a BSDF whose ``eval``/``pdf``/``sample`` results are validated on every call.

    Parameters
    ----------
    bsdf
        Any object with the :class:`brdflab.BSDF` methods.
    name
        Name used in messages (default: the BSDF's ``type_name`` or class name).
    params
        Its parameters, echoed in messages.

    Examples
    --------
    >>> import numpy as np
    >>> from brdflab.bsdf.diffuse import Diffuse
    >>> from brdflab.judges.core.guard import CheckedBSDF, PluginFault
    >>> class Broken(Diffuse):
    ...     def pdf(self, wi, wo, uv=None):
    ...         return -super().pdf(wi, wo, uv)
    >>> b = CheckedBSDF(Broken(0.5), params={"albedo": 0.5})
    >>> try:
    ...     b.pdf(np.array([[0.0, 0.0, 1.0]]), np.array([[0.0, 0.0, 1.0]]))
    ... except PluginFault as fault:
    ...     print(fault)
    Broken.pdf(albedo=0.5): negative value -0.31831 at wi=(0, 0, 1), wo=(0, 0, 1)
    """

    def __init__(self, bsdf, name: str | None = None, params: dict | None = None) -> None:
        self.inner = bsdf.inner if isinstance(bsdf, CheckedBSDF) else bsdf
        self.name = name or describe(self.inner)
        self.params = dict(params or {})
        #: Reciprocal unless the class says ``reciprocal = False``.
        self.reciprocal = bool(getattr(self.inner, "reciprocal", True))

    def __getattr__(self, item):
        # Only the wrapped BSDF's own attributes: special names (pickle's __setstate__, copy's __deepcopy__ …)
        # and 'inner' itself (absent while an unpickled proxy is being rebuilt) must not recurse into it.
        if item == "inner" or (item.startswith("__") and item.endswith("__")):
            raise AttributeError(item)
        return getattr(self.inner, item)

    def fault(self, method: str, what: str, wi=None, other=None, other_name: str = "wo") -> PluginFault:
        """A :class:`PluginFault` about this BSDF."""
        return PluginFault(method, self.name, self.params, what, wi, other, other_name)

    def _call(self, method: str, *args):
        try:
            with np.errstate(all="ignore"):
                return getattr(self.inner, method)(*args)
        except PluginFault:
            raise
        except (Exception, SystemExit) as exc:  # a plugin's own bug (even sys.exit()): reported as a verdict
            msg = f"{type(exc).__name__}: {exc}"
            msg = msg if len(msg) <= 160 else msg[:157] + "..."
            wi = args[0][0] if len(args) and len(args[0]) else None
            other = args[1][0] if len(args) > 1 and len(args[1]) else None
            raise self.fault(method, f"raised {msg}", wi, other, "u" if method == "sample" else "wo") from None

    def _array(self, method, value, shape, wi, other, what="", nonnegative=True, other_name="wo"):
        try:
            raw = np.asarray(value)
            if raw.dtype.kind not in "biuf":  # complex, strings, objects: never silently converted
                raise TypeError
            a = raw.astype(np.float64)
        except (TypeError, ValueError):
            kind = f" of {value.dtype}" if hasattr(value, "dtype") else ""
            raise self.fault(method, f"returned {type(value).__name__}{kind}{what}, expected an array of real numbers "
                             f"of shape {shape}") from None
        if a.shape != shape:
            first = (wi[0], other[0], other_name) if len(wi) and len(other) else ()
            raise self.fault(method, f"returned shape {a.shape}{what}, expected {shape}", *first)
        rows = a.reshape(len(a), -1) if a.ndim else a.reshape(1, 1)
        bad = ~np.isfinite(rows).all(axis=1)
        if bad.any():
            i = int(np.argmax(bad))
            raise self.fault(method, f"non-finite value {_vec(rows[i])}{what}", wi[i], other[i], other_name)
        if nonnegative:
            neg = (rows < 0).any(axis=1)
            if neg.any():
                i = int(np.argmax(neg))
                v = rows[i][rows[i] < 0][0]
                raise self.fault(method, f"negative value {v:.6g}{what}", wi[i], other[i], other_name)
        return a

    def eval(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None = None) -> np.ndarray:
        """f(wi, wo), checked: (N, 3), finite, ≥ 0."""
        return self._array("eval", self._call("eval", wi, wo, uv), (len(wi), 3), wi, wo)

    def pdf(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None = None) -> np.ndarray:
        """Solid-angle density (N,), checked: finite, ≥ 0."""
        return self._array("pdf", self._call("pdf", wi, wo, uv), (len(wi),), wi, wo)

    def eval_pdf(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None = None):
        """(:meth:`eval`, :meth:`pdf`) through the checked calls."""
        return self.eval(wi, wo, uv), self.pdf(wi, wo, uv)

    def sample(self, wi: np.ndarray, u: np.ndarray, uv: np.ndarray | None = None) -> BSDFSample:
        """Checked sample: wo (N, 3) unit where pdf > 0, weight (N, 3) ≥ 0, pdf (N,) ≥ 0, all finite."""
        r = self._call("sample", wi, u, uv)
        try:
            wo, weight, pdf, *rest = r
            if len(rest) > 1:
                raise ValueError
        except (TypeError, ValueError):
            raise self.fault("sample", f"returned {type(r).__name__}, expected BSDFSample(wo, weight, pdf[, delta])"
                             ) from None
        n = len(wi)
        delta = rest[0] if rest else None
        if delta is not None:
            delta = np.asarray(delta)
            if delta.shape != (n,) or delta.dtype.kind not in "bui":
                raise self.fault("sample", f"returned delta of shape {delta.shape} and type {delta.dtype}, expected "
                                 f"None or ({n},) booleans")
            delta = delta.astype(bool)
        pdf = self._array("sample", pdf, (n,), wi, u, " in pdf", other_name="u")
        wo = self._array("sample", wo, (n, 3), wi, u, " in wo", nonnegative=False, other_name="u")
        weight = self._array("sample", weight, (n, 3), wi, u, " in weight", other_name="u")
        norm_err = np.abs(np.sqrt((wo * wo).sum(axis=1)) - 1.0)
        off = (pdf > 0) & (norm_err > 1e-6)
        if off.any():
            i = int(np.argmax(off))
            raise self.fault("sample", f"wo={_vec(wo[i])} is not a unit vector (|wo| − 1 = {norm_err[i]:.2g})",
                             wi[i], u[i], "u")
        return BSDFSample(wo, weight, pdf, delta)


def checked(bsdf, name: str | None = None, params: dict | None = None) -> CheckedBSDF:
    """``bsdf`` behind a :class:`CheckedBSDF` (an existing proxy is re-wrapped with the new name/params)."""
    if isinstance(bsdf, CheckedBSDF) and name is None and params is None:
        return bsdf
    return CheckedBSDF(bsdf, name, params if params is not None else getattr(bsdf, "params", None))


def bsdf_params(bsdf) -> dict:
    """Best-effort scalar parameters of a BSDF for messages: public float/int/str attributes and constants."""
    inner = bsdf.inner if isinstance(bsdf, CheckedBSDF) else bsdf
    out = {}
    for k, v in vars(inner).items():
        if k.startswith("_"):
            continue
        if isinstance(v, bool | int | float | str):
            out[k] = v
        elif getattr(v, "constant", False) and hasattr(v, "value"):
            val = np.asarray(v.value, dtype=float).ravel()
            out[k] = float(val[0]) if np.all(val == val[0]) else ",".join(f"{x:g}" for x in val)
    return out


class SceneCheckedBSDF(CheckedBSDF):
    """A user's BSDF in a scene: the same checks, but a broken contract is a located :class:`SceneError`
    (``scene.xml:12: bsdf "phong": phong.eval(exponent=20): non-finite value … at wi=…, wo=…``), which the
    renderer's workers pass back and the command line prints as one line (exit status 2)."""

    def __init__(self, bsdf, file: str | None = None, line: int | None = None) -> None:
        super().__init__(bsdf, params=bsdf_params(bsdf))
        self.file, self.line = file, line

    def fault(self, method: str, what: str, wi=None, other=None, other_name: str = "wo"):
        from brdflab.errors import SceneError

        text = str(PluginFault(method, self.name, self.params, what, wi, other, other_name))
        return SceneError(f'bsdf "{self.name}": {text}', self.file, self.line)
