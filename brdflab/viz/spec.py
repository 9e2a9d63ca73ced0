"""``--bsdf`` specifications of ``brdflab plot``: several BSDFs, each with its own parameters.

Syntax (one ``--bsdf`` per material, repeatable)::

    --bsdf NAME[:KEY=VALUE,KEY=VALUE…]

e.g. ``--bsdf roughconductor:alpha=0.05 --bsdf roughconductor:alpha=0.3,R0=0.95,0.64,0.54``. A colour
keeps its commas: an item without ``=`` continues the previous value. The global ``--alpha A`` and
``--param KEY=VALUE`` options apply to every ``--bsdf`` that does not set that key itself, so the common
case ``--bsdf roughconductor --alpha 0.1 --param R0=0.9`` means ``roughconductor:alpha=0.1,R0=0.9``
(``--alpha`` is ignored by materials without a roughness, e.g. ``diffuse``).
Values are strings converted by :func:`brdflab.plugins.make_bsdf` according to the type of each
parameter's default.
"""

from __future__ import annotations

from dataclasses import dataclass, field

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
    text = text.encode("unicode_escape").decode("ascii")
    return text if len(text) <= n else text[: n - 1] + "…"


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
    """Parse ``NAME[:KEY=VALUE,…]``."""
    name, _, rest = text.partition(":")
    name = name.strip()
    if not name:
        raise BrdflabError(f"--bsdf: expected NAME[:KEY=VALUE,...], got '{_short(text)}'")
    return BSDFSpec(name, parse_params(rest, f"--bsdf {_short(name)}"))


def resolve(specs: list[str], alpha: float | None = None, params: list[str] | None = None) -> list[BSDFSpec]:
    """Combine ``--bsdf`` texts with the global ``--alpha`` and ``--param`` defaults."""
    common: dict[str, str] = {}
    for p in params or []:
        common.update(parse_params(p, "--param"))
    out = []
    for text in specs:
        s = parse_bsdf(text)
        merged = {k: v for k, v in common.items() if k not in s.params}
        merged.update(s.params)
        s.params = merged
        if alpha is not None and "alpha" not in s.params:
            s.alpha = alpha
        out.append(s)
    return out


def build(spec: BSDFSpec):
    """The BSDF object of ``spec`` (through the plugin registry)."""
    from brdflab.viz.registry import make_bsdf

    return make_bsdf(spec.name, spec.params, alpha=spec.alpha)
