"""``--bsdf`` specifications of ``brdflab plot`` and ``brdflab explore``: several BSDFs, each with its own
parameters.

Syntax (one ``--bsdf`` per material, repeatable)::

    --bsdf NAME[:KEY=VALUE,KEY=VALUE…]

``NAME`` is a built-in (``roughconductor``, ``roughsubstrate/specular`` for one lobe …), a plugin's
``type_name`` (after ``--plugin FILE``) or ``package.module:Class``. Examples:
``--bsdf roughconductor:alpha=0.05 --bsdf roughconductor:alpha=0.3,R0=0.95,0.64,0.54``; a colour keeps its
commas (an item without ``=`` continues the previous value); ``--bsdf mypkg.phong:Phong:exponent=50``.

The global options are defaults for every ``--bsdf`` that does not set the key itself, and apply only to
materials that have that parameter (it is an error when none has it):

* ``--param KEY=VALUE`` (repeatable), e.g. ``--param R0=0.9``;
* ``--alpha A`` (repeatable): one material per value — an α sweep — for each ``--bsdf`` with a roughness.

So the common case ``--bsdf roughconductor --alpha 0.1 --param R0=0.9`` means ``roughconductor:alpha=0.1,R0=0.9``
and ``--bsdf roughconductor --bsdf roughsubstrate --alpha 0.05 --alpha 0.3`` draws four materials. Values
are converted by :func:`brdflab.plugins.make_bsdf` according to each parameter's kind.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from brdflab.errors import BrdflabError


@dataclass
class BSDFSpec:
    """One material to plot: its registered name, its parameters and a legend label."""

    name: str
    params: dict[str, str] = field(default_factory=dict)
    alpha: float | None = None

    @property
    def label(self) -> str:
        """``name`` followed by the parameters that were set, e.g. ``roughconductor alpha=0.1 R0=0.9``."""
        items = ([f"alpha={self.alpha:g}"] if self.alpha is not None and "alpha" not in self.params else [])
        items += [f"{k}={v}" for k, v in self.params.items()]
        return " ".join([self.name, *items])


def _short(text: str, n: int = 40) -> str:
    from brdflab.plugins import _short as short

    return short(text, n)


def parse_params(text: str, what: str) -> dict[str, str]:
    """``KEY=VALUE,KEY=VALUE…`` → dict (an item without ``=`` continues the previous value)."""
    out: dict[str, str] = {}
    last = None
    for item in text.split(","):
        key, sep, value = item.partition("=")
        if sep:
            key = key.strip()
            if not key:
                raise BrdflabError(f"{what}: empty parameter name in '{_short(text)}'")
            out[key] = value.strip()
            last = key
        elif last is not None and item.strip():
            out[last] += "," + item.strip()
        elif item.strip():
            raise BrdflabError(f"{what}: expected KEY=VALUE, got '{_short(item)}'")
    return out


def parse_bsdf(text: str) -> BSDFSpec:
    """Parse ``NAME[:KEY=VALUE,…]`` (``NAME`` may itself be ``package.module:Class``)."""
    from brdflab.plugins import bsdf_names

    head, sep, tail = text.rpartition(":")
    first = text.partition(":")[0]
    if sep and "=" in tail:
        name, rest = head, tail
    elif sep and ("=" in head or first.partition("/")[0] in bsdf_names()):  # a registered NAME, then K=V,…
        name, _, rest = text.partition(":")
    else:
        name, rest = text, ""
    name = name.strip()
    if not name:
        raise BrdflabError(f"--bsdf: expected NAME[:KEY=VALUE,...], got '{_short(text)}'")
    return BSDFSpec(name, parse_params(rest, f"--bsdf {_short(name)}"))


def _kinds(name: str) -> dict[str, str]:
    from brdflab.cli.options import resolve_bsdf
    from brdflab.plugins import bsdf_class, parameter_kinds

    return parameter_kinds(bsdf_class(resolve_bsdf(name).partition("/")[0]))


def resolve(specs: list[str], alphas: list[float] | None = None, params: list[str] | None = None) -> list[BSDFSpec]:
    """Combine ``--bsdf`` texts with the global ``--alpha`` values and ``--param`` defaults (module docstring).

    Raises
    ------
    BrdflabError
        Bad syntax, unknown BSDFs, or a global parameter (or ``--alpha``) that no chosen BSDF has.
    """
    from brdflab.cli.options import resolve_bsdf
    from brdflab.parameters import key_values

    common = key_values(params or [], "--param")
    parsed = [parse_bsdf(t) for t in specs]
    kinds = [_kinds(s.name) for s in parsed]
    for key in common:
        if not any(key in k for k in kinds):
            raise BrdflabError(f"--param {_short(key)}: none of the BSDFs has this parameter (they have "
                               f"{', '.join(sorted(set().union(*kinds))) or 'none'})")
    if alphas and not any("alpha" in k for k in kinds):
        raise BrdflabError("--alpha: none of the BSDFs has an 'alpha' parameter")
    out = []
    for s, k in zip(parsed, kinds, strict=True):
        s.name = resolve_bsdf(s.name)
        s.params = {**{key: v for key, v in common.items() if key in k and key not in s.params}, **s.params}
        if alphas and "alpha" in k and "alpha" not in s.params:
            out.extend(BSDFSpec(s.name, dict(s.params), a) for a in alphas)
        else:
            out.append(s)
    return out


def build(spec: BSDFSpec):
    """The BSDF object of ``spec`` (through the plugin registry; ``type/lobe`` selects one lobe)."""
    from brdflab.judges.core.guard import SceneCheckedBSDF
    from brdflab.judges.material.battery import make_named_bsdf
    from brdflab.limits import check_alpha
    from brdflab.plugins import is_builtin

    alpha = spec.params.get("alpha", spec.alpha)
    if alpha is not None and np.ndim(alpha) == 0:
        check_alpha(alpha, f"{spec.name}: alpha")
    bsdf = make_named_bsdf(spec.name, spec.alpha, spec.params)
    # A plugin's values are checked on every call (finite, ≥ 0, real, the right shape): a NaN is an error
    # naming the plugin and the direction, never drawn as f = 0.
    return bsdf if is_builtin(spec.name.partition("/")[0]) else SceneCheckedBSDF(bsdf)
