"""How soon `brdflab explore` shows the last value after one arrow-key press on α and after a burst of 40 (issue 43's
done-when), in a headless Chromium (Debian's chromium and chromium-driver, Selenium), alternating.

    python benchmarks/explore_burst.py [--rounds 3] [--overlay] [--no-refine]

``--overlay`` compares with a rough dielectric (a second material); ``--no-refine`` turns the background lit-sphere
render off (to see what it costs). The time is from the end of the key presses in the browser to the status line
showing the slider's value; "updates" counts the server's computed updates.
"""

from __future__ import annotations

import argparse
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.test_explore import MODEL_VALUE_JS, SLIDERS_JS, STATUS_JS  # noqa: E402
from tests.test_report import _chromium  # noqa: E402

LAUNCH = ("import sys, brdflab.viz.explorer as e\nif {off}: e._threaded = lambda doc: None\n"
          "from brdflab.cli.main import main\nsys.exit(main(sys.argv[1:]))")


def _wait(pred, timeout: float = 300.0):
    """Poll ``pred`` every 20 ms (the measured latencies are below a second) until it is true."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if v := pred():
            return v
        time.sleep(0.02)
    raise SystemExit("timed out")


def main() -> None:
    from selenium import webdriver
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.keys import Keys

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--overlay", action="store_true")
    ap.add_argument("--no-refine", action="store_true")
    a = ap.parse_args()
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    url = f"http://127.0.0.1:{port}/"
    tmp = tempfile.mkdtemp(prefix="explore-burst-")
    srv = subprocess.Popen([sys.executable, "-c", LAUNCH.format(off=a.no_refine), "explore", "--port", str(port),
                            "--no-browser"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                           start_new_session=True)
    drv = None
    try:
        def up():
            try:
                return urllib.request.urlopen(url, timeout=5).status == 200
            except OSError:
                return False

        _wait(up, 90)
        o = webdriver.ChromeOptions()
        for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--window-size=1280,1000",
                    f"--user-data-dir={tmp}/chrome"):
            o.add_argument(arg)
        o.binary_location = _chromium()
        drv = webdriver.Chrome(options=o, service=webdriver.ChromeService(executable_path=shutil.which("chromedriver")))
        drv.get(url)
        _wait(lambda: "peak f" in drv.execute_script(STATUS_JS), 90)
        if a.overlay:
            drv.execute_script("Bokeh.documents[0].get_model_by_name('bsdf_2').value = 'roughdielectric'")
            _wait(lambda: "2: rough" in drv.execute_script(STATUS_JS))
        time.sleep(3)
        handle = next(h for t, h in drv.execute_script(SLIDERS_JS) if t.startswith("alpha"))
        ActionChains(drv).click(handle).perform()
        time.sleep(3)

        def runs() -> int:
            s = drv.execute_script(STATUS_JS)
            return int(s.split("hidden>")[1].split("<")[0]) if "hidden>" in s else -1

        for r in range(a.rounds):
            for n in (1, 40):
                r0 = runs()
                keys = ActionChains(drv)
                for _ in range(n):
                    keys.send_keys(Keys.ARROW_RIGHT if r % 2 == 0 else Keys.ARROW_LEFT)
                keys.perform()
                t0 = time.monotonic()
                last = float(drv.execute_script(MODEL_VALUE_JS, "param_alpha"))
                # α is followed by a space (the last parameter) or a comma (distribution … follow it)
                _wait(lambda last=last: any(f", alpha={last:g}{c}" in drv.execute_script(STATUS_JS) for c in " ,"))
                print(f"round {r} presses {n:2d}: shown after {time.monotonic() - t0:.2f} s, {runs() - r0} update(s); "
                      f"load {os.getloadavg()[0]:.1f}", flush=True)
                time.sleep(4)
    finally:
        if drv is not None:
            drv.quit()
        srv.terminate()
        srv.wait(15)
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
