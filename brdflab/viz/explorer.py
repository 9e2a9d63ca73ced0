"""``brdflab explore``: the BRDF views live in a browser, on a local Bokeh server (127.0.0.1 only).

One page holds the BSDF choice, sliders for θ_i, φ_i and every parameter of the chosen BSDF (floats and
integers as sliders, each with a box to type a value — validated: bad input is a status line, nothing changes —,
colours as a colour picker beside the linear r,g,b values, booleans, strings), up to two more materials to compare
with (each with its own parameters), and six linked views (:mod:`brdflab.viz.explorer_views`) recomputed by the
NumPy core of :mod:`brdflab.viz.views` whenever a widget changes:

* the plane of incidence (f, linear or log) with ω_i and the mirror direction, every material overlaid in its own
  colour and dash; the whole circle when one transmits; delta lobes as spikes;
* the 3D lobe f·|cos θ_o| ω_o as a shaded surface (:mod:`brdflab.viz.lobe3d`), turned by two view sliders;
* the θ_h × θ_d slice at a chosen φ_d (log₁₀ f with a colour bar);
* the directional albedo against θ_i (quadrature, Monte Carlo ± 2σ; R and T apart when one transmits), the
  current θ_i marked;
* 2000 directions drawn by the BSDF's own ``sample`` over its ``pdf`` (both projected onto the unit disk,
  (x, y) = (ω_o.x, ω_o.y), as Nori's warptest does), with the fraction of failed samples;
* the lit spheres of every material (a preview at once, refined in the background: :mod:`brdflab.viz.sphere`).

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
from types import SimpleNamespace

import numpy as np

from brdflab.viz.coalesce import DEBOUNCE_MS, QUIET_MS, Coalescer
from brdflab.viz.explorer_choices import Alternatives, as_rgb_text, handled
from brdflab.viz.explorer_views import (
    CONTROLS_W,
    MAX_MATERIALS,
    PREVIEW,
    REFINED,
    VIEW_W,
    Material,
    Views,
    sphere_images,
)
from brdflab.viz.server_safety import _no_tracebacks_to_clients, one_line_logs

#: Longest text a string parameter may carry (a client can send anything).
MAX_TEXT = 200
#: The choice of no material in a "compare with" slot.
NONE = "(none)"
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


class _Slot:
    """One material's controls: its type choice and a box of parameter widgets (slot 1 is the edited one)."""

    def __init__(self, index: int, select, box) -> None:
        self.index, self.select, self.box = index, select, box
        self.prefix = "param_" if index == 1 else f"param{index}_"
        self.name: str | None = select.value if index == 1 else None
        self.widgets: dict[str, tuple[str, object]] = {}  # parameter → (kind, widget)
        self.alt = None  # the choice and alternative widgets (:mod:`brdflab.viz.explorer_choices`)


def make_document(doc, allowed: dict[str, type] | None = None, schedule=None, background=None) -> None:
    """Build the explorer into a Bokeh document (one per browser tab) offering the types of ``allowed``.

    ``schedule(callback)`` runs a coalesced update later (:class:`Coalescer`); by default a timeout of
    :data:`DEBOUNCE_MS` on a served document, at once on a document without a server session (tests).
    ``background(job, done)`` runs the refined lit sphere: ``job()`` in a worker thread (it watches its own stop
    event, set by the next change), then ``done(result)`` on the document's thread; by default a thread on a
    served document, nothing without a server (tests inject their own)."""
    from bokeh.layouts import column, row
    from bokeh.models import Checkbox, ColorPicker, Div, Select, Slider, TextInput

    from brdflab.errors import BrdflabError
    from brdflab.plugins import bsdf_parameters, build_bsdf, convert_value, parameter_kinds, property_list

    allowed = dict(allowed if allowed is not None else allowed_bsdfs())
    names = list(allowed)
    start = "roughconductor" if "roughconductor" in names else names[0]
    W = dict(width=CONTROLS_W - 10)
    SW, TW = CONTROLS_W - 86, 66  # a slider and its typed-value box side by side
    status = Div(text="", name="status", width=CONTROLS_W + 3 * VIEW_W)
    state: dict[str, object] = {"syncing": False, "stop": None, "gen": 0}
    #: Server-side truth of every numeric widget: key → (widget, low, high, default, integer).
    numeric: dict[str, tuple[object, float, float, float, bool]] = {}

    def say(text: str) -> None:
        status.text = f"<b style='color:#cf222e'>{esc(text[:300])}</b>"

    def guarded(fn):
        """A widget callback that never raises: an error becomes one escaped status line, no traceback."""
        @functools.wraps(fn)
        def run(*args):
            try:
                fn(*args)
            except BrdflabError as exc:
                say(str(exc))
            except Exception as exc:  # a plugin's own error: say which, keep the traceback on the server
                log.warning("explore: %s raised", slots[0].name, exc_info=True)
                status.text = (f"<b style='color:#cf222e'>{esc(str(slots[0].name))} raised "
                               f"{esc(_one_line(exc))}</b>")
        return run

    def number(key: str) -> float:
        """A numeric widget's value, clamped to the server's range (the client may send anything)."""
        w, lo, hi, default, _ = numeric[key]
        try:
            v = float(w.value)
        except (TypeError, ValueError):
            return default
        return min(max(v, lo), hi) if math.isfinite(v) else default

    def slider(key: str, title: str, lo: float, hi: float, step: float, value: float, integer: bool = False,
               on_change=None):
        """A slider with a typed-value box beside it; the box is validated (a clear status line for bad input,
        nothing changes) and both show the same value."""
        fmt = "0[.]0000" if step < 0.01 else "0[.]00"
        w = Slider(title=title, start=lo, end=hi, step=step, value=value, name=key, width=SW, format=fmt)
        box = TextInput(value=f"{value:g}", name=f"typed_{key}", width=TW, title=" ")
        numeric[key] = (w, float(lo), float(hi), float(value), integer)

        def typed(attr, old, new) -> None:
            if state["syncing"]:
                return
            text = str(new).strip()[:40]
            try:
                v = float(text)
            except ValueError:
                v = float("nan")
            if not (math.isfinite(v) and lo <= v <= hi) or (integer and v != int(v)):
                kind = "an integer" if integer else "a number"
                say(f"{title}: type {kind} from {lo:g} to {hi:g} (got '{text}'); nothing changed")
                return
            w.value = int(v) if integer else v

        def moved(attr, old, new) -> None:
            state["syncing"] = True
            try:
                box.value = f"{number(key):.6g}"
            finally:
                state["syncing"] = False

        w.on_change("value", moved, on_change or updates.on_change)
        box.on_change("value", guarded(typed))
        return w, row(w, box)

    def colour_widgets(slot: _Slot, key: str, default) -> list:
        rgb = np.broadcast_to(np.asarray(default, float), (3,))
        text = TextInput(title=f"{key} (linear r,g,b)", value=",".join(f"{x:.4g}" for x in rgb),
                         name=f"{slot.prefix}{key}", width=CONTROLS_W - 90)
        pick_name = f"pick_{key}" if slot.index == 1 else f"pick{slot.index}_{key}"
        picker = ColorPicker(title=" ", color=linear_to_hex(rgb), name=pick_name, width=70)

        def picked(attr, old, new) -> None:
            if state["syncing"]:
                return
            lin = hex_to_linear(new)  # ValueError for a forged value → caught by guarded
            state["syncing"] = True
            try:
                text.value = ",".join(f"{x:.4g}" for x in lin)
            finally:
                state["syncing"] = False
            updates.request()

        def typed(attr, old, new) -> None:
            if state["syncing"]:
                return
            lin = convert_value("color", str(new)[:MAX_TEXT], f"parameter '{key}'")
            state["syncing"] = True
            try:
                picker.color = linear_to_hex(lin)
            finally:
                state["syncing"] = False
            updates.request()

        picker.on_change("color", guarded(picked))
        text.on_change("value", guarded(typed))
        slot.widgets[key] = ("color", text)
        return [row(text, picker)]

    def rebuild_params(slot: _Slot) -> None:
        for key in [k for k in numeric if k.startswith(slot.prefix)]:
            del numeric[key]
        slot.widgets.clear()
        if slot.name is None:
            slot.box.children = []
            return
        defaults = bsdf_parameters(slot.name, cls=allowed[slot.name])
        kinds = parameter_kinds(allowed[slot.name])
        children = []
        slot.alt = alt = Alternatives(slot.prefix, kinds, defaults, tools(slot)) if handled(kinds) else None
        for key, default in defaults.items():
            if alt is not None and key in alt.keys:  # a dropdown, a link or one of alternatives
                children += alt.build(key)
                continue
            if default is None:  # an optional parameter without a value (roughconductor's alpha_u, eta …)
                continue
            kind = kinds[key]
            if kind == "color":
                children += colour_widgets(slot, key, default)
                continue
            if kind in ("float", "integer"):
                lo, hi, step = _range(key, kind, default)
                w, box = slider(f"{slot.prefix}{key}", key, lo, hi, step, min(max(float(default), lo), hi),
                                kind == "integer")
                children.append(box)
            elif kind == "boolean":
                w = Checkbox(label=key, active=bool(default), name=f"{slot.prefix}{key}")
                w.on_change("active", updates.on_change)
                children.append(w)
            else:
                w = TextInput(title=key, value=str(default)[:MAX_TEXT], name=f"{slot.prefix}{key}", **W)
                w.on_change("value", updates.on_change)
                children.append(w)
            slot.widgets[key] = (kind, w)
        slot.widgets.update(alt.widgets if alt is not None else {})
        slot.box.children = children

    def tools(slot: _Slot) -> SimpleNamespace:
        """The widget makers and callbacks :class:`~brdflab.viz.explorer_choices.Alternatives` builds with."""
        return SimpleNamespace(slider=slider, colour=functools.partial(colour_widgets, slot), guarded=guarded,
                               take=slot.widgets.__getitem__, request=lambda: updates.request(), number=number,
                               on_change=lambda attr, old, new: updates.on_change(attr, old, new),
                               width=CONTROLS_W - 10, set_colour=lambda w, rgb: setattr(w, "value", as_rgb_text(rgb)))

    def material(slot: _Slot) -> Material:
        cls = allowed[slot.name]
        values = {}
        for key, (kind, w) in slot.widgets.items():
            if kind == "boolean":
                v = bool(w.active) if isinstance(w.active, bool) else False
            elif kind in ("float", "integer"):
                v = number(f"{slot.prefix}{key}")
                v = int(round(v)) if kind == "integer" else v
            else:  # string and colour texts: length-limited, converted by kind
                text = w.value if isinstance(w.value, str) else ""
                if len(text) > MAX_TEXT:
                    raise BrdflabError(f"parameter '{key}': longer than {MAX_TEXT} characters")
                v = convert_value(kind, text, f"parameter '{key}'") if kind == "color" else text
            values[key] = v
        if slot.alt is not None:
            slot.alt.adjust(values)
        shown = " ".join(_shown(k, x) for k, x in values.items() if not isinstance(x, np.ndarray))  # no colours
        return Material(slot.name, build_bsdf(cls, property_list(slot.name, values, cls=cls)), values,
                        f"{slot.name} {shown}".strip())

    def update() -> None:
        mats = [material(s) if s.name is not None else None for s in slots]
        ti, pi = number("theta_i"), number("phi_i")
        out = views_.update(mats, ti, pi, number("phi_d"), bool(logscale.active))
        views_.draw_lobe(number("view_az"), number("view_el"))
        spheres(mats)
        first = mats[0]
        shown = ", ".join(_shown(k, x) for k, x in first.values.items())
        others = "".join(f" · {k + 1}: {esc(m.label)}" for k, m in enumerate(mats) if k and m is not None)
        peak = ("delta lobes only" if out["delta"] else
                f"peak f = <span id='peak'>{out['fmax']:.4g}</span> at θ_o = {out['peak']:+.1f}°")
        status.text = (f"<b>{esc(first.name)}</b> {esc(shown)} — θ_i = {ti:g}°, φ_i = {pi:g}°: {peak}; ρ(θ_i) = "
                       f"{out['rho']:.4f}; {out['failed']:.1f} % samples failed{others}"
                       f"<span id='updates' hidden>{updates.runs}</span>")

    def spheres(mats: list[Material | None]) -> None:
        """The preview sphere now; the refined one in the background, dropped if another update came first."""
        stop_refine()
        state["gen"] += 1
        bsdfs = [m.bsdf for m in mats if m is not None]
        numbers = [k + 1 for k, m in enumerate(mats) if m is not None]
        views_.show_spheres(sphere_images(bsdfs, PREVIEW, paths=False), numbers,
                            "preview (refining…)" if background else "preview, direct light")
        if background is None:
            return
        import threading

        gen, stop = state["gen"], threading.Event()
        state["stop"] = stop

        def done(images) -> None:
            if images is not None and gen == state["gen"]:
                views_.show_spheres(images, numbers, f"{REFINED[1]} / {REFINED[2]} spp")

        background(lambda: sphere_images(bsdfs, REFINED, stop), guarded(done))

    quiet = 0.0
    if schedule is None:  # a served document: after a burst's last change; no server (tests): at once
        served = getattr(doc, "session_context", None) is not None
        schedule = (lambda cb: doc.add_timeout_callback(cb, DEBOUNCE_MS)) if served else (lambda cb: cb())
        quiet = QUIET_MS if served else 0.0
        if served and background is None:
            background = _threaded(doc)

    def stop_refine() -> None:
        if state["stop"] is not None:
            state["stop"].set()  # a change came: the background sphere is stale, free the CPU for the update

    updates = Coalescer(guarded(update), schedule, quiet, on_request=stop_refine)
    redraws = Coalescer(guarded(lambda: views_.draw_lobe(number("view_az"), number("view_el"))), schedule, quiet)

    views_ = Views()
    theta_i, theta_row = slider("theta_i", "θ_i [°]", 0, 89, 1, 45)
    phi_i, phi_row = slider("phi_i", "φ_i [°]", 0, 360, 5, 0)
    phi_d, phi_d_row = slider("phi_d", "slice φ_d [°]", 0, 180, 5, 90)
    view_az, _ = slider("view_az", "lobe view azimuth [°]", -180, 180, 5, -60, on_change=redraws.on_change)
    view_el, _ = slider("view_el", "lobe view elevation [°]", -10, 90, 5, 25, on_change=redraws.on_change)
    view_az.width = view_el.width = VIEW_W - 10
    logscale = Checkbox(label="log scale (polar)", active=True, name="log")
    logscale.on_change("active", updates.on_change)
    slots = [_Slot(1, Select(title="BSDF 1 (edited)", value=start, options=names, name="bsdf", **W),
                   column(name="params"))]
    slots += [_Slot(k, Select(title=f"compare with {k}", value=NONE, options=[NONE, *names], name=f"bsdf_{k}", **W),
                    column(name=f"params_{k}")) for k in range(2, MAX_MATERIALS + 1)]

    def chose(slot: _Slot, attr, old, new) -> None:
        current = slot.name if slot.name is not None else NONE
        if new == current:
            return
        if not isinstance(new, str) or (new not in allowed and not (slot.index > 1 and new == NONE)):
            # a forged choice: refuse, restore, resolve nothing
            slot.select.options = names if slot.index == 1 else [NONE, *names]
            slot.select.value = current
            status.text = (f"<b style='color:#cf222e'>refused: '{esc(str(new)[:60])}' is not one of the BSDF "
                           "types this explorer was started with</b>")
            return
        slot.name = None if new == NONE else new
        rebuild_params(slot)
        updates.request()

    for s in slots:
        s.select.on_change("value", guarded(functools.partial(chose, s)))
        guarded(rebuild_params)(s)
    guarded(update)()
    controls = column(Div(text="<h3 style='margin:4px 0'>brdflab explore</h3>"), slots[0].select, theta_row,
                      phi_row, phi_d_row, logscale, Div(text="<b>parameters of 1</b>"), slots[0].box,
                      *(c for s in slots[1:] for c in (s.select, s.box)), width=CONTROLS_W)
    doc.add_root(column(status, views_.layout(controls, view_az, view_el)))
    doc.title = "brdflab explore"


def _threaded(doc):
    """``background(job, done)`` of a served document: ``job()`` in one worker thread per document, its result
    handed to ``done`` on the document's thread; the thread ends with the session."""
    from concurrent.futures import ThreadPoolExecutor

    pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="brdflab-sphere")

    def run(job, done) -> None:
        def finished(fut) -> None:
            try:
                result = fut.result()
            except Exception as exc:  # a plugin raising inside the render: one line in the log
                log.warning("explore: the lit sphere's render raised %s", _one_line(exc))
                return
            try:
                doc.add_next_tick_callback(lambda: done(result))
            except Exception:  # the session is gone
                pass

        pool.submit(job).add_done_callback(finished)

    doc.on_session_destroyed(lambda ctx: pool.shutdown(wait=False, cancel_futures=True))
    return run


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
