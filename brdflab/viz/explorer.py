"""``brdflab explore``: the BRDF views live in a browser, on a local Bokeh server (127.0.0.1 only).

One page holds the BSDF choice, sliders for θ_i, φ_i and every parameter of the chosen BSDF (floats and
integers as sliders, colours as a colour picker beside the linear r,g,b values, booleans, strings), and five
linked views recomputed by the NumPy core of :mod:`brdflab.viz.views` whenever a widget changes:

* the plane of incidence (f, linear or log) with ω_i and the mirror direction;
* the 3D lobe f·cos θ_o ω_o as a shaded surface (:mod:`brdflab.viz.lobe3d`), turned by two view sliders;
* the θ_h × θ_d slice at a chosen φ_d (log₁₀ f with a colour bar);
* the directional albedo against θ_i (quadrature, Monte Carlo ± 2σ), the current θ_i marked;
* 2000 directions drawn by the BSDF's own ``sample`` over its ``pdf`` (both projected onto the unit disk,
  (x, y) = (ω_o.x, ω_o.y), as Nori's warptest does), with the fraction of failed samples.

A status line sums up the current state (peak of f, albedo) — the browser test reads it.

**Trust boundary.** Every widget value arrives from the browser, and any local program can speak Bokeh's
websocket protocol, so the server trusts none of them: the BSDF types are an allow-list of classes resolved
when the server starts (:func:`allowed_bsdfs`; a client's type string is only ever looked up in that
dictionary, never handed to the plugin loader), numbers are clamped to the ranges the server chose, texts are
length-limited and converted by the parameter's kind, every callback catches its own errors (the status line
gets one escaped line, the browser never a traceback), and Bokeh's own protocol errors are sent without the
traceback (:func:`serve`).

Bokeh serves its JavaScript from the installed Python package (no CDN, works offline); the server binds
only 127.0.0.1 and accepts websocket connections from that origin only. Ctrl-C, SIGTERM and SIGHUP stop it
with the exit status 128 + the signal number.
"""

from __future__ import annotations

import functools
import logging
import math
import re
from html import escape as esc

import numpy as np

from brdflab.viz import coords, lobe3d, views
from brdflab.viz.coalesce import DEBOUNCE_MS, Coalescer
from brdflab.viz.server_safety import _no_tracebacks_to_clients, one_line_logs

#: Albedo curve angles of the explorer (fewer than ``brdflab plot``, so that it stays interactive).
THETAS = tuple(float(t) for t in range(0, 90, 8))
N_SAMPLES = 2000
#: Longest text a string parameter may carry (a client can send anything).
MAX_TEXT = 200
#: View widths: controls plus three columns of views fit a 1280-px window.
CONTROLS_W, VIEW_W = 230, 330
_HEX = re.compile(r"#[0-9a-fA-F]{6}")
log = logging.getLogger(__name__)


def _range(name: str, kind: str, default) -> tuple[float, float, float]:
    """(start, end, step) of a parameter slider, guessed from its name and default."""
    d = float(default)
    low = name.lower()
    if low == "alpha":
        return 0.002, 1.0, 0.002
    if "ior" in low or low in ("eta", "n"):
        return 1.0, 3.0, 0.01
    if low in ("r0", "kd", "ks", "albedo", "reflectance"):
        return 0.0, 1.0, 0.01
    if kind == "integer":
        return 0, max(10, 2 * int(d)), 1
    hi = max(1.0, 2.0 * abs(d))
    return 0.0, hi, hi / 200


def linear_to_hex(rgb) -> str:
    """``#rrggbb`` of a linear RGB colour (sRGB-encoded, clipped to [0, 1]; IEC 61966-2-1)."""
    c = np.clip(np.asarray(rgb, float), 0.0, 1.0)
    s = np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)
    return "#" + "".join(f"{int(round(v * 255)):02x}" for v in s)


def hex_to_linear(text: str) -> np.ndarray:
    """Linear RGB of an ``#rrggbb`` sRGB colour (IEC 61966-2-1); ValueError for anything else."""
    if not isinstance(text, str) or not _HEX.fullmatch(text):
        raise ValueError("expected #rrggbb")
    s = np.array([int(text[i:i + 2], 16) for i in (1, 3, 5)]) / 255.0
    return np.where(s <= 0.04045, s / 12.92, ((s + 0.055) / 1.055) ** 2.4)


def allowed_bsdfs() -> dict[str, type]:
    """The explorer's allow-list: every registered BSDF type (built-ins first) → its class, resolved once.

    Types whose parameters brdflab cannot convert are left out. The browser can only choose among these keys.
    """
    from brdflab.errors import BrdflabError
    from brdflab.plugins import bsdf_class, bsdf_names, parameter_kinds

    out: dict[str, type] = {}
    for name in bsdf_names():
        try:
            cls = bsdf_class(name)
            kinds = parameter_kinds(cls)
        except BrdflabError:
            continue
        if "filename" in kinds:  # a type that reads a file the browser would name (``measured``): not offered
            continue
        out[name] = cls
    return out


def _one_line(exc: BaseException) -> str:
    lines = str(exc).strip().splitlines()
    text = f"{type(exc).__name__}: {lines[0] if lines else ''}"
    return text if len(text) <= 160 else text[:157] + "…"


def make_document(doc, allowed: dict[str, type] | None = None, schedule=None) -> None:
    """Build the explorer into a Bokeh document (one per browser tab) offering the types of ``allowed``.

    ``schedule(callback)`` runs a coalesced update later (:class:`Coalescer`); by default a timeout of
    :data:`DEBOUNCE_MS` on a served document, at once on a document without a server session (tests)."""
    from bokeh.layouts import column, row
    from bokeh.models import (
        Checkbox,
        ColorBar,
        ColorPicker,
        ColumnDataSource,
        Div,
        LinearColorMapper,
        Select,
        Slider,
        TextInput,
        Whisker,
    )
    from bokeh.plotting import figure

    from brdflab.errors import BrdflabError
    from brdflab.plugins import bsdf_parameters, build_bsdf, convert_value, parameter_kinds, property_list

    allowed = dict(allowed if allowed is not None else allowed_bsdfs())
    names = list(allowed)
    start = "roughconductor" if "roughconductor" in names else names[0]
    W = dict(width=CONTROLS_W - 10)
    select = Select(title="BSDF", value=start, options=names, name="bsdf", **W)
    theta_i = Slider(title="θ_i [°]", start=0, end=89, step=1, value=45, name="theta_i", **W)
    phi_i = Slider(title="φ_i [°]", start=0, end=360, step=5, value=0, name="phi_i", **W)
    phi_d = Slider(title="slice φ_d [°]", start=0, end=180, step=5, value=90, name="phi_d", **W)
    logscale = Checkbox(label="log scale (polar)", active=True, name="log")
    view_az = Slider(title="lobe view azimuth [°]", start=-180, end=180, step=5, value=-60, name="view_az",
                     width=VIEW_W - 10)
    view_el = Slider(title="lobe view elevation [°]", start=-10, end=90, step=5, value=25, name="view_el",
                     width=VIEW_W - 10)
    status = Div(text="", name="status", width=CONTROLS_W + 3 * VIEW_W)
    params_box = column(name="params")
    #: Server-side truth of every numeric widget: key → (widget, low, high, default).
    numeric: dict[str, tuple[object, float, float, float]] = {
        "theta_i": (theta_i, 0.0, 89.0, 45.0), "phi_i": (phi_i, 0.0, 360.0, 0.0),
        "phi_d": (phi_d, 0.0, 180.0, 90.0), "view_az": (view_az, -180.0, 180.0, -60.0),
        "view_el": (view_el, -10.0, 90.0, 25.0)}
    widgets: dict[str, tuple[str, object]] = {}  # parameter → (kind, widget)
    pickers: dict[str, object] = {}

    polar_src = ColumnDataSource({"x": [], "y": []})
    guide_src = ColumnDataSource({"xs": [], "ys": [], "c": []})
    lobe_src = ColumnDataSource({"xs": [], "ys": [], "c": []})
    axes_src = ColumnDataSource({"xs": [], "ys": [], "c": []})
    slice_src = ColumnDataSource({"image": [np.zeros((2, 2))]})
    alb_src = ColumnDataSource({"t": [], "q": []})
    mc_src = ColumnDataSource({"t": [], "m": [], "lo": [], "hi": []})
    cur_src = ColumnDataSource({"t": [], "q": []})
    pdf_src = ColumnDataSource({"image": [np.zeros((2, 2))]})
    pts_src = ColumnDataSource({"x": [], "y": []})

    tools = "pan,wheel_zoom,reset,save"
    polar = figure(title="plane of incidence (θ_o > 0: away from ω_i)", width=VIEW_W, height=230,
                   x_range=(-1.05, 1.05), y_range=(-0.02, 1.05), match_aspect=True, tools=tools, name="polar")
    polar.multi_line("xs", "ys", color="c", source=guide_src, line_dash="dashed")
    polar.line("x", "y", source=polar_src, line_width=2, color="#1f77b4")
    polar.xaxis.axis_label = "radius ∝ f (log: decades above 10⁻⁴ max)"
    lobe = figure(title="3D lobe f·cos θ_o (shaded)", width=VIEW_W, height=300, match_aspect=True,
                  x_range=(-1.1, 1.1), y_range=(-0.6, 1.1), tools=tools, name="lobe")
    lobe.patches("xs", "ys", fill_color="c", line_color="c", line_width=0.3, source=lobe_src)
    lobe.multi_line("xs", "ys", color="c", line_width=2, source=axes_src)
    lobe.axis.visible = False
    lobe.grid.visible = False
    mapper = LinearColorMapper(palette="Magma256", low=-4, high=0, nan_color="#cccccc")
    sl = figure(title="θ_h × θ_d slice: log₁₀ f (grey: outside)", width=VIEW_W, height=280, x_range=(0, 90),
                y_range=(0, 90),
                tools="hover,reset,save", name="slice")
    sl.image("image", x=0, y=0, dw=90, dh=90, color_mapper=mapper, source=slice_src)
    sl.add_layout(ColorBar(color_mapper=mapper, width=10), "right")
    sl.xaxis.axis_label, sl.yaxis.axis_label = "θ_h [°]", "θ_d [°]"
    alb = figure(title="directional albedo: quadrature, MC ± 2σ", width=VIEW_W, height=230, x_range=(0, 90),
                 tools="pan,reset,save", name="albedo")
    alb.line("t", "q", source=alb_src, line_width=2)
    alb.scatter("t", "m", source=mc_src, size=5, color="#d62728")
    alb.add_layout(Whisker(source=mc_src, base="t", lower="lo", upper="hi", line_color="#d62728"))
    alb.scatter("t", "q", source=cur_src, size=11, marker="diamond", color="black")
    alb.xaxis.axis_label, alb.yaxis.axis_label = "θ_i [°]", "ρ(θ_i)"
    pdf_map = LinearColorMapper(palette="Viridis256", low=0, high=1)
    smp = figure(title=f"{N_SAMPLES} samples over the pdf (disk: ω_o.x, ω_o.y)", width=VIEW_W, height=320,
                 x_range=(-1, 1), y_range=(-1, 1), match_aspect=True, tools=tools, name="samples")
    smp.image("image", x=-1, y=-1, dw=2, dh=2, color_mapper=pdf_map, source=pdf_src)
    smp.scatter("x", "y", source=pts_src, size=2.5, color="white", alpha=0.7)
    smp.add_layout(ColorBar(color_mapper=pdf_map, width=10, title="pdf / max"), "right")

    state: dict[str, object] = {"name": start, "bsdf_key": None, "albedo": None, "lobe": None, "wi": None,
                                "syncing": False}

    def number(key: str) -> float:
        """A numeric widget's value, clamped to the server's range (the client may send anything)."""
        w, lo, hi, default = numeric[key]
        try:
            v = float(w.value)
        except (TypeError, ValueError):
            return default
        return min(max(v, lo), hi) if math.isfinite(v) else default

    def guarded(fn):
        """A widget callback that never raises: an error becomes one escaped status line, no traceback."""
        @functools.wraps(fn)
        def run(*args):
            try:
                fn(*args)
            except BrdflabError as exc:
                status.text = f"<b style='color:#cf222e'>{esc(str(exc)[:300])}</b>"
            except Exception as exc:  # a plugin's own error: say which, keep the traceback on the server
                log.warning("explore: %s raised", state["name"], exc_info=True)
                status.text = (f"<b style='color:#cf222e'>{esc(str(state['name']))} raised "
                               f"{esc(_one_line(exc))}</b>")
        return run

    def current_bsdf():
        name = state["name"]
        cls = allowed[name]
        values = {}
        for key, (kind, w) in widgets.items():
            if kind == "boolean":
                v = bool(w.active) if isinstance(w.active, bool) else False
            elif kind in ("float", "integer"):
                v = number(f"param_{key}")
                v = int(round(v)) if kind == "integer" else v
            else:  # string and colour texts: length-limited, converted by kind
                text = w.value if isinstance(w.value, str) else ""
                if len(text) > MAX_TEXT:
                    raise BrdflabError(f"parameter '{key}': longer than {MAX_TEXT} characters")
                v = convert_value(kind, text, f"parameter '{key}'") if kind == "color" else text
            values[key] = v
        return build_bsdf(cls, property_list(name, values, cls=cls)), values

    def colour_widgets(key: str, default) -> list:
        rgb = np.broadcast_to(np.asarray(default, float), (3,))
        text = TextInput(title=f"{key} (linear r,g,b)", value=",".join(f"{x:.4g}" for x in rgb),
                         name=f"param_{key}", width=CONTROLS_W - 90)
        picker = ColorPicker(title=" ", color=linear_to_hex(rgb), name=f"pick_{key}", width=70)

        def picked(attr, old, new) -> None:
            if state["syncing"]:
                return
            lin = hex_to_linear(new)  # ValueError for a forged value → caught by guarded
            state["syncing"] = True
            try:
                text.value = ",".join(f"{x:.4g}" for x in lin)
            finally:
                state["syncing"] = False
            update()

        def typed(attr, old, new) -> None:
            if state["syncing"]:
                return
            lin = convert_value("color", str(new)[:MAX_TEXT], f"parameter '{key}'")
            state["syncing"] = True
            try:
                picker.color = linear_to_hex(lin)
            finally:
                state["syncing"] = False
            update()

        picker.on_change("color", guarded(picked))
        text.on_change("value", guarded(typed))
        pickers[key] = picker
        widgets[key] = ("color", text)
        return [row(text, picker)]

    def rebuild_params() -> None:
        name = state["name"]
        defaults = bsdf_parameters(name, cls=allowed[name])
        kinds = parameter_kinds(allowed[name])
        widgets.clear()
        pickers.clear()
        for key in [k for k in numeric if k.startswith("param_")]:
            del numeric[key]
        children = []
        for key, default in defaults.items():
            kind = kinds[key]
            if kind == "color":
                children += colour_widgets(key, default)
                continue
            if kind in ("float", "integer"):
                lo, hi, step = _range(key, kind, default)
                v = min(max(float(default), lo), hi)
                w = Slider(title=key, start=lo, end=hi, step=step, value=v, name=f"param_{key}",
                           width=CONTROLS_W - 10)
                numeric[f"param_{key}"] = (w, float(lo), float(hi), v)
                w.on_change("value", updates.on_change)
            elif kind == "boolean":
                w = Checkbox(label=key, active=bool(default), name=f"param_{key}")
                w.on_change("active", updates.on_change)
            else:
                w = TextInput(title=key, value=str(default)[:MAX_TEXT], name=f"param_{key}", width=CONTROLS_W - 10)
                w.on_change("value", updates.on_change)
            widgets[key] = (kind, w)
            children.append(w)
        params_box.children = children

    def draw_lobe() -> None:
        pts, wi = state["lobe"], state["wi"]
        if pts is None:
            return
        az, el = number("view_az"), number("view_el")
        pl = lobe3d.project(pts, az, el)
        lobe_src.data = {"xs": pl.xs.tolist(), "ys": pl.ys.tolist(), "c": lobe3d.shade_colours(pl.shade)}
        ex, ey, _ = lobe3d.view_axes(az, el)
        circle = np.stack([np.cos(np.linspace(0, 2 * np.pi, 73)), np.sin(np.linspace(0, 2 * np.pi, 73)),
                           np.zeros(73)], axis=1)
        n = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
        w = np.array([[0.0, 0.0, 0.0], wi])
        axes_src.data = {"xs": [(circle @ ex).tolist(), (n @ ex).tolist(), (w @ ex).tolist()],
                         "ys": [(circle @ ey).tolist(), (n @ ey).tolist(), (w @ ey).tolist()],
                         "c": ["#bbbbbb", "#777777", "black"]}

    def update() -> None:
        bsdf, values = current_bsdf()
        name = state["name"]
        ti, pi = number("theta_i"), number("phi_i")
        # Plane of incidence.
        t, v = views.polar([bsdf], ti, pi, n=361)
        f = v[0]
        wo_plane = coords.plane_directions(t, pi)
        raw = bsdf.eval(np.ascontiguousarray(np.broadcast_to(coords.incident(ti, pi), wo_plane.shape)), wo_plane)
        if not np.all(np.isfinite(raw)):
            raise BrdflabError(f"{name}: eval returned NaN or infinity in the plane of incidence "
                               f"(θ_i = {ti:g}°); nothing drawn")
        fmax = float(f.max()) if f.max() > 0 else 1.0
        if logscale.active:
            r = np.clip(np.log10(np.maximum(f, 1e-300) / fmax) + 4.0, 0.0, None) / 4.0
        else:
            r = f / fmax
        tr = np.radians(t)
        polar_src.data = {"x": (r * np.sin(tr)).tolist(), "y": (r * np.cos(tr)).tolist()}
        a = math.radians(ti)
        guide_src.data = {"xs": [[0, -math.sin(a)], [0, math.sin(a)]], "ys": [[0, math.cos(a)], [0, math.cos(a)]],
                          "c": ["#777777", "black"]}
        # Lobe: the surface once per material/angle change; the view sliders only re-project it.
        lb = views.lobe([bsdf], ti, pi, n_theta=31, n_phi=61)
        state["lobe"] = lobe3d.surface(lb.directions, lb.values[0] * np.cos(np.radians(lb.theta_o_deg))[:, None])
        wi = coords.incident(ti, pi)
        state["wi"] = wi
        draw_lobe()
        # Slice.
        _, _, sv = views.half_diff_slice([bsdf], number("phi_d"), n=72)
        with np.errstate(divide="ignore", invalid="ignore"):
            lg = np.log10(np.where(np.isfinite(sv[0]) & (sv[0] > 0), sv[0], np.nan))
        top = float(np.nanmax(lg)) if np.isfinite(lg).any() else 0.0
        mapper.low, mapper.high = top - 5, top
        # f = 0 below the colour range (black, as in `brdflab plot`); outside the hemisphere NaN: grey
        slice_src.data = {"image": [np.where(np.isfinite(sv[0]), np.nan_to_num(lg, nan=top - 6), np.nan)]}
        # Albedo (only when the material changed).
        key = (name, tuple(sorted((k, repr(x)) for k, x in values.items())))
        if state["bsdf_key"] != key:
            state["albedo"] = views.albedo([bsdf], THETAS, n=4000, seed=0)
            state["bsdf_key"] = key
            al = state["albedo"]
            alb_src.data = {"t": list(al.theta_deg), "q": al.quadrature[0].tolist()}
            mc_src.data = {"t": list(al.theta_deg), "m": al.monte_carlo[0].tolist(),
                           "lo": (al.monte_carlo[0] - 2 * al.mc_stderr[0]).tolist(),
                           "hi": (al.monte_carlo[0] + 2 * al.mc_stderr[0]).tolist()}
        rho = float(views.albedo_quadrature(bsdf, ti)) if pi == 0 else float("nan")
        cur_src.data = {"t": [ti], "q": [rho if np.isfinite(rho) else float(np.interp(ti, THETAS,
                                                                                          state["albedo"].quadrature[0]))]}
        # Samples over the pdf.
        rng = np.random.default_rng(19)
        wiv = np.ascontiguousarray(np.broadcast_to(wi, (N_SAMPLES, 3)))
        smp_out = bsdf.sample(wiv, rng.random((N_SAMPLES, 3)))
        ok = smp_out.pdf > 0
        pts_src.data = {"x": smp_out.wo[ok, 0].tolist(), "y": smp_out.wo[ok, 1].tolist()}
        g = np.linspace(-1, 1, 81)
        GX, GY = np.meshgrid(g, g)
        rho2 = GX**2 + GY**2
        inside = rho2 < 1
        wo = np.stack([GX.ravel(), GY.ravel(), np.sqrt(np.clip(1 - rho2.ravel(), 0, 1))], axis=1)
        pd = bsdf.pdf(np.ascontiguousarray(np.broadcast_to(wi, wo.shape)), wo).reshape(GX.shape)
        pd = np.where(inside & np.isfinite(pd), pd, 0.0)
        pdf_src.data = {"image": [pd / (pd.max() if pd.max() > 0 else 1.0)]}
        peak = float(t[np.argmax(f)])
        shown = ", ".join(_shown(k, x) for k, x in values.items())
        failed = 100 * (1 - ok.mean())
        status.text = (f"<b>{esc(name)}</b> {esc(shown)} — θ_i = {ti:g}°, φ_i = {pi:g}°: peak f = "
                       f"<span id='peak'>{fmax:.4g}</span> at θ_o = {peak:+.1f}°; ρ(θ_i) = {cur_src.data['q'][0]:.4f}; "
                       f"{failed:.1f} % samples failed<span id='updates' hidden>{updates.runs}</span>")

    if schedule is None:  # a served document: after a burst's last change; no server (tests): at once
        served = getattr(doc, "session_context", None) is not None
        schedule = (lambda cb: doc.add_timeout_callback(cb, DEBOUNCE_MS)) if served else (lambda cb: cb())
    updates = Coalescer(guarded(update), schedule)
    redraws = Coalescer(guarded(draw_lobe), schedule)

    def on_bsdf(attr, old, new) -> None:
        if new == state["name"]:
            return
        if not isinstance(new, str) or new not in allowed:  # a forged choice: refuse, restore, resolve nothing
            select.options = names
            select.value = state["name"]
            status.text = (f"<b style='color:#cf222e'>refused: '{esc(str(new)[:60])}' is not one of the BSDF "
                           "types this explorer was started with</b>")
            return
        state["name"] = new
        rebuild_params()
        updates.request()

    select.on_change("value", guarded(on_bsdf))
    for w in (theta_i, phi_i, phi_d):
        w.on_change("value", updates.on_change)
    for w in (view_az, view_el):
        w.on_change("value", redraws.on_change)
    logscale.on_change("active", updates.on_change)
    guarded(rebuild_params)()
    guarded(update)()
    controls = column(Div(text="<h3 style='margin:4px 0'>brdflab explore</h3>"), select, theta_i, phi_i, phi_d,
                      logscale, Div(text="<b>parameters</b>"), params_box, width=CONTROLS_W)
    doc.add_root(column(status, row(controls, column(polar, alb, smp), column(lobe, view_az, view_el), column(sl))))
    doc.title = "brdflab explore"


def _shown(key: str, value) -> str:
    if isinstance(value, float):
        return f"{key}={value:g}"
    if isinstance(value, np.ndarray):
        return f"{key}=(" + ", ".join(f"{x:.3g}" for x in value) + ")"
    return f"{key}={value}"


def serve(port: int = 5006, open_browser: bool = True, say=print) -> None:
    """Serve the explorer on http://127.0.0.1:``port``/ until a signal stops it.

    The BSDF allow-list is resolved here, before the first connection. Ctrl-C, SIGTERM and SIGHUP stop the
    server cleanly and raise :class:`brdflab.errors.Interrupted` (exit status 128 + the signal number).
    """
    import signal

    from bokeh.application import Application
    from bokeh.application.handlers.function import FunctionHandler
    from bokeh.server.server import Server

    from brdflab.errors import BrdflabError, Interrupted

    allowed = allowed_bsdfs()
    if not allowed:
        raise BrdflabError("no BSDF type to explore")
    _no_tracebacks_to_clients()
    one_line_logs()
    origins = [f"127.0.0.1:{port}", f"localhost:{port}"]
    server = Server({"/": Application(FunctionHandler(functools.partial(make_document, allowed=allowed)))},
                    port=port, address="127.0.0.1", allow_websocket_origin=origins, num_procs=1)
    server.start()
    url = f"http://127.0.0.1:{server.port}/"
    say(f"brdflab explore: serving {url} (Ctrl-C to stop)", flush=True)
    loop = server.io_loop
    received: list[int] = []

    def stop(signum, frame):
        received.append(signum)
        loop.add_callback_from_signal(loop.stop)

    handled = [s for s in (getattr(signal, n, None) for n in ("SIGINT", "SIGTERM", "SIGHUP")) if s is not None]
    previous = {s: signal.signal(s, stop) for s in handled}
    if open_browser:
        loop.add_callback(server.show, "/")
    try:
        loop.start()
    except KeyboardInterrupt:
        received.append(signal.SIGINT)
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
        server.stop()
    if received:
        raise Interrupted(received[0], "explorer stopped")
