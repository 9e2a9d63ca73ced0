"""The explorer's widgets for parameters that are choices or alternatives (issue 45), by parameter name, for any
BSDF that has them (built-in ``roughconductor``; a plugin with the same names gets the same widgets):

* ``distribution`` (a string): a dropdown of :data:`brdflab.bsdf.microfacet.DISTRIBUTIONS`, not a text box;
* ``sample_visible`` (a boolean without a default): a checkbox, set to the distribution's default (true for
  GGX, false for Beckmann) whenever the distribution changes;
* ``alpha_u``/``alpha_v`` beside ``alpha``: a checkbox "α_u = α_v = α" (on: one α slider, the BSDF gets no
  α_u/α_v and stays isotropic — for Beckmann the course's code path); off: two sliders, started at the current
  α, replace it (re-linking sets α to √(α_u α_v));
* ``R0`` (Schlick) or ``eta``/``k`` or ``material``: one dropdown "Fresnel" of ``Schlick R0``, the metals of
  :data:`brdflab.bsdf.conductors.MATERIALS` and ``η, k (typed)``; only the widgets of the choice are shown
  (R0's colour, or η and k as colours started at the last metal's values) and only its parameters are given.

Widget names (the browser tests find them): ``<prefix>distribution``, ``<prefix>sample_visible``,
``<prefix>alpha_link``, ``<prefix>alpha_u``, ``<prefix>alpha_v``, ``<prefix>fresnel``, ``<prefix>eta``,
``<prefix>k`` (``prefix`` is ``param_`` for the edited material). A choice the client forges is refused in
:meth:`Alternatives.adjust` (the server's options are the allow-list).
"""

from __future__ import annotations

import math

import numpy as np

from brdflab.errors import BrdflabError

SCHLICK = "Schlick R0"
ETA_K = "η, k (typed)"
ALPHAS = ("alpha", "alpha_u", "alpha_v")
FRESNEL = ("R0", "eta", "k", "material")


def _distributions() -> tuple[str, ...]:
    from brdflab.bsdf.microfacet import DISTRIBUTIONS

    return tuple(DISTRIBUTIONS)


def _metals() -> tuple[str, ...]:
    from brdflab.bsdf.conductors import MATERIALS

    return tuple(MATERIALS)


def handled(kinds: dict) -> set[str]:
    """The parameters of ``kinds`` that :class:`Alternatives` builds (the explorer's generic loop skips them)."""
    out: set[str] = set()
    if kinds.get("distribution") == "string":
        out.add("distribution")
        if kinds.get("sample_visible") == "boolean":
            out.add("sample_visible")
    if all(kinds.get(k) == "float" for k in ALPHAS):
        out.update(ALPHAS)
    if (kinds.get("R0"), kinds.get("eta"), kinds.get("k"), kinds.get("material")) == ("color",) * 3 + ("string",):
        out.update(FRESNEL)
    return out


class Alternatives:
    """One material slot's choice and alternative widgets (module docstring).

    ``tools`` gives the explorer's own widget makers and callbacks: ``slider(key, title, lo, hi, step, value)``
    → (slider, row), ``colour(key, default)`` → [row], ``request()`` (an update), ``on_change`` (a widget
    change handler that requests one), ``guarded(fn)``.
    """

    def __init__(self, prefix: str, kinds: dict, defaults: dict, tools) -> None:
        self.prefix, self.kinds, self.defaults, self.tools = prefix, kinds, defaults, tools
        self.keys = handled(kinds)
        self.widgets: dict[str, tuple[str, object]] = {}  # parameter → (kind, widget), as the slot's
        self.rows: dict[str, object] = {}
        self.link = self.fresnel = None
        self.metal = _metals()[0]

    def build(self, key: str) -> list:
        """The widgets (layouts) for ``key``, or [] when ``key`` is built with another or not handled."""
        if key == "distribution":
            return self._distribution()
        if key == "alpha":
            return self._alphas()
        if key == "R0":
            return self._fresnel()
        return []

    # -- distribution and visible-normal sampling -------------------------------------------------------------
    def _distribution(self) -> list:
        from bokeh.models import Checkbox, Select

        t = self.tools
        dists = _distributions()
        start = self.defaults.get("distribution") or dists[0]
        select = Select(title="distribution", value=start, options=list(dists), name=f"{self.prefix}distribution",
                        width=t.width)
        self.widgets["distribution"] = ("string", select)
        out = [select]
        if "sample_visible" in self.keys:
            box = Checkbox(label="sample_visible (visible normals)", active=self._visible_default(start),
                           name=f"{self.prefix}sample_visible")
            box.on_change("active", t.on_change)
            self.widgets["sample_visible"] = ("boolean", box)
            out.append(box)

        def chosen(attr, old, new) -> None:
            if "sample_visible" in self.widgets and new in dists:
                self.widgets["sample_visible"][1].active = self._visible_default(new)  # its default for new
            t.request()

        select.on_change("value", t.guarded(chosen))
        return out

    @staticmethod
    def _visible_default(dist: str) -> bool:
        from brdflab.bsdf.microfacet import GGX

        return dist == GGX

    # -- α, or α_u and α_v ------------------------------------------------------------------------------------
    def _alphas(self) -> list:
        from bokeh.models import Checkbox

        t = self.tools
        a0 = float(self.defaults.get("alpha") or 0.1)
        rows = {}
        for key in ALPHAS:
            title = {"alpha": "alpha", "alpha_u": "alpha_u (along x)", "alpha_v": "alpha_v (along y)"}[key]
            w, rows[key] = t.slider(f"{self.prefix}{key}", title, 0.002, 1.0, 0.002, min(max(a0, 0.002), 1.0))
            self.widgets[key] = ("float", w)
        self.link = Checkbox(label="α_u = α_v = α (isotropic)", active=True, name=f"{self.prefix}alpha_link")
        self.rows.update(rows)
        self._show_alphas(True)

        def linked(attr, old, new) -> None:
            on = bool(new) if isinstance(new, bool) else True
            a, u, v = (self.widgets[k][1] for k in ALPHAS)
            if on:
                a.value = min(max(math.sqrt(t.number(f"{self.prefix}alpha_u") * t.number(f"{self.prefix}alpha_v")),
                                  a.start), a.end)
            else:
                u.value = v.value = t.number(f"{self.prefix}alpha")
            self._show_alphas(on)
            t.request()

        self.link.on_change("active", t.guarded(linked))
        return [self.link, rows["alpha"], rows["alpha_u"], rows["alpha_v"]]

    def _show_alphas(self, linked: bool) -> None:
        self.rows["alpha"].visible = linked
        self.rows["alpha_u"].visible = self.rows["alpha_v"].visible = not linked

    # -- Fresnel: Schlick's R0, a metal, or η and k -------------------------------------------------------------
    def _fresnel(self) -> list:
        from bokeh.models import Select

        from brdflab.bsdf.conductors import METALS_RGB

        t = self.tools
        options = [SCHLICK, *_metals(), ETA_K]
        self.fresnel = Select(title="Fresnel", value=SCHLICK, options=options, name=f"{self.prefix}fresnel",
                              width=t.width)
        eta, k = METALS_RGB[self.metal]
        r0 = t.colour("R0", self.defaults.get("R0", 0.5))
        rows = {"R0": r0, "eta": t.colour("eta", eta), "k": t.colour("k", k)}
        for key in ("R0", "eta", "k"):
            self.widgets[key] = t.take(key)
        self.rows.update({key: rows[key][0] for key in rows})
        self._show_fresnel(SCHLICK)

        def chosen(attr, old, new) -> None:
            if new not in options:
                t.request()  # refused in adjust(): a status line, nothing shown changes
                return
            if new in METALS_RGB:  # η and k start at the last metal's values when typed
                self.metal = new
                for key, value in zip(("eta", "k"), METALS_RGB[new], strict=True):
                    t.set_colour(self.widgets[key][1], value)
            self._show_fresnel(new)
            t.request()

        self.fresnel.on_change("value", t.guarded(chosen))
        return [self.fresnel, *rows["R0"], *rows["eta"], *rows["k"]]

    def _show_fresnel(self, choice: str) -> None:
        self.rows["R0"].visible = choice == SCHLICK
        self.rows["eta"].visible = self.rows["k"].visible = choice == ETA_K

    # -- the values the BSDF gets -------------------------------------------------------------------------------
    def adjust(self, values: dict) -> dict:
        """Drop the parameters the current choices leave out and add the chosen metal (in place; returned)."""
        if "distribution" in self.widgets and values.get("distribution") not in _distributions():
            raise BrdflabError(f"distribution must be one of {', '.join(_distributions())}")
        if self.link is not None:
            if self.link.active is not False:  # linked (anything but an explicit False from the client)
                values.pop("alpha_u", None)
                values.pop("alpha_v", None)
        if self.fresnel is not None:
            choice = self.fresnel.value
            if choice == SCHLICK:
                drop = ("eta", "k")
            elif choice == ETA_K:
                drop = ("R0",)
            elif choice in _metals():
                drop = ("R0", "eta", "k")
                values["material"] = choice
            else:
                raise BrdflabError(f"Fresnel must be one of {SCHLICK}, {', '.join(_metals())}, {ETA_K}")
            for key in drop:
                values.pop(key, None)
        return values


def as_rgb_text(rgb) -> str:
    """The colour text box's form of a linear RGB triple."""
    return ",".join(f"{x:.4g}" for x in np.broadcast_to(np.asarray(rgb, float), (3,)))
