"""``brdflab explore``: the BRDF views live in a browser, on a local Bokeh server (127.0.0.1 only).

One page holds the BSDF choice (built-ins and every registered plugin), sliders for θ_i, φ_i and every
parameter of the chosen BSDF (from the registry: colours as one grey level, floats, integers, booleans,
strings), and five linked views recomputed by the NumPy core of :mod:`brdflab.viz.views` whenever a
widget changes:

* the plane of incidence (f, linear or log) with ω_i and the mirror direction;
* the 3D lobe f·cos θ_o ω_o as an orthographic wireframe;
* the θ_h × θ_d slice at a chosen φ_d (log₁₀ f with a colour bar);
* the directional albedo against θ_i (quadrature, Monte Carlo ± 2σ), the current θ_i marked;
* 2000 directions drawn by the BSDF's own ``sample`` over its ``pdf`` (both projected onto the unit disk,
  (x, y) = (ω_o.x, ω_o.y), as Nori's warptest does), with the fraction of failed samples.

A status line sums up the current state (peak of f, albedo) — the browser test reads it.

Bokeh serves its JavaScript from the installed Python package (no CDN, works offline); the server binds
only 127.0.0.1 and accepts websocket connections from that origin only.
"""

from __future__ import annotations

import math
from html import escape as esc

import numpy as np

from brdflab.viz import coords, views

#: Albedo curve angles of the explorer (fewer than ``brdflab plot``, so that it stays interactive).
THETAS = tuple(float(t) for t in range(0, 90, 8))
N_SAMPLES = 2000


def _range(name: str, kind: str, default) -> tuple[float, float, float]:
    """(start, end, step) of a parameter slider, guessed from its name and default."""
    d = float(np.mean(default)) if kind == "color" else float(default)
    low = name.lower()
    if low == "alpha":
        return 0.002, 1.0, 0.002
    if "ior" in low or low in ("eta", "n"):
        return 1.0, 3.0, 0.01
    if kind == "color" or low in ("r0", "kd", "ks", "albedo", "reflectance"):
        return 0.0, 1.0, 0.01
    if kind == "integer":
        return 0, max(10, 2 * int(d)), 1
    hi = max(1.0, 2.0 * abs(d))
    return 0.0, hi, hi / 200


def bsdf_choices() -> list[str]:
    """Every registered BSDF type, built-ins first."""
    from brdflab.plugins import bsdf_names

    return list(bsdf_names())


def make_document(doc) -> None:
    """Build the explorer into a Bokeh document (one per browser tab)."""
    from bokeh.layouts import column, row
    from bokeh.models import (
        Checkbox,
        ColorBar,
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
    from brdflab.plugins import bsdf_class, bsdf_parameters, make_bsdf, parameter_kinds

    names = bsdf_choices()
    start = "roughconductor" if "roughconductor" in names else names[0]
    select = Select(title="BSDF", value=start, options=names, name="bsdf", width=220)
    theta_i = Slider(title="θ_i [°]", start=0, end=89, step=1, value=45, name="theta_i", width=220)
    phi_i = Slider(title="φ_i [°]", start=0, end=360, step=5, value=0, name="phi_i", width=220)
    phi_d = Slider(title="slice φ_d [°]", start=0, end=180, step=5, value=90, name="phi_d", width=220)
    log = Checkbox(label="log scale (polar)", active=True, name="log")
    status = Div(text="", name="status", width=900)
    params_box = column(name="params")
    widgets: dict[str, object] = {}

    polar_src = ColumnDataSource({"x": [], "y": []})
    guide_src = ColumnDataSource({"xs": [], "ys": [], "c": []})
    lobe_src = ColumnDataSource({"xs": [], "ys": []})
    slice_src = ColumnDataSource({"image": [np.zeros((2, 2))]})
    alb_src = ColumnDataSource({"t": [], "q": []})
    mc_src = ColumnDataSource({"t": [], "m": [], "lo": [], "hi": []})
    cur_src = ColumnDataSource({"t": [], "q": []})
    pdf_src = ColumnDataSource({"image": [np.zeros((2, 2))]})
    pts_src = ColumnDataSource({"x": [], "y": []})

    polar = figure(title="plane of incidence (θ_o signed: + opposite ω_i)", width=430, height=260,
                   x_range=(-1.05, 1.05), y_range=(-0.02, 1.05), match_aspect=True, tools="pan,wheel_zoom,reset,save",
                   name="polar")
    polar.multi_line("xs", "ys", color="c", source=guide_src, line_dash="dashed")
    polar.line("x", "y", source=polar_src, line_width=2, color="#1f77b4")
    polar.xaxis.axis_label = "radius ∝ f (log: decades above 10⁻⁴ max)"
    lobe = figure(title="3D lobe f·cos θ_o (orthographic)", width=430, height=300, match_aspect=True,
                  tools="pan,wheel_zoom,reset,save", name="lobe")
    lobe.multi_line("xs", "ys", source=lobe_src, line_width=0.7, color="#2ca02c")
    lobe.axis.visible = False
    mapper = LinearColorMapper(palette="Magma256", low=-4, high=0)
    sl = figure(title="θ_h × θ_d slice: log₁₀ f", width=430, height=330, x_range=(0, 90), y_range=(0, 90),
                tools="hover,reset,save", name="slice")
    sl.image("image", x=0, y=0, dw=90, dh=90, color_mapper=mapper, source=slice_src)
    sl.add_layout(ColorBar(color_mapper=mapper, width=10), "right")
    sl.xaxis.axis_label, sl.yaxis.axis_label = "θ_h [°]", "θ_d [°]"
    alb = figure(title="directional albedo: quadrature, MC ± 2σ", width=430, height=260, x_range=(0, 90),
                 tools="pan,reset,save", name="albedo")
    alb.line("t", "q", source=alb_src, line_width=2)
    alb.scatter("t", "m", source=mc_src, size=5, color="#d62728")
    alb.add_layout(Whisker(source=mc_src, base="t", lower="lo", upper="hi", line_color="#d62728"))
    alb.scatter("t", "q", source=cur_src, size=11, marker="diamond", color="black")
    alb.xaxis.axis_label, alb.yaxis.axis_label = "θ_i [°]", "ρ(θ_i)"
    pdf_map = LinearColorMapper(palette="Viridis256", low=0, high=1)
    smp = figure(title=f"{N_SAMPLES} samples over the pdf (disk: ω_o.x, ω_o.y)", width=430, height=400,
                 x_range=(-1, 1), y_range=(-1, 1), match_aspect=True, tools="pan,wheel_zoom,reset,save",
                 name="samples")
    smp.image("image", x=-1, y=-1, dw=2, dh=2, color_mapper=pdf_map, source=pdf_src)
    smp.scatter("x", "y", source=pts_src, size=2.5, color="white", alpha=0.7)
    smp.add_layout(ColorBar(color_mapper=pdf_map, width=10, title="pdf / max"), "right")

    state = {"bsdf_key": None, "albedo": None}

    def current_bsdf():
        name = select.value
        kinds = parameter_kinds(bsdf_class(name))
        values = {}
        for key, w in widgets.items():
            v = w.active if isinstance(w, Checkbox) else w.value
            if kinds.get(key) == "integer":
                v = int(v)
            values[key] = v
        return make_bsdf(name, values), values

    def rebuild_params() -> None:
        name = select.value
        defaults = bsdf_parameters(name)
        kinds = parameter_kinds(bsdf_class(name))
        widgets.clear()
        children = []
        for key, default in defaults.items():
            kind = kinds[key]
            if kind in ("float", "integer", "color"):
                lo, hi, step = _range(key, kind, default)
                v = float(np.mean(default)) if kind == "color" else float(default)
                title = f"{key}" + (" (grey)" if kind == "color" else "")
                w = Slider(title=title, start=lo, end=hi, step=step, value=min(max(v, lo), hi), name=f"param_{key}",
                           width=220)
                w.on_change("value", lambda attr, old, new: update())
            elif kind == "boolean":
                w = Checkbox(label=key, active=bool(default), name=f"param_{key}")
                w.on_change("active", lambda attr, old, new: update())
            else:
                w = TextInput(title=key, value=str(default), name=f"param_{key}", width=220)
                w.on_change("value", lambda attr, old, new: update())
            widgets[key] = w
            children.append(w)
        params_box.children = children

    def update() -> None:
        try:
            bsdf, values = current_bsdf()
        except BrdflabError as exc:
            status.text = f"<b style='color:#cf222e'>{esc(str(exc))}</b>"
            return
        ti, pi = float(theta_i.value), float(phi_i.value)
        # Plane of incidence.
        t, v = views.polar([bsdf], ti, pi, n=361)
        f = v[0]
        fmax = float(f.max()) if f.max() > 0 else 1.0
        if log.active:
            r = np.clip(np.log10(np.maximum(f, 1e-300) / fmax) + 4.0, 0.0, None) / 4.0
        else:
            r = f / fmax
        tr = np.radians(t)
        polar_src.data = {"x": (r * np.sin(tr)).tolist(), "y": (r * np.cos(tr)).tolist()}
        a = math.radians(ti)
        guide_src.data = {"xs": [[0, -math.sin(a)], [0, math.sin(a)]], "ys": [[0, math.cos(a)], [0, math.cos(a)]],
                          "c": ["#777777", "black"]}
        # Lobe, orthographic projection (elevation 25°, azimuth −60°).
        lb = views.lobe([bsdf], ti, pi, n_theta=19, n_phi=37)
        rr = lb.values[0] * np.cos(np.radians(lb.theta_o_deg))[:, None]
        rr = rr / (rr.max() if rr.max() > 0 else 1.0)
        p = lb.directions * rr[..., None]
        az, el = math.radians(-60), math.radians(25)
        ex = np.array([math.cos(az), math.sin(az), 0.0])
        ey = np.array([-math.sin(az) * math.sin(el), math.cos(az) * math.sin(el), math.cos(el)])
        X, Y = p @ ex, p @ ey
        xs = [row.tolist() for row in X] + [col.tolist() for col in X.T]
        ys = [row.tolist() for row in Y] + [col.tolist() for col in Y.T]
        wi = coords.incident(ti, pi)
        xs.append([0.0, float(wi @ ex)])
        ys.append([0.0, float(wi @ ey)])
        lobe_src.data = {"xs": xs, "ys": ys}
        # Slice.
        _, _, sv = views.half_diff_slice([bsdf], float(phi_d.value), n=72)
        lg = np.log10(np.where(np.isfinite(sv[0]) & (sv[0] > 0), sv[0], np.nan))
        top = float(np.nanmax(lg)) if np.isfinite(lg).any() else 0.0
        mapper.low, mapper.high = top - 5, top
        slice_src.data = {"image": [np.nan_to_num(lg, nan=top - 6)]}
        # Albedo (only when the material changed).
        key = (select.value, tuple(sorted((k, repr(x)) for k, x in values.items())))
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
        shown = ", ".join(f"{k}={x:g}" if isinstance(x, float) else f"{k}={x}" for k, x in values.items())
        failed = 100 * (1 - ok.mean())
        status.text = (f"<b>{esc(select.value)}</b> {esc(shown)} — θ_i = {ti:g}°, φ_i = {pi:g}°: peak f = "
                       f"<span id='peak'>{fmax:.4g}</span> at θ_o = {peak:+.1f}°; ρ(θ_i) = {cur_src.data['q'][0]:.4f}; "
                       f"{failed:.1f} % samples failed")

    def on_bsdf(attr, old, new) -> None:
        rebuild_params()
        update()

    select.on_change("value", on_bsdf)
    for w in (theta_i, phi_i, phi_d):
        w.on_change("value", lambda attr, old, new: update())
    log.on_change("active", lambda attr, old, new: update())
    rebuild_params()
    update()
    controls = column(Div(text="<h3 style='margin:4px 0'>brdflab explore</h3>"), select, theta_i, phi_i, phi_d, log,
                      Div(text="<b>parameters</b>"), params_box, width=240)
    doc.add_root(column(status, row(controls, column(polar, alb), column(lobe, sl), smp)))
    doc.title = "brdflab explore"


def serve(port: int = 5006, open_browser: bool = True, say=print) -> None:
    """Serve the explorer on http://127.0.0.1:``port``/ until interrupted (Ctrl-C or SIGTERM)."""
    import signal

    from bokeh.application import Application
    from bokeh.application.handlers.function import FunctionHandler
    from bokeh.server.server import Server

    origins = [f"127.0.0.1:{port}", f"localhost:{port}"]
    server = Server({"/": Application(FunctionHandler(make_document))}, port=port, address="127.0.0.1",
                    allow_websocket_origin=origins, num_procs=1)
    server.start()
    url = f"http://127.0.0.1:{server.port}/"
    say(f"brdflab explore: serving {url} (Ctrl-C to stop)", flush=True)
    loop = server.io_loop

    def stop(*_):
        loop.add_callback_from_signal(loop.stop)

    signal.signal(signal.SIGTERM, stop)
    if open_browser:
        loop.add_callback(server.show, "/")
    try:
        loop.start()
    except KeyboardInterrupt:
        pass
    finally:
        server.stop()
