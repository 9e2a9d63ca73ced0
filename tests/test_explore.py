"""brdflab explore in a real headless Chromium (Selenium + Debian's chromium-driver): move a slider, see the
plots change. Skips cleanly without chromium, chromedriver or selenium; the server and the browser are
always shut down, and every wait is bounded."""

from __future__ import annotations

import contextlib
import shutil
import socket
import subprocess
import sys
import time
import urllib.request

import pytest

from tests.test_report import _chromium

STATUS_JS = ("return (window.Bokeh && Bokeh.documents.length && Bokeh.documents[0].get_model_by_name('status'))"
             " ? Bokeh.documents[0].get_model_by_name('status').text : ''")
# Bokeh 3 renders widgets in shadow roots: find each slider's title and handle there.
SLIDERS_JS = """
const out = [];
const walk = (root) => root.querySelectorAll('*').forEach(e => {
  if (!e.shadowRoot) return;
  const s = e.shadowRoot, title = s.querySelector('.bk-slider-title'), handle = s.querySelector('.noUi-handle');
  if (title && handle) out.push([title.textContent, handle]);
  walk(s);
});
walk(document);
return out;
"""


MODEL_VALUE_JS = "return Bokeh.documents[0].get_model_by_name(arguments[0]).value"
SET_JS = "Bokeh.documents[0].get_model_by_name(arguments[0]).value = arguments[1]"
SPHERE_TITLE_JS = "return Bokeh.documents[0].get_model_by_name('sphere').title.text"

PICKERS_JS = """
let n = 0;
const walk = (root) => root.querySelectorAll('*').forEach(e => {
  if (e.tagName === 'INPUT' && e.type === 'color') n++;
  if (e.shadowRoot) walk(e.shadowRoot);
});
walk(document);
return n;
"""


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _wait(pred, timeout: float, what: str):
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        v = pred()
        if v:
            return v
        time.sleep(0.25)
    pytest.fail(f"timed out after {timeout:.0f} s waiting for {what}")


@contextlib.contextmanager
def _explorer(tmp_path):
    """A served explorer and a headless Chromium on its page (skips without them); both always shut down."""
    exe, driver_exe = _chromium(), shutil.which("chromedriver")
    if exe is None or driver_exe is None:
        pytest.skip("no chromium/chromedriver on this machine (CI installs Debian's chromium and chromium-driver)")
    webdriver = pytest.importorskip("selenium.webdriver")
    port = _free_port()
    url = f"http://127.0.0.1:{port}/"
    log = open(tmp_path / "explore.log", "w")
    server = subprocess.Popen([sys.executable, "-m", "brdflab.cli.main", "explore", "--port", str(port),
                               "--no-browser"], stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    driver = None
    try:
        def up():
            if server.poll() is not None:
                tail = (tmp_path / 'explore.log').read_text()[-2000:]
                pytest.fail(f"explore exited with {server.returncode}: {tail}")
            try:
                return urllib.request.urlopen(url, timeout=5).status == 200
            except OSError:
                return False

        _wait(up, 90, "the explorer to serve")
        opts = webdriver.ChromeOptions()
        for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--window-size=1280,1000",
                  "--disable-background-networking", "--disable-component-update", f"--user-data-dir={tmp_path}/p"):
            opts.add_argument(a)
        opts.binary_location = exe
        driver = webdriver.Chrome(options=opts, service=webdriver.ChromeService(executable_path=driver_exe))
        driver.set_page_load_timeout(90)
        driver.set_script_timeout(30)
        driver.url_served = url
        yield driver
    finally:
        if driver is not None:
            driver.quit()
        server.terminate()
        try:
            server.wait(timeout=15)
        except subprocess.TimeoutExpired:
            server.kill()
            server.wait(timeout=15)
        log.close()


def test_explorer_slider_updates_the_plots(tmp_path):
    from selenium.webdriver.common.action_chains import ActionChains

    with _explorer(tmp_path) as driver:
        url = driver.url_served
        html = urllib.request.urlopen(url, timeout=10).read().decode()
        assert 'src="/static/js/bokeh' in html and "cdn" not in html.lower()  # JS served locally, no CDN
        driver.get(url)
        before = _wait(lambda: "peak f" in driver.execute_script(STATUS_JS) and driver.execute_script(STATUS_JS),
                       90, "the first plots")
        assert "θ_i = 45°" in before
        shot_before = driver.get_screenshot_as_png()
        # the page fits a 1280-px window, and a colour parameter has a colour picker
        assert driver.execute_script("return document.documentElement.scrollWidth") <= 1280
        assert driver.execute_script(PICKERS_JS) >= 1
        sliders = _wait(lambda: driver.execute_script(SLIDERS_JS), 30, "the sliders")
        titles = [t for t, _ in sliders]
        assert any(t.startswith("alpha") for t in titles), titles
        handle = next(h for t, h in sliders if t.startswith("θ_i"))
        ActionChains(driver).click_and_hold(handle).move_by_offset(-50, 0).release().perform()
        after = _wait(lambda: (s := driver.execute_script(STATUS_JS)) != before and "peak f" in s and s, 60,
                      "the plots to follow the slider")
        assert "θ_i = 45°" not in after
        theta = float(after.split("θ_i = ")[1].split("°")[0])
        assert 0 <= theta < 45
        time.sleep(0.5)  # let the canvases repaint
        assert driver.get_screenshot_as_png() != shot_before
        # the live lit sphere: the background render replaces the preview
        _wait(lambda: "spp" in driver.execute_script(SPHERE_TITLE_JS), 120, "the refined lit sphere")
        # an overlay, chosen in the page, and a typed value, both round trips through the server
        driver.execute_script(SET_JS, "bsdf_2", "roughdielectric")
        _wait(lambda: "· 2: roughdielectric" in driver.execute_script(STATUS_JS), 60, "the overlay")
        driver.execute_script(SET_JS, "typed_theta_i", "30")
        _wait(lambda: "θ_i = 30°" in driver.execute_script(STATUS_JS), 60, "the typed θ_i")
        assert float(driver.execute_script(MODEL_VALUE_JS, "theta_i")) == 30




def test_a_burst_of_40_key_presses_ends_at_the_last_value(tmp_path):
    """Issue 43: 40 arrow-key presses on α left the plots at α 0.238 while the slider said 0.28, 91 s later.
    Coalesced, the status line reaches the slider's last value, and far fewer than 40 updates were computed."""
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.keys import Keys

    with _explorer(tmp_path) as driver:
        driver.get(driver.url_served)
        _wait(lambda: "peak f" in driver.execute_script(STATUS_JS), 90, "the first plots")
        sliders = _wait(lambda: driver.execute_script(SLIDERS_JS), 30, "the sliders")
        handle = next(h for t, h in sliders if t.startswith("alpha"))
        ActionChains(driver).click(handle).perform()
        _wait(lambda: "peak f" in driver.execute_script(STATUS_JS), 60, "the click's update")
        keys = ActionChains(driver)
        for _ in range(40):
            keys.send_keys(Keys.ARROW_RIGHT)
        keys.perform()
        last = float(driver.execute_script(MODEL_VALUE_JS, "param_alpha"))

        def settled():
            s = driver.execute_script(STATUS_JS)
            return s if f"alpha={last:g}" in s and "peak f" in s else ""

        final = _wait(settled, 120, f"the status line to show the slider's last value alpha={last:g}")
        assert float(driver.execute_script(MODEL_VALUE_JS, "param_alpha")) == last  # no straggler moved it
        runs = int(final.split("hidden>")[1].split("<")[0])
        assert runs <= 12, f"{runs} updates for 40 key presses (coalescing failed)"


def test_distribution_dropdown_and_anisotropic_alpha_round_trip(tmp_path):
    """Issue 45's widgets in the browser: the distribution dropdown switches to GGX (and turns visible-normal
    sampling on), unlinking α shows α_u/α_v sliders, a typed α_v makes the lobe anisotropic (the plots change),
    and the Fresnel dropdown gives a metal's η, k."""
    with _explorer(tmp_path) as driver:
        driver.get(driver.url_served)
        first = _wait(lambda: "peak f" in (s := driver.execute_script(STATUS_JS)) and s, 90, "the first plots")
        assert "distribution=beckmann" in first
        assert driver.execute_script("return Bokeh.documents[0].get_model_by_name('param_distribution').options"
                                     ) == ["beckmann", "ggx"]
        driver.execute_script(SET_JS, "param_distribution", "ggx")
        ggx = _wait(lambda: "distribution=ggx" in (s := driver.execute_script(STATUS_JS)) and "peak f" in s and s,
                    60, "the GGX lobe")
        assert "sample_visible=True" in ggx
        shown = driver.execute_script(SLIDERS_JS)
        displayed = [t for t, h in shown if h.is_displayed()]
        assert "alpha" in [t.split(":")[0].strip() for t in displayed] and not any("alpha_v" in t for t in displayed)
        driver.execute_script("Bokeh.documents[0].get_model_by_name('param_alpha_link').active = false")
        _wait(lambda: "alpha_u=" in driver.execute_script(STATUS_JS), 60, "α_u and α_v in the model")
        _wait(lambda: any("alpha_v" in t and h.is_displayed() for t, h in driver.execute_script(SLIDERS_JS)), 30,
              "the α_u/α_v sliders shown")
        shot = driver.get_screenshot_as_png()
        driver.execute_script(SET_JS, "typed_param_alpha_v", "0.5")
        aniso = _wait(lambda: "alpha_v=0.5" in (s := driver.execute_script(STATUS_JS)) and "peak f" in s and s, 60,
                      "the anisotropic lobe")
        assert aniso.split("peak f")[1] != ggx.split("peak f")[1]  # another peak and albedo
        time.sleep(0.5)
        assert driver.get_screenshot_as_png() != shot
        driver.execute_script(SET_JS, "param_fresnel", "Au")
        _wait(lambda: "material=Au" in driver.execute_script(STATUS_JS), 60, "gold")
