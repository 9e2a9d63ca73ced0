"""What ``fit`` (:mod:`brdflab.fitting`) fits against and how it reads the result: the data nodes (a measured
table's, or an analytic BSDF's at several half-vector azimuths), the free parameters with their ranges and
starts, and the diagnostics (correlated parameters, a poor fit, anisotropy the model misses).

**Azimuths of the half vector.** A MERL table is isotropic: it has no φ_h axis, and its nodes are placed at
φ_h = 0. An anisotropic model (``alpha_u``/``alpha_v`` free or given) is compared with it at φ_h ∈ {0°, 30°, 60°,
90°} (:data:`PHI_H`: D(ω_h) and G1 of an anisotropic α are symmetric under x → −x and y → −y, so a quarter
turn covers every azimuth), each φ_h against the same measured value; the standard errors then divide the
information by the 4 copies (the copies share one measurement's noise). Data given as a BSDF (an analytic or
anisotropic model, e.g. synthetic data) are evaluated at every φ_h of :data:`PHI_H`.

**η and k.** The exact conductor Fresnel term of (η, k) depends on θ_d only, and its curve over θ_d constrains
η and k jointly much better than each: they trade off (a larger k with a larger η keeps the reflectance at
normal incidence). ``fit`` fits η and k per channel within bounds (η ∈ [0.02, 5], k ∈ [0, 10], which hold the
visible-range indices of the common metals) and reports the correlation of every pair of fitted values; a pair
with |ρ| > :data:`STRONG_CORRELATION` is named in the result's notes (the data then fix a combination of the
two, e.g. the normal-incidence reflectance, better than either).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from brdflab.errors import BrdflabError, clean

#: Half-vector azimuths (degrees) of the nodes of an anisotropic fit or of data given as a BSDF.
PHI_H = (0.0, 30.0, 60.0, 90.0)
#: Parameters whose presence makes a model anisotropic (the nodes then span :data:`PHI_H`).
ANISOTROPIC = ("alpha_u", "alpha_v")
#: Start values of parameters that have no default (e.g. roughconductor's η and k: a typical metal).
STARTS = {"eta": 0.5, "k": 3.0}
#: |ρ| above which two fitted values are reported as poorly separated.
STRONG_CORRELATION = 0.95
#: Relative error above which a fit is called poor in its notes.
POOR_FIT = 0.15
#: Anisotropy of the data the model misses (fraction of the cosine-weighted light) above which a note says so.
MISSED_ANISOTROPY = 0.05


def bounds(name: str, kind: str, default) -> tuple[float, float]:
    """The search range of a parameter, from its name and kind."""
    low = name.lower()
    if low in ("alpha", "alpha_u", "alpha_v"):
        return 1e-3, 1.0
    if low == "eta" and kind == "color":  # a conductor's real index (roughconductor)
        return 0.02, 5.0
    if low == "k" and kind == "color":  # a conductor's extinction coefficient
        return 0.0, 10.0
    if "ior" in low or low in ("eta",):
        return 1.0, 3.0
    if kind == "color" or low in ("r0", "kd", "ks", "albedo", "reflectance"):
        return 0.0, 1.0
    d = abs(float(default)) if default is not None else 1.0
    return 0.0, max(1.0, 10.0 * d)


def free_parameters(model: str, cls: type, kinds: dict, fixed: dict, free: Sequence[str] | str | None) -> list:
    """The parameters to fit: ``free`` (names, or one comma-separated text) checked against the model, or by
    default the class's ``fit_parameters`` (else every float and colour) less the fixed ones."""
    fittable = [k for k, kind in kinds.items() if kind in ("float", "color")]
    if free is None:
        default = getattr(cls, "fit_parameters", None) or tuple(kinds)
        out = [k for k in fittable if k not in fixed and k in default]
        if not out:
            raise BrdflabError(f"fit: '{model}' has no float or colour parameter left to fit")
        return out
    names = [s.strip() for s in ([free] if isinstance(free, str) else list(free)) for s in str(s).split(",")]
    names = [s for s in names if s]
    if not names:
        raise BrdflabError("fit: free names no parameter")
    for k in names:
        if k not in kinds:
            raise BrdflabError(f"fit: '{clean(model, 40)}' has no parameter '{clean(k, 40)}'; its parameters: "
                               f"{', '.join(kinds)}")
        if k not in fittable:
            raise BrdflabError(f"fit: '{clean(k, 40)}' is a {kinds[k]} parameter; only float and colour "
                               f"parameters can be fitted (give it with fix)")
        if k in fixed:
            raise BrdflabError(f"fit: '{clean(k, 40)}' is both fixed and free")
    return list(dict.fromkeys(names))


def node_angles_at(stride: tuple[int, int, int]):
    """(θh, θd, φd) grids of the table nodes used with ``stride`` (radians, broadcast together)."""
    from brdflab.bsdf.measured import node_angles

    th, td, pd = node_angles()
    return np.meshgrid(th[::stride[0]], td[::stride[1]], pd[::stride[2]], indexing="ij")


def nodes(stride: tuple[int, int, int], phi_h: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """(ω_i, ω_o), each (len(phi_h) · n, 3): the strided table nodes at each half-vector azimuth (degrees)."""
    from brdflab.viz import coords

    th, td, pd = node_angles_at(stride)
    pairs = [coords.half_diff_to_io(th, np.radians(p), td, pd) for p in phi_h]
    return np.concatenate([p[0] for p in pairs]), np.concatenate([p[1] for p in pairs])


def bsdf_values(bsdf, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """f of data given as a BSDF at the nodes (N, 3), 0 where a direction is below the surface."""
    f = np.zeros((len(wi), 3))
    ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    f[ok] = np.asarray(bsdf.eval(np.ascontiguousarray(wi[ok]), np.ascontiguousarray(wo[ok])), dtype=np.float64)
    return f


def correlations(cov: np.ndarray, layout: list[tuple[str, int]]) -> tuple[list[str], np.ndarray]:
    """Labels of the fitted values (``eta[g]`` for a colour's channel) and their correlation matrix."""
    labels = [k if width == 1 else f"{k}[{c}]" for k, width in layout for c in ("rgb" if width == 3 else "-")]
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        rho = cov / np.outer(sd, sd)
    return labels, np.where(np.isfinite(rho), np.clip(rho, -1.0, 1.0), 0.0)


def strong_pairs(labels: list[str], rho: np.ndarray, limit: float = STRONG_CORRELATION) -> list[tuple]:
    """(a, b, ρ) of every pair of fitted values with |ρ| > ``limit``, strongest first."""
    n = len(labels)
    pairs = [(labels[i], labels[j], float(rho[i, j])) for i in range(n) for j in range(i + 1, n)
             if abs(rho[i, j]) > limit]
    return sorted(pairs, key=lambda p: -abs(p[2]))


def anisotropy(f: np.ndarray, cc: np.ndarray, copies: int) -> float:
    """How much ``f`` changes with φ_h: Σ |f − mean over φ_h| cos cos / Σ f cos cos over the nodes, ``f`` (and
    ``cc``) stacked as :func:`nodes` makes them (``copies`` azimuths). 0 for an isotropic BSDF."""
    if copies < 2:
        return 0.0
    w = f * cc[:, None]
    s = w.reshape(copies, -1, 3)
    return float(np.abs(s - s.mean(axis=0)).sum() / max(w.sum(), 1e-300))


def notes(rel: float, labels: list[str], rho: np.ndarray | None, data_aniso: float, model_aniso: float) -> list:
    """Sentences about the fit's trustworthiness: a poor fit, anisotropy the model misses, correlated values."""
    out = []
    if rel > POOR_FIT:
        out.append(f"poor fit: the model misses {100 * rel:.1f} % of the data's cosine-weighted f (above "
                   f"{100 * POOR_FIT:g} %): its parameters are the closest this model gets, not the material's")
    if data_aniso - model_aniso > MISSED_ANISOTROPY:
        out.append(f"the data change with the half vector's azimuth φ_h by {100 * data_aniso:.1f} %, the fitted "
                   f"model by {100 * model_aniso:.1f} %: the data are anisotropic (fit alpha_u, alpha_v)")
    if rho is not None:
        for a, b, r in strong_pairs(labels, rho):
            out.append(f"{a} and {b} are strongly correlated (ρ = {r:+.3f}): the data fix a combination of "
                       "them better than either")
    return out


def noisy(bsdf, sigma: float = 0.05, seed: int = 0):
    """``bsdf`` as synthetic measured data: every ``eval`` multiplies f by independent log-normal noise
    (σ = ``sigma`` of log f, like a gonioreflectometer's relative error), drawn from its own stream ``seed``.

    Examples
    --------
    >>> import numpy as np
    >>> import brdflab as bl
    >>> data = noisy(bl.RoughConductor(alpha=0.2), 0.05, seed=1)
    >>> wi = np.array([[0.0, 0.0, 1.0]])
    >>> f = data.eval(wi, wi)
    >>> bool(0.8 < f[0, 0] / bl.RoughConductor(alpha=0.2).eval(wi, wi)[0, 0] < 1.25)
    True
    """
    from brdflab.bsdf.base import BSDF

    class Noisy(BSDF):
        type_name = f"noisy {getattr(bsdf, 'type_name', 'bsdf')}"

        def __init__(self) -> None:
            self.rng = np.random.default_rng(seed)

        def eval(self, wi, wo, uv=None):
            f = np.asarray(bsdf.eval(wi, wo, uv), dtype=np.float64)
            return f * self.rng.lognormal(0.0, sigma, f.shape)

        def pdf(self, wi, wo, uv=None):
            return bsdf.pdf(wi, wo, uv)

        def sample(self, wi, u, uv=None):
            s = bsdf.sample(wi, u, uv)
            ok = (s.pdf > 0)[:, None]
            w = self.eval(wi, s.wo, uv) * s.wo[:, 2:] / np.where(ok, s.pdf[:, None], 1.0)
            return s._replace(weight=np.where(ok, w, 0.0))

    return Noisy()
