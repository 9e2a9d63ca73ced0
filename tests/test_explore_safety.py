"""The explorer trusts nothing its browser sends (issue 28): a forged BSDF choice is refused and never reaches
the plugin loader, numbers are clamped to the server's ranges, texts are bounded, a plugin's error becomes one
status line, Bokeh's protocol errors carry no traceback, and a signal stops the server with 128 + signum.

The in-process tests drive the Bokeh document directly (server-side callbacks run on every property change);
one test speaks Bokeh's real websocket protocol to a running ``brdflab explore`` as a hostile local program
would."""

from __future__ import annotations

import signal
import socket
import subprocess
import sys
import time
import urllib.request

import numpy as np
import pytest

pytest.importorskip("bokeh")

from bokeh.document import Document  # noqa: E402

from brdflab.viz import explorer as explore  # noqa: E402
from brdflab.viz import lobe3d  # noqa: E402

EVIL = "open({marker!r}, 'w').write('ran')\n"


def _doc(allowed=None):
    doc = Document()
    explore.make_document(doc, allowed)
    return doc, doc.get_model_by_name


@pytest.fixture()
def evil_plugin(tmp_path):
    marker = tmp_path / "PWNED"
    path = tmp_path / "evil.py"
    path.write_text(EVIL.format(marker=str(marker)))
    return path, marker


def test_forged_bsdf_choice_is_refused_and_never_loaded(evil_plugin, monkeypatch):
    import brdflab.plugins as plugins

    path, marker = evil_plugin
    calls = []
    monkeypatch.setattr(plugins, "load_plugin", lambda spec: calls.append(spec) or [])
    doc, g = _doc()
    before = g("status").text
    for forged in (f"{path}:x", "os:system", "subprocess:Popen", "roughconductor ", "", "x" * 10_000):
        g("bsdf").value = forged
        assert g("bsdf").value == "roughconductor"  # restored
        assert "refused" in g("status").text and "not one of the BSDF types" in g("status").text
        assert len(g("status").text) < 400
    # options forged too: still refused, and the real options are restored
    g("bsdf").options = ["os:system"]
    g("bsdf").value = "os:system"
    assert g("bsdf").options == list(explore.allowed_bsdfs())
    assert not marker.exists() and calls == []
    g("bsdf").value = "diffuse"  # a real choice still works
    assert g("status").text.startswith("<b>diffuse</b>") and g("status").text != before


def test_allow_list_is_resolved_once_at_start(monkeypatch):
    import brdflab.plugins as plugins

    allowed = {"roughconductor": plugins.bsdf_class("roughconductor")}
    doc, g = _doc(allowed)
    assert g("bsdf").options == ["roughconductor"]
    g("bsdf").value = "diffuse"  # registered, but not offered by this server
    assert g("bsdf").value == "roughconductor" and "refused" in g("status").text
    monkeypatch.setattr(plugins, "bsdf_class", lambda name: pytest.fail(f"looked up {name!r} after start"))
    g("param_alpha").value = 0.3
    assert "alpha=0.3" in g("status").text


def test_numbers_are_clamped_to_the_servers_range():
    doc, g = _doc()
    for value, shown in [(1e-12, "alpha=0.002"), (float("nan"), "alpha=0.1"), (5.0, "alpha=1,"),
                         (float("inf"), "alpha=0.1"), (0.2, "alpha=0.2")]:
        g("param_alpha").value = 0.1
        g("param_alpha").value = value
        assert shown in g("status").text, value


def test_angles_are_clamped():
    doc, g = _doc()
    g("theta_i").value = 1e9
    assert "θ_i = 89°" in g("status").text
    g("phi_i").value = -1e300
    assert "φ_i = 0°" in g("status").text


def test_texts_are_bounded_and_colours_converted():
    doc, g = _doc()
    g("param_R0").value = "x" * 100_000
    text = g("status").text
    assert "expected a colour" in text and len(text) < 400
    g("param_R0").value = "0.9,0.8,0.7"
    assert g("pick_R0").color == explore.linear_to_hex([0.9, 0.8, 0.7])
    assert "R0=(0.9, 0.8, 0.7)" in g("status").text
    g("pick_R0").color = "#ff0000"
    assert g("param_R0").value == "1,0,0" and "R0=(1, 0, 0)" in g("status").text
    g("pick_R0").color = "red"  # a named colour is valid Bokeh but not ours: refused, nothing changes
    assert "expected #rrggbb" in g("status").text or "R0=(1, 0, 0)" in g("status").text


def test_a_raising_or_nan_plugin_gets_one_status_line(tmp_path):
    import brdflab as bl
    from brdflab.plugins import register_bsdf, unregister_bsdf

    class Raises(bl.BSDF):
        type_name = "explore_raises"

        def __init__(self, k: float = 1.0):
            self.k = k

        def eval(self, wi, wo):
            raise RuntimeError("boom\nsecond line\n" + "y" * 5000)

        def pdf(self, wi, wo):
            return np.ones(len(wi))

        def sample(self, wi, u):
            raise RuntimeError("boom")

    class NaNs(Raises):
        type_name = "explore_nans"

        def eval(self, wi, wo):
            return np.full((len(wi), 3), np.nan)

        def sample(self, wi, u):
            return bl.BSDFSample(np.tile([0.0, 0.0, 1.0], (len(wi), 1)), np.ones((len(wi), 3)), np.ones(len(wi)))

    register_bsdf(Raises)
    register_bsdf(NaNs)
    try:
        doc, g = _doc()
        g("bsdf").value = "explore_raises"
        text = g("status").text
        assert "explore_raises raised RuntimeError: boom" in text
        assert "second line" not in text and "Traceback" not in text and len(text) < 400
        g("bsdf").value = "explore_nans"
        assert "NaN" in g("status").text  # drawn as nothing, never as f = 0
    finally:
        unregister_bsdf("explore_raises")
        unregister_bsdf("explore_nans")


def test_protocol_errors_carry_no_traceback():
    from bokeh.protocol import Protocol
    from bokeh.server.connection import ServerConnection

    explore._no_tracebacks_to_clients()

    class Fake:
        protocol = Protocol()

    class Msg:
        header = {"msgid": "1"}

    try:
        raise ValueError("secret internals /home/user/plugin.py")
    except ValueError:
        reply = ServerConnection.error(Fake(), Msg(), "ValueError('secret internals')")
    assert reply.content["traceback"] is None
    assert "secret" not in reply.content["text"]


def test_colour_round_trip_and_known_value():
    assert explore.hex_to_linear("#808080") == pytest.approx([0.21586] * 3, abs=1e-5)  # IEC 61966-2-1
    rng = np.random.default_rng(5)
    for c in rng.random((50, 3)):
        assert explore.hex_to_linear(explore.linear_to_hex(c)) == pytest.approx(c, abs=0.01)
    for bad in ("red", "#fff", "#gggggg", "javascript:1", None, "#ffffff00"):
        with pytest.raises(ValueError):
            explore.hex_to_linear(bad)


def test_lobe_projection_is_a_right_handed_view_sorted_back_to_front():
    for az, el in ((-60, 25), (0, 90), (135, -10), (10, 0)):
        ex, ey, d = lobe3d.view_axes(az, el)
        assert np.allclose([ex @ ex, ey @ ey, d @ d], 1) and np.allclose([ex @ ey, ex @ d, ey @ d], 0, atol=1e-12)
        assert np.allclose(np.cross(ex, ey), d) and ey[2] >= -1e-12  # +z never points down on the screen
    t, p = np.meshgrid(np.radians(np.linspace(0, 90, 7)), np.radians(np.linspace(0, 360, 13)), indexing="ij")
    dirs = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1)
    pts = lobe3d.surface(dirs, 2 * np.cos(t))  # a Lambertian lobe f·cos θ, scaled to its maximum
    assert np.max(np.linalg.norm(pts, axis=-1)) == pytest.approx(1.0)
    pl = lobe3d.project(pts, -60, 25)
    assert pl.xs.shape == (6 * 12, 4) and np.all(np.diff(pl.depth) >= 0)
    assert np.all((pl.shade >= 0.25) & (pl.shade <= 1.0 + 1e-12))
    zero = lobe3d.surface(dirs, np.zeros(t.shape))
    assert np.all(zero == 0) and np.all(lobe3d.project(zero, 0, 30).shade == 0.25)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _start(tmp_path):
    port = _free_port()
    log = open(tmp_path / "explore.log", "w")
    proc = subprocess.Popen([sys.executable, "-m", "brdflab.cli.main", "explore", "--port", str(port), "--no-browser"],
                            stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    url = f"http://127.0.0.1:{port}/"
    t0 = time.monotonic()
    while time.monotonic() - t0 < 90:
        if proc.poll() is not None:
            pytest.fail(f"explore exited with {proc.returncode}: {(tmp_path / 'explore.log').read_text()[-2000:]}")
        try:
            if urllib.request.urlopen(url, timeout=5).status == 200:
                return proc, url, log
        except OSError:
            time.sleep(0.25)
    proc.kill()
    pytest.fail("the explorer did not serve within 90 s")


def _stop(proc, sig) -> int:
    proc.send_signal(sig)
    try:
        return proc.wait(timeout=30)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(timeout=15)
        pytest.fail("the explorer ignored the signal")


def test_websocket_client_cannot_make_the_explorer_load_a_file(tmp_path, evil_plugin):
    from bokeh.client import pull_session

    path, marker = evil_plugin
    proc, url, log = _start(tmp_path)
    try:
        session = pull_session(url=url)
        doc = session.document
        doc.get_model_by_name("bsdf").options = [f"{path}:x"]
        doc.get_model_by_name("bsdf").value = f"{path}:x"
        session.force_roundtrip()
        doc.get_model_by_name("bsdf").value = "brdflab.plugins:load_plugin"
        session.force_roundtrip()
        # the server's own view of this session (a synchronous client does not receive pushes)
        server = pull_session(session_id=session.id, url=url).document
        assert server.get_model_by_name("bsdf").value == "roughconductor"
        assert "refused" in server.get_model_by_name("status").text
        assert not marker.exists()
        session.close()
        status = _stop(proc, signal.SIGINT)
        assert status == 130, (tmp_path / "explore.log").read_text()[-2000:]
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=15)
        log.close()
    text = (tmp_path / "explore.log").read_text()
    assert "Traceback" not in text and not marker.exists()


def test_sigterm_stops_the_explorer_with_143(tmp_path):
    proc, url, log = _start(tmp_path)
    try:
        assert _stop(proc, signal.SIGTERM) == 143
    finally:
        if proc.poll() is None:
            proc.kill()
        log.close()
    assert "stopped (SIGTERM)" in (tmp_path / "explore.log").read_text()


def test_a_burst_of_changes_computes_once_on_the_latest_value():
    """Issue 43: 40 slider changes queued 40 updates (~2.5 s each under load); coalesced, the burst computes once,
    from the widgets' last values, and the status line agrees with the sliders."""
    from bokeh.document import Document

    from brdflab.viz.coalesce import Coalescer

    pending = []
    doc = Document()
    explore.make_document(doc, schedule=pending.append)  # runs only when the test says so
    theta = doc.get_model_by_name("theta_i")
    for v in range(10, 50):  # 40 changes, as 40 arrow-key presses would send
        theta.value = v
    assert len(pending) == 1  # one run scheduled for the whole burst
    pending.pop()()
    status = doc.get_model_by_name("status").text
    assert "θ_i = 49°" in status and "<span id='updates' hidden>1</span>" in status, status
    # a change while nothing is pending schedules again; a run with nothing pending computes nothing
    theta.value = 30
    assert len(pending) == 1
    c = Coalescer(lambda: None, lambda cb: None)
    c._run()
    assert c.runs == 0


def test_client_errors_reach_the_log_in_one_line(caplog):
    """Issue 41: the explorer's log got Bokeh's tracebacks when a client sent junk; now one line each, from the
    'bokeh' logger and from its modules' own loggers alike (negative control: a logger outside the list keeps it)."""
    import logging

    from brdflab.viz.server_safety import one_line_logs

    child = logging.getLogger("bokeh.server.protocol_handler")
    other = logging.getLogger("brdflab.test.elsewhere")
    one_line_logs()
    one_line_logs()  # idempotent
    try:
        raise ValueError("forged message\nsecond line")
    except ValueError:
        with caplog.at_level(logging.ERROR):
            logging.getLogger("bokeh").error("error handling message", exc_info=True)
            child.error("from a module's logger", exc_info=True)
            quiet = caplog.text
            other.error("elsewhere", exc_info=True)
    assert "Traceback" not in quiet and quiet.count("(ValueError: forged message)") == 2, quiet
    assert "Traceback" in caplog.text.split("elsewhere", 1)[1]
