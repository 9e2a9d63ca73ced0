"""The explorer's views (:mod:`brdflab.viz.explorer`): Bokeh figures and what each shows for a list of materials.

The first material is the one edited; the others are overlaid, each in its own colour **and** dash pattern
(legible in grey print), where an overlay makes sense: the plane of incidence (each curve over its own maximum
when there are several; the whole circle when one transmits, the transmitted half below the horizon line; delta
lobes as spikes of length ∝ their energy), the directional albedo (R + T as lines, R ○ and T △ when one
transmits) and the lit spheres (one column each). The 3D lobe, the θ_h × θ_d slice and the samples show the
first material.

**Live lit sphere.** Every update renders a small preview (:data:`PREVIEW`: size and samples per pixel per
light; direct light only, so glass looks dark in it) at once; then a refined render (:data:`REFINED`; glass
path-traced) runs in the background, stopped as soon as another update starts (a burst of slider changes never
waits for a stale sphere) and shown only if it is still current.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass

import numpy as np

from brdflab.viz import coords, lobe3d, reflectance, views

#: Albedo curve angles of the explorer (fewer than ``brdflab plot``, so that it stays interactive).
THETAS = tuple(float(t) for t in range(0, 90, 8))
N_SAMPLES = 2000
#: Controls plus three columns of views fit a 1280-px window.
CONTROLS_W, VIEW_W = 230, 330
#: Colours (tab10) and dash patterns of the materials, first to third.
COLOURS = ("#1f77b4", "#d62728", "#2ca02c")
DASHES = ("solid", "dashed", "dotted")
MAX_MATERIALS = len(COLOURS)
#: Lit-sphere renders: (size, point-light spp, environment spp), preview while editing and refined after.
PREVIEW = (48, 2, 8)
REFINED = (96, 8, 48)
#: Samples per pixel of one chunk of a background render (between chunks it looks at its stop event).
CHUNK_SPP = 4


@dataclass
class Material:
    """One material of the explorer: its type name, BSDF object, parameter values and legend label."""

    name: str
    bsdf: object
    values: dict
    label: str


def _polar_radius(f: np.ndarray, fmax: float, floor: float, log: bool) -> np.ndarray:
    if log:
        return np.clip(np.log10(np.maximum(f, 1e-300) / floor), 0.0, None) / math.log10(fmax / floor)
    return f / fmax


def _spike_path(lobes, rmax: float) -> tuple[list, list, list]:
    """Delta lobes as one broken line (NaN between spikes) in the plane's (x, y), and their labels."""
    xs, ys, labels = [], [], []
    for d in lobes:
        t = math.atan2(-d.direction[0], d.direction[2])
        r = rmax * min(max(d.energy, 0.0), 1.0)
        xs += [0.0, r * math.sin(t), float("nan")]
        ys += [0.0, r * math.cos(t), float("nan")]
        labels.append((r * math.sin(t), r * math.cos(t), f"{'T' if d.transmitted else 'R'} = {d.energy:.3f}"))
    return xs, ys, labels


def _blank():
    from bokeh.core.properties import value

    return value("")


def _legend(items):
    from bokeh.models import Legend

    return Legend(items=items, label_text_font_size="7pt", spacing=0, padding=2, margin=2, glyph_width=28,
                  label_height=12, glyph_height=12, border_line_alpha=0)


def _label(items, mats) -> None:
    """Legend items: "k: label" (at most 44 characters) of the materials shown, the others hidden."""
    from bokeh.core.properties import value

    for k, item in enumerate(items):
        item.visible = mats[k] is not None
        text = f"{k + 1}: {mats[k].label}" if mats[k] is not None else ""
        item.label = value(text if len(text) <= 44 else text[:43] + "…")


class Views:
    """The Bokeh figures of the explorer and their data sources; :meth:`update` redraws them for materials."""

    def __init__(self) -> None:
        from bokeh.models import ColorBar, ColumnDataSource, LegendItem, LinearColorMapper, Whisker
        from bokeh.plotting import figure

        tools = "pan,wheel_zoom,reset,save"
        cds = ColumnDataSource
        self.polar_src = [cds({"x": [], "y": []}) for _ in COLOURS]
        self.spike_txt = cds({"x": [], "y": [], "text": [], "c": []})
        self.guide_src = cds({"xs": [], "ys": [], "c": []})
        self.lobe_src = cds({"xs": [], "ys": [], "c": []})
        self.axes_src = cds({"xs": [], "ys": [], "c": []})
        self.slice_src = cds({"image": [np.zeros((2, 2))]})
        self.alb_src = [cds({"t": [], "q": []}) for _ in COLOURS]
        self.parts_src = [cds({"t": [], "r": [], "tr": []}) for _ in COLOURS]
        self.mc_src = [cds({"t": [], "m": [], "lo": [], "hi": []}) for _ in COLOURS]
        self.cur_src = cds({"t": [], "q": []})
        self.pdf_src = cds({"image": [np.zeros((2, 2))]})
        self.pts_src = cds({"x": [], "y": [], "c": []})
        self.sphere_src = cds({"image": [], "x": [], "y": [], "dw": [], "dh": []})
        self.sphere_txt = cds({"x": [], "y": [], "text": []})

        self.polar = figure(title="plane of incidence (θ_o > 0: away from ω_i)", width=VIEW_W, height=250,
                            x_range=(-1.05, 1.05), y_range=(-0.02, 1.05), match_aspect=True, tools=tools,
                            name="polar")
        self.polar.multi_line("xs", "ys", color="c", source=self.guide_src, line_dash="dashed")
        self.polar_items = [LegendItem(label=_blank(), visible=False, renderers=[self.polar.line(
            "x", "y", source=src, line_width=2, color=COLOURS[k], line_dash=DASHES[k])])
            for k, src in enumerate(self.polar_src)]
        self.polar.add_layout(_legend(self.polar_items), "below")
        self.polar.text("x", "y", "text", source=self.spike_txt, text_font_size="8pt", text_color="c",
                        x_offset=4, y_offset=-2)
        self.polar.xaxis.axis_label = "radius ∝ f (log: 4 decades)"

        self.lobe = figure(title="3D lobe f·|cos θ_o|", width=VIEW_W, height=280, match_aspect=True,
                           x_range=(-1.1, 1.1), y_range=(-0.6, 1.1), tools=tools, name="lobe")
        self.lobe.patches("xs", "ys", fill_color="c", line_color="c", line_width=0.3, source=self.lobe_src)
        self.lobe.multi_line("xs", "ys", color="c", line_width=2, source=self.axes_src)
        self.lobe.axis.visible = False
        self.lobe.grid.visible = False

        self.mapper = LinearColorMapper(palette="Magma256", low=-4, high=0, nan_color="#cccccc")
        self.slice = figure(title="θ_h × θ_d: log₁₀ f (grey: outside)", width=VIEW_W, height=280,
                            x_range=(0, 90), y_range=(0, 90), tools="hover,reset,save", name="slice")
        self.slice.image("image", x=0, y=0, dw=90, dh=90, color_mapper=self.mapper, source=self.slice_src)
        self.slice.add_layout(ColorBar(color_mapper=self.mapper, width=10), "right")
        self.slice.xaxis.axis_label, self.slice.yaxis.axis_label = "θ_h [°]", "θ_d [°]"

        self.albedo = figure(title="albedo: quadrature (lines), MC ± 2σ", width=VIEW_W, height=270,
                             x_range=(0, 90), tools="pan,reset,save", name="albedo")
        self.albedo_items = []
        for k in range(MAX_MATERIALS):
            c = COLOURS[k]
            line = self.albedo.line("t", "q", source=self.alb_src[k], line_width=2, color=c, line_dash=DASHES[k])
            self.albedo_items.append(LegendItem(label=_blank(), visible=False, renderers=[line]))
            self.albedo.scatter("t", "r", source=self.parts_src[k], marker="circle", fill_color=None,
                                line_color=c, size=6)
            self.albedo.scatter("t", "tr", source=self.parts_src[k], marker="triangle", fill_color=None,
                                line_color=c, size=6)
            self.albedo.scatter("t", "m", source=self.mc_src[k], size=4, color=c)
            self.albedo.add_layout(Whisker(source=self.mc_src[k], base="t", lower="lo", upper="hi", line_color=c))
        self.albedo.scatter("t", "q", source=self.cur_src, size=11, marker="diamond", color="black")
        self.albedo.add_layout(_legend(self.albedo_items), "below")
        self.albedo.xaxis.axis_label, self.albedo.yaxis.axis_label = "θ_i [°]", "ρ(θ_i)"

        self.pdf_map = LinearColorMapper(palette="Viridis256", low=0, high=1)
        self.samples = figure(title=f"{N_SAMPLES} samples on the pdf (ω_o.x, ω_o.y)", frame_width=VIEW_W - 100,
                              frame_height=VIEW_W - 100, x_range=(-1, 1), y_range=(-1, 1), tools=tools,
                              name="samples")
        self.samples.image("image", x=-1, y=-1, dw=2, dh=2, color_mapper=self.pdf_map, source=self.pdf_src)
        self.samples.scatter("x", "y", source=self.pts_src, size=2.5, color="c", alpha=0.7)
        self.samples.add_layout(ColorBar(color_mapper=self.pdf_map, width=10, title="pdf/max"), "right")

        self.sphere = figure(title="lit sphere (direct_mis)", frame_width=VIEW_W - 30,
                             frame_height=int((VIEW_W - 30) * 2.12 / 3), x_range=(0, 3), y_range=(0, 2.12),
                             tools="save", name="sphere", min_border_left=5, min_border_right=5)
        self.sphere.image_rgba("image", x="x", y="y", dw="dw", dh="dh", source=self.sphere_src)
        self.sphere.text("x", "y", "text", source=self.sphere_txt, text_font_size="7pt", text_align="center")
        self.sphere.axis.visible = False
        self.sphere.grid.visible = False
        self.state = {"lobe": None, "wi": None, "albedo_key": None, "albedo": [], "sphere_gen": 0}

    def layout(self, controls, view_az, view_el):
        """Controls and the views in three columns."""
        from bokeh.layouts import column, row

        return row(controls, column(self.polar, self.albedo, self.samples),
                   column(self.lobe, view_az, view_el, self.slice), column(self.sphere))

    # -- the views ------------------------------------------------------------------------------------------
    def update(self, mats: list[Material | None], ti: float, pi: float, phi_d: float, log: bool) -> dict:
        """Redraw every view but the sphere for the material of each slot (None: an empty slot; the first is the
        edited one); returns the first material's summary (peak f, its θ_o, ρ(θ_i), the share of failed
        samples)."""
        from brdflab.errors import BrdflabError

        first = mats[0]
        t, shown = views.polar([m.bsdf for m in mats if m is not None], ti, pi, n=361)
        it = iter(shown)
        v = [next(it) if m is not None else None for m in mats]
        wo_plane = coords.plane_directions(t, pi)
        raw = first.bsdf.eval(np.ascontiguousarray(np.broadcast_to(coords.incident(ti, pi), wo_plane.shape)),
                              wo_plane)
        if not np.all(np.isfinite(raw)):
            raise BrdflabError(f"{first.name}: eval returned NaN or infinity in the plane of incidence "
                               f"(θ_i = {ti:g}°); nothing drawn")
        self._polar(mats, t, v, ti, log)
        self._lobe(first, ti, pi)
        self._slice(first, phi_d)
        rho = self._albedo(mats, ti, pi)
        failed = self._samples(first, ti, pi)
        f = v[0]
        return {"fmax": float(f.max()), "peak": float(t[np.argmax(f)]), "rho": rho, "failed": failed,
                "delta": reflectance.all_delta(first.bsdf)}

    def _polar(self, mats, t, v, ti, log) -> None:
        full = abs(t[0]) > 90
        several = sum(m is not None for m in mats) > 1
        fin = [np.where(np.isfinite(x), x, 0.0) if x is not None else None for x in v]
        gmax = max([float(x.max()) for x in fin if x is not None] + [0.0]) or 1.0
        texts = []
        _label(self.polar_items, mats)
        for k, src in enumerate(self.polar_src):
            if mats[k] is None:
                src.data = {"x": [], "y": []}
                continue
            m = mats[k]
            if reflectance.all_delta(m.bsdf):
                xs, ys, lab = _spike_path(reflectance.delta_lobes(m.bsdf, ti), 1.0)
                texts += [(x, y, s, COLOURS[k]) for x, y, s in lab]
                src.data = {"x": np.array(xs), "y": np.array(ys)}
                continue
            own = float(fin[k].max()) if fin[k].max() > 0 else 1.0
            r = _polar_radius(fin[k], own if several and not log else gmax, gmax / 1e4, log)
            tr = np.radians(t)
            src.data = {"x": (r * np.sin(tr)).tolist(), "y": (r * np.cos(tr)).tolist()}
        self.spike_txt.data = {"x": [x for x, *_ in texts], "y": [y for _, y, *_ in texts],
                               "text": [s for *_, s, _ in texts], "c": [c for *_, c in texts]}
        a = math.radians(ti)
        xs, ys, cs = [[0, -math.sin(a)], [0, math.sin(a)]], [[0, math.cos(a)], [0, math.cos(a)]], ["#777777", "black"]
        if full:
            xs, ys, cs = xs + [[-1.05, 1.05]], ys + [[0, 0]], cs + ["#444444"]
        self.guide_src.data = {"xs": xs, "ys": ys, "c": cs}
        self.polar.y_range.start = -1.05 if full else -0.02
        self.polar.height = (330 if full else 250) + 14 * sum(m is not None for m in mats)
        self.polar.title.text = ("plane of incidence, whole circle (below: T)" if full else
                                 "plane of incidence (θ_o > 0: away from ω_i)")

    def _lobe(self, m: Material, ti, pi) -> None:
        full = reflectance.transmits(m.bsdf)
        wi = coords.incident(ti, pi)
        if reflectance.all_delta(m.bsdf):
            pts = np.zeros((2, 2, 3))
            self.state["spikes"] = [(d.direction * min(max(d.energy, 0.0), 1.0), d.transmitted)
                                    for d in reflectance.delta_lobes(m.bsdf, ti, pi)]
        else:
            lb = views.lobe([m.bsdf], ti, pi, n_theta=31, n_phi=61, full=full)
            pts = lobe3d.surface(lb.directions, lb.values[0] * np.abs(np.cos(np.radians(lb.theta_o_deg)))[:, None])
            self.state["spikes"] = []
        self.state["lobe"], self.state["wi"] = pts, wi
        self.lobe.y_range.start = -1.1 if full else -0.6
        self.lobe.title.text = f"3D lobe f·|cos θ_o| of 1 ({'whole sphere' if full else 'hemisphere'})"

    def draw_lobe(self, az: float, el: float) -> None:
        """Project the lobe for a view (the view sliders only re-project it)."""
        pts, wi = self.state["lobe"], self.state["wi"]
        if pts is None:
            return
        pl = lobe3d.project(pts, az, el)
        self.lobe_src.data = {"xs": pl.xs.tolist(), "ys": pl.ys.tolist(), "c": lobe3d.shade_colours(pl.shade)}
        ex, ey, _ = lobe3d.view_axes(az, el)
        ring = np.linspace(0, 2 * np.pi, 73)
        circle = np.stack([np.cos(ring), np.sin(ring), np.zeros(73)], axis=1)
        lines = [(circle, "#bbbbbb"), (np.array([[0.0, 0, 0], [0, 0, 1]]), "#777777"),
                 (np.array([[0.0, 0, 0], wi]), "black")]
        lines += [(np.array([[0.0, 0, 0], tip]), COLOURS[1] if below else COLOURS[0])
                  for tip, below in self.state["spikes"]]
        self.axes_src.data = {"xs": [(p @ ex).tolist() for p, _ in lines], "ys": [(p @ ey).tolist() for p, _ in lines],
                              "c": [c for _, c in lines]}

    def _slice(self, m: Material, phi_d: float) -> None:
        _, _, sv = views.half_diff_slice([m.bsdf], phi_d, n=72)
        with np.errstate(divide="ignore", invalid="ignore"):
            lg = np.log10(np.where(np.isfinite(sv[0]) & (sv[0] > 0), sv[0], np.nan))
        top = float(np.nanmax(lg)) if np.isfinite(lg).any() else 0.0
        self.mapper.low, self.mapper.high = top - 5, top
        # f = 0 below the colour range (black, as in `brdflab plot`); outside the hemisphere NaN: grey
        self.slice_src.data = {"image": [np.where(np.isfinite(sv[0]), np.nan_to_num(lg, nan=top - 6), np.nan)]}
        note = (" (delta lobes: f = 0)" if reflectance.all_delta(m.bsdf) else
                " (reflection only)" if reflectance.transmits(m.bsdf) else "")
        self.slice.title.text = f"θ_h × θ_d of 1: log₁₀ f{note}" if note else "θ_h × θ_d: log₁₀ f (grey: outside)"

    def _albedo(self, mats, ti, pi) -> float:
        keys = [m and (m.name, tuple(sorted((k, repr(x)) for k, x in m.values.items()))) for m in mats]
        if self.state["albedo_key"] != keys:
            # per material: editing one of three recomputes one curve (the rough glass's took 2 s)
            known = dict(zip(self.state["albedo_key"] or [], self.state["albedo"], strict=True))
            self.state["albedo"] = [m and (known.get(key) or views.albedo([m.bsdf], THETAS, n=4000, seed=0))
                                    for m, key in zip(mats, keys, strict=True)]
            self.state["albedo_key"] = keys
            _label(self.albedo_items, mats)
            for k in range(MAX_MATERIALS):
                if mats[k] is None:
                    self.alb_src[k].data = {"t": [], "q": []}
                    self.parts_src[k].data = {"t": [], "r": [], "tr": []}
                    self.mc_src[k].data = {"t": [], "m": [], "lo": [], "hi": []}
                    continue
                al = self.state["albedo"][k]
                tt = list(al.theta_deg)
                self.alb_src[k].data = {"t": tt, "q": al.quadrature[0].tolist()}
                self.parts_src[k].data = ({"t": tt, "r": al.reflected[0].tolist(), "tr": al.transmitted[0].tolist()}
                                          if al.any_transmission else {"t": [], "r": [], "tr": []})
                mc, se = al.monte_carlo[0], al.mc_stderr[0]
                self.mc_src[k].data = {"t": tt, "m": mc.tolist(), "lo": (mc - 2 * se).tolist(),
                                       "hi": (mc + 2 * se).tolist()}
            split = any(a.any_transmission for a in self.state["albedo"] if a is not None)
            self.albedo.title.text = ("albedo R+T (lines), R ○, T △; MC ± 2σ" if split else
                                      "albedo: quadrature (lines), MC ± 2σ")
        rho = float(views.albedo_quadrature(mats[0].bsdf, ti)) if pi == 0 else float(
            np.interp(ti, THETAS, self.state["albedo"][0].quadrature[0]))
        self.cur_src.data = {"t": [ti], "q": [rho]}
        return rho

    def _samples(self, m: Material, ti, pi) -> float:
        rng = np.random.default_rng(19)
        wi = np.ascontiguousarray(np.broadcast_to(coords.incident(ti, pi), (N_SAMPLES, 3)))
        out = m.bsdf.sample(wi, rng.random((N_SAMPLES, 3)))
        ok = out.pdf > 0
        below = out.wo[ok, 2] < 0
        self.pts_src.data = {"x": out.wo[ok, 0].tolist(), "y": out.wo[ok, 1].tolist(),
                             "c": np.where(below, "#ff7f0e", "white").tolist()}
        g = np.linspace(-1, 1, 81)
        gx, gy = np.meshgrid(g, g)
        rho2 = gx**2 + gy**2
        wo = np.stack([gx.ravel(), gy.ravel(), np.sqrt(np.clip(1 - rho2.ravel(), 0, 1))], axis=1)
        pd = m.bsdf.pdf(np.ascontiguousarray(wi[:1].repeat(len(wo), 0)), wo).reshape(gx.shape)
        pd = np.where((rho2 < 1) & np.isfinite(pd), pd, 0.0)
        self.pdf_src.data = {"image": [pd / (pd.max() if pd.max() > 0 else 1.0)]}
        self.samples.title.text = (f"{N_SAMPLES} samples of 1 (orange: below)" if below.any() else
                                   f"{N_SAMPLES} samples of 1 on its pdf")
        return float(100 * (1 - ok.mean()))

    # -- the lit sphere -------------------------------------------------------------------------------------
    def show_spheres(self, images: list[list[np.ndarray]], numbers: list[int], note: str) -> None:
        """Lay out sphere images (rows: point light, environment; a column per material, headed by its
        ``numbers``)."""
        from brdflab.imageio import srgb_bytes

        data = {"image": [], "x": [], "y": [], "dw": [], "dh": []}
        for r, row in enumerate(images):
            for c, img in enumerate(row):
                rgb = srgb_bytes(img)[::-1]  # Bokeh's images start at the bottom row
                rgba = np.ascontiguousarray(np.dstack([rgb, np.full(rgb.shape[:2], 255, np.uint8)]))
                data["image"].append(rgba.view(np.uint32)[..., 0])
                data["x"].append(c + 0.02)
                data["y"].append(1.0 - r + 0.02)
                data["dw"].append(0.96)
                data["dh"].append(0.96)
        self.sphere_src.data = data
        n = len(images[0]) if images else 0
        self.sphere_txt.data = {"x": [c + 0.5 for c in range(n)], "y": [2.02] * n,
                                "text": [str(k) for k in numbers[:n]]}
        self.sphere.title.text = f"lit sphere: {note}"


_STAGES: dict[tuple[int, str], object] = {}
_STAGE_LOCK = threading.Lock()


def sphere_images(bsdfs: list, quality: tuple[int, int, int], stop=None,
                  paths: bool = True) -> list[list[np.ndarray]] | None:
    """Renders of a sphere of each BSDF under each light of :mod:`brdflab.viz.sphere` at ``quality`` (size,
    point-light spp, environment spp), in this process; None when ``stop`` was set before the end.

    ``paths``: a transmitting BSDF is path-traced (:func:`brdflab.viz.sphere.integrator_for`); without, every
    sphere gets direct light only (the preview: path tracing glass took 2 s even at 48² pixels)."""
    from brdflab.viz.sphere import LIGHTS, SphereStage, integrator_for

    size, *spps = quality
    out = []
    for light, spp in zip(LIGHTS, spps, strict=True):
        row = []
        for b in bsdfs:
            if stop is not None and stop.is_set():
                return None
            key = (size, integrator_for(b) if paths else "direct_mis")
            with _STAGE_LOCK:  # the scenes of each size and integrator are written and loaded once per process
                stage = _STAGES.get(key) or _STAGES.setdefault(key, SphereStage(*key))
            if stop is None:
                row.append(stage.render(b, light, spp))
                continue
            # in chunks of at most CHUNK_SPP, each its own seed, so that a stop request ends it quickly (the
            # renderer checks ``stop`` between work units; one unit of the whole sphere took up to a second)
            chunks = [min(CHUNK_SPP, spp - k) for k in range(0, spp, CHUNK_SPP)]
            acc = np.zeros((size, size, 3))
            for seed, n in enumerate(chunks):
                if stop.is_set():
                    return None
                acc += stage.render(b, light, n, seed=seed, stop=stop) * (n / spp)
            row.append(acc.astype(np.float32))
        out.append(row)
    return None if stop is not None and stop.is_set() else out
