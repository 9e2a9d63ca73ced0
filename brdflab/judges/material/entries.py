"""What the validation battery runs on: the built-in BSDFs and lobe variants, the warps, the negative controls (the
conductor pdf without its Jacobian; the GGX visible-normal pdf without G1(ω_i); α_u/α_v swapped in a sampler), and
:class:`BSDFEntry` — how to build any BSDF (a name, an instance, a class, a plugin, a factory) with its sweep —
resolved by :func:`resolve_bsdfs`. The battery itself is :mod:`brdflab.judges.material.battery`.
"""

from __future__ import annotations

import inspect
import itertools
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from brdflab.bsdf import microfacet as mf
from brdflab.bsdf.dielectric import Dielectric
from brdflab.bsdf.diffuse import Diffuse
from brdflab.bsdf.microfacet import beckmann_d, half_vector
from brdflab.bsdf.mirror import Mirror
from brdflab.bsdf.roughconductor import RoughConductor, alpha_values
from brdflab.bsdf.roughdielectric import RoughDielectric
from brdflab.bsdf.roughsubstrate import RoughSubstrate
from brdflab.judges.core.guard import describe
from brdflab.math import warps


class NoJacobianConductor(RoughConductor):
    """A deliberately wrong rough conductor: its pdf omits the 1/(4 |ω_o·ω_h|) Jacobian."""

    def pdf(self, wi, wo, uv=None):
        """D(ω_h) cos θ_h — the density of ω_h, wrongly used as the density of ω_o."""
        a = alpha_values(self.alpha, uv, len(wi))
        wh, ok = half_vector(wi, wo)
        return np.where(ok & (wi[:, 2] > 0), beckmann_d(wh[:, 2], a) * np.maximum(wh[:, 2], 0.0), 0.0)


class VndfWithoutG1Conductor(RoughConductor):
    """A deliberately wrong GGX conductor with visible-normal sampling: its pdf omits G1(ω_i), i.e. uses
    max(0, ω_i·ω_h) D(ω_h)/cos θ_i · 1/(4 |ω_o·ω_h|), which does not integrate to 1."""

    def __init__(self, R0=0.5, alpha=0.3, **kw):  # noqa: N803
        super().__init__(R0, alpha, **{"distribution": "ggx", "sample_visible": True, **kw})

    def _terms(self, wi, wo, uv, need_f, need_pdf):
        f, pdf = super()._terms(wi, wo, uv, need_f, need_pdf)
        if need_pdf:
            pdf = pdf * (1.0 + mf.smith_lambda(self.distribution, wi, *self.alphas(uv, len(wi))))
        return f, pdf


class SwappedAlphaSampler:
    """Mix-in of a deliberately wrong anisotropic microfacet material: its sampler swaps α_u and α_v (eval and
    pdf do not)."""

    def sample_normals(self, wi, u, uv=None):
        """The normals of the sampler with α_u and α_v exchanged."""
        ax, ay = self.alphas(uv, len(wi))
        return self.normals_for(wi, u, ay, ax)


class SwappedAlphaConductor(SwappedAlphaSampler, RoughConductor):
    """A deliberately wrong anisotropic conductor: its sampler swaps α_u and α_v (eval and pdf do not)."""

    def __init__(self, R0=0.5, alpha=0.3, **kw):  # noqa: N803
        super().__init__(R0, alpha, **{"distribution": "ggx", "alpha_u": 0.1, "alpha_v": 0.4, **kw})


#: The controls of the GGX/anisotropic conductor: (name, BSDF) that the chi-square must reject.
CONDUCTOR_CONTROLS: tuple[tuple[str, Callable], ...] = (
    ("ggx conductor, visible-normal pdf without G1(ω_i)", lambda: VndfWithoutG1Conductor(0.5, 0.3)),
    ("anisotropic ggx conductor, α_u/α_v swapped in the sampler", lambda: SwappedAlphaConductor(0.5)),
    ("anisotropic beckmann conductor, α_u/α_v swapped in the sampler",
     lambda: SwappedAlphaConductor(0.5, distribution="beckmann", sample_visible=False)),
)


#: BSDF factories by name: (alpha, **params) → BSDF. Lobe variants of the substrate are separate entries.
BSDFS: dict[str, Callable] = {
    "diffuse": lambda alpha, **kw: Diffuse(kw.get("albedo", 0.5)),
    "roughconductor": lambda alpha, **kw: RoughConductor(kw.get("R0", 0.5), alpha),
    "roughsubstrate": lambda alpha, **kw: RoughSubstrate(kw.get("kd", 0.5), alpha, kw.get("intIOR", 1.5046),
                                                         kw.get("extIOR", 1.000277)),
    "roughsubstrate/specular": lambda alpha, **kw: RoughSubstrate(kw.get("kd", 0.5), alpha, kw.get("intIOR", 1.5046),
                                                                  kw.get("extIOR", 1.000277), lobe="specular"),
    "roughsubstrate/diffuse": lambda alpha, **kw: RoughSubstrate(kw.get("kd", 0.5), alpha, kw.get("intIOR", 1.5046),
                                                                 kw.get("extIOR", 1.000277), lobe="diffuse"),
    "mirror": lambda alpha, **kw: Mirror(),
    "dielectric": lambda alpha, **kw: Dielectric(kw.get("intIOR", 1.5046), kw.get("extIOR", 1.000277)),
    "roughdielectric": lambda alpha, **kw: RoughDielectric(alpha, kw.get("intIOR", 1.5046), kw.get("extIOR", 1.000277),
                                                           kw.get("ka", 1.0)),
}


#: Direction warps: name → (sample, pdf, takes alpha).
WARPS: dict[str, tuple[Callable, Callable, bool]] = {
    "uniform_sphere": (warps.square_to_uniform_sphere, warps.square_to_uniform_sphere_pdf, False),
    "uniform_hemisphere": (warps.square_to_uniform_hemisphere, warps.square_to_uniform_hemisphere_pdf, False),
    "cosine_hemisphere": (warps.square_to_cosine_hemisphere, warps.square_to_cosine_hemisphere_pdf, False),
    "beckmann": (warps.square_to_beckmann, warps.square_to_beckmann_pdf, True),
}


#: Warps to 2-D points: name → (sample, pdf, bounds).
POINT_WARPS = {
    "uniform_triangle": (warps.square_to_uniform_triangle, warps.square_to_uniform_triangle_pdf, (0, 1, 0, 1)),
    "uniform_disk": (warps.square_to_uniform_disk, warps.square_to_uniform_disk_pdf, (-1, 1, -1, 1)),
}


def make_named_bsdf(name: str, alpha: float | None, params: dict | None = None):
    """The BSDF ``name`` of the battery: a registry type (built-in or plugin, :func:`brdflab.plugins.make_bsdf`),
    or ``type/lobe`` for one lobe of a built-in mixture (``roughsubstrate/specular``); ``alpha`` only for a
    BSDF with an ``alpha`` parameter."""
    from brdflab.plugins import make_bsdf

    base, _, lobe = name.partition("/")
    bsdf = make_bsdf(base, params, alpha=alpha)
    if lobe:
        bsdf.lobe = lobe
    return bsdf


def has_alpha(name: str) -> bool:
    """True when BSDF ``name`` (or its base type) has an ``alpha`` parameter."""
    from brdflab.plugins import bsdf_class, parameter_kinds

    return "alpha" in parameter_kinds(bsdf_class(name.partition("/")[0]))


@dataclass
class BSDFEntry:
    """A BSDF the battery can run: how to build it and what to sweep.

    Attributes
    ----------
    name
        Display name (``type_name`` for plugins; ``roughsubstrate/specular`` for a lobe variant).
    factory
        ``factory(alpha, params) -> BSDF``; ``alpha`` is None for a BSDF without roughness.
    takes_alpha
        Sweep α (the battery's ``alphas``) as well as θ.
    sweep
        Extra parameter grid, e.g. ``{"exponent": [5, 20, 100]}`` (from the class attribute ``sweep``).
    checks
        Run consistency and furnace on this entry (False for lobe variants: chi-square only).
    furnace_params
        Parameters overriding ``params`` for the white furnace (built-ins: R0 = 1, k_d = 1, albedo = 1).
    """

    name: str
    factory: Callable
    takes_alpha: bool = False
    sweep: dict = field(default_factory=dict)
    checks: bool = True
    furnace_params: dict = field(default_factory=dict)
    #: Built from a name by the registry (can be rebuilt on cluster workers).
    by_name: bool = False

    def make(self, alpha: float | None, params: dict | None = None):
        """Build the BSDF (``alpha`` ignored without roughness)."""
        return self.factory(alpha if self.takes_alpha else None, dict(params or {}))

    def flag(self, name: str) -> bool:
        """A class attribute of the contract (``all_delta``, ``two_sided``, ``has_transmission``) of the BSDF
        this entry builds (False when a prototype cannot be built without parameters)."""
        if not hasattr(self, "_flags"):
            try:
                proto = self.make(0.1, {})
            except Exception:  # noqa: BLE001 - the tests themselves report a constructor's error
                proto = None
            self._flags = {k: bool(getattr(proto, k, False)) for k in ("all_delta", "two_sided", "has_transmission")}
        return self._flags[name]

    def angles(self, thetas) -> tuple[float, ...]:
        """``thetas`` and, for a two-sided BSDF, the same angles from inside (180° − θ for θ > 0)."""
        thetas = tuple(thetas)
        return thetas + tuple(180.0 - t for t in thetas if t > 0) if self.flag("two_sided") else thetas

    def grid(self, params: dict | None = None) -> list[dict]:
        """Parameter points of the sweep (the product of :attr:`sweep`, minus explicitly given keys)."""
        axes = {k: list(v) for k, v in self.sweep.items() if k not in (params or {})}
        if not axes:
            return [{}]
        return [dict(zip(axes, vals, strict=True)) for vals in itertools.product(*axes.values())]


#: The α of the battery's furnace (albedo) checks and of ``validate``'s path-traced white furnace.
FURNACE_ALPHAS = (0.05, 0.1, 0.3, 0.5, 1.0)


def furnace_name(entry: BSDFEntry, point: dict) -> str:
    """``roughconductor R0=1``: an entry's name with its sweep point and furnace parameters (the furnace's label)."""
    return " ".join([entry.name, *(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}"
                                   for k, v in {**point, **entry.furnace_params}.items())])


#: Parameters that a furnace parameter replaces: R0 = 1 (Schlick) is the alternative of a conductor's η, k or material.
_FURNACE_REPLACES = {"R0": ("eta", "k", "material")}


def furnace_parameters(entry: BSDFEntry, params: dict, point: dict) -> dict:
    """The furnace's parameters: the user's, the sweep point, then the entry's furnace parameters (the most
    reflective setting: R0 = 1, albedo 1), which drop the user's alternatives to them (R0 = 1 replaces a
    conductor's η, k or material: F = 1 bounds every Fresnel term, so the furnace's energy test stays the
    strictest)."""
    prm = {**params, **point}
    for key in entry.furnace_params:
        for alt in _FURNACE_REPLACES.get(key, ()):
            prm.pop(alt, None)
    return {**prm, **entry.furnace_params}


def _builtin(name: str) -> BSDFEntry:
    furn = {"diffuse": {"albedo": 1.0}, "roughconductor": {"R0": 1.0}, "roughsubstrate": {"kd": 1.0}}
    return BSDFEntry(name, lambda a, p: make_named_bsdf(name, a, p), takes_alpha=has_alpha(name),
                     checks="/" not in name, furnace_params=furn.get(name, {}), by_name=True)


def _takes_alpha(cls) -> bool:
    try:
        return "alpha" in inspect.signature(cls.__init__).parameters
    except (TypeError, ValueError):
        return False


def _class_entry(name: str, cls, factory: Callable) -> BSDFEntry:
    return BSDFEntry(name, factory, takes_alpha=_takes_alpha(cls), sweep=dict(getattr(cls, "sweep", None) or {}))


def _from_class(cls) -> BSDFEntry:
    takes = _takes_alpha(cls)

    def factory(a, p):
        return cls(**({"alpha": a} if takes and a is not None else {}), **p)

    return _class_entry(getattr(cls, "type_name", "") or cls.__name__, cls, factory)


def _from_registry(name: str, make: Callable | None) -> BSDFEntry:
    if make is not None:
        proto = make(name, None, {})
        return _class_entry(name, type(proto), lambda a, p: make(name, a, p))
    from brdflab import plugins

    entry = _class_entry(name, plugins.bsdf_class(name.partition("/")[0]), lambda a, p: make_named_bsdf(name, a, p))
    entry.takes_alpha = has_alpha(name)
    entry.checks = "/" not in name
    entry.by_name = True
    return entry


def resolve_bsdfs(bsdfs=None, make: Callable | None = None) -> list[BSDFEntry]:
    """Battery entries for ``bsdfs`` (see the module docstring); None: every built-in BSDF and lobe variant."""
    if bsdfs is None:
        return [_builtin(n) for n in BSDFS]
    if isinstance(bsdfs, dict):
        bsdfs = list(bsdfs.items())
    out = []
    for item in bsdfs:
        if isinstance(item, BSDFEntry):
            out.append(item)
        elif isinstance(item, str):
            out.append(_builtin(item) if item in BSDFS and make is None else _from_registry(item, make))
        elif isinstance(item, tuple) and len(item) == 2 and isinstance(item[0], str):
            name, fac = item
            if isinstance(fac, type):
                e = _from_class(fac)
                e.name = name
                out.append(e)
            else:
                proto = fac(None, {})
                out.append(_class_entry(name, type(proto), fac))
        elif isinstance(item, type):
            out.append(_from_class(item))
        elif hasattr(item, "sample") and hasattr(item, "pdf"):
            out.append(BSDFEntry(describe(item), lambda a, p, b=item: b, takes_alpha=False))
        else:
            raise TypeError(f"cannot run the battery on {item!r}: expected a name, a BSDF, a class or (name, factory)")
    return out
