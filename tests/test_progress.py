"""The render progress display: plain lines when not a terminal, a width-fitting tqdm bar on one, and an ETA
that respects --time-limit."""

from __future__ import annotations

import io
import os
import re
import select

import pytest

from brdflab.cli.progress import Progress


class Stats:
    spp = 0


class FakeTTY(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_plain_lines_when_not_a_terminal():
    out = io.StringIO()
    p = Progress("rendering", 1000, 100, stream=out)
    st = Stats()
    p(0.0, st)  # nothing yet: no pass done, no interval elapsed
    st.spp = 1
    p(0.01, st)  # the first completed pass is reported at once
    p(0.02, st)  # then at most every PLAIN_INTERVAL seconds
    st.spp = 100
    p(1.0, st)
    lines = out.getvalue().splitlines()
    assert len(lines) == 2 and "\r" not in out.getvalue()
    # One unit done: no rate yet, so no ETA.
    assert re.fullmatch(r"rendering: 1\.0% \(1 of 100 spp\) after [\d.]+ s", lines[0]), lines
    assert lines[1].startswith("rendering: 100.0% (100 of 100 spp)") and lines[1].endswith("ETA 0.0 s")


class Clock:
    """A fake clock: the test sets ``t``."""

    t = 0.0

    def __call__(self) -> float:
        return self.t


def test_eta_respects_the_time_limit():
    clock = Clock()
    p = Progress("rendering", 10**9, 1000, time_limit=10.0, stream=io.StringIO(), clock=clock)
    clock.t = 5.0  # a slow start (one-off costs): not part of the rate
    p(10**6 / 10**9, Stats())
    # Then 1e7 samples per second: by the 10 s limit 5e7 more fit, so the target (and the ETA) is that.
    assert p._target(2 * 10**6, 5.1) == pytest.approx(2 * 10**6 + 10**7 * 4.9)
    assert p.eta(2 * 10**6, 5.1) == pytest.approx(4.9)
    q = Progress("r", 10**9, 1000, stream=io.StringIO(), clock=clock)
    assert q._target(10**7, 1.0) == 10**9 and q.eta(10**7, 1.0) is None


def test_eta_comes_from_the_rate_of_completed_work_not_from_a_slow_first_pass():
    """A first pass that took 20 s (a kernel build, workers starting) then 100 units of 0.1 s each: no ETA
    before there is a rate, then every ETA within 10 % of the time really left (from the elapsed time of
    the whole run, the first ETA would have been about 100 times too long, as issue 42 saw)."""
    clock = Clock()
    out = io.StringIO()
    p = Progress("rendering", 101, 101, stream=out, clock=clock)
    st = Stats()
    clock.t = 20.0
    st.spp = 1
    p(1 / 101, st)
    etas = []
    for k in range(2, 102):
        clock.t = 20.0 + 0.1 * (k - 1)
        st.spp = k
        p(k / 101, st)
        left = 0.1 * (101 - k)
        if k < 101:
            assert p.eta(k, clock.t) == pytest.approx(left, rel=0.1, abs=1e-9)
        etas.append(p.eta(k, clock.t))
    lines = out.getvalue().splitlines()
    assert "ETA" not in lines[0] and lines[0].startswith("rendering: 1.0% (1 of 101 spp) after 20.0 s")
    shown = [float(m) for m in re.findall(r"ETA ([\d.]+) s", out.getvalue())]
    assert shown and max(shown) <= 10.0  # the whole run after the first pass is 10 s


def test_the_bar_on_a_terminal_rates_only_the_work_after_the_first_unit():
    """The tqdm bar starts at the first completed unit (``initial``): the 20 s before it are not in its rate."""
    clock = Clock()
    p = Progress("rendering", 100, 100, stream=FakeTTY(), clock=clock)
    clock.t = 20.0
    p(0.01, Stats())
    assert p.bar is not None and p.bar.n == 1 and p.bar.initial == 1
    p.close()


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a pseudo-terminal")
def test_bar_on_a_terminal_fits_its_width():
    import fcntl
    import struct
    import termios

    master, slave = os.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 20, 60, 0, 0))  # a 60-column terminal
    chunks = []
    with open(slave, "w", encoding="utf-8", closefd=True) as tty:
        p = Progress("rendering", 10**6, 100, stream=tty)
        for k in range(1, 11):
            p(k / 10, Stats())
        p.close()
        tty.flush()
        while select.select([master], [], [], 0.5)[0]:
            chunks.append(os.read(master, 65536))
    os.close(master)
    text = b"".join(chunks).decode("utf-8", "replace")
    frames = [f for f in re.split(r"[\r\n]", text) if f.strip()]
    assert frames and all(len(f) <= 60 for f in frames), frames
    assert "100%" in frames[-1]


def test_quiet_writes_nothing():
    out = FakeTTY()
    p = Progress("rendering", 10, 1, stream=out, quiet=True)
    p(1.0, Stats())
    assert out.getvalue() == ""


def test_a_real_render_ends_with_every_pass_counted():
    """The last plain line of a render counts the passes it completed ("100.0% (4 of 4 spp)", not "0 of 4")."""
    from pathlib import Path

    import brdflab as bl
    from brdflab.renderer import render

    cbox = Path(__file__).resolve().parents[1] / "scenes" / "cbox" / "cbox_diffuse.xml"
    scene = bl.load_scene(cbox, width=16, height=12)
    out = io.StringIO()
    p = Progress("rendering", 16 * 12 * 4, 4, stream=out)
    render(scene, spp=4, seed=1, workers=1, progress=p)
    last = out.getvalue().splitlines()[-1]
    assert last.startswith("rendering: 100.0% (4 of 4 spp)"), out.getvalue()


def test_startup_does_not_count_what_a_shell_ran_before_exec():
    """``bash -c "… && brdflab …"`` execs brdflab in the shell's process: its start-up must not include the
    commands before it (an install)."""
    import shutil
    import subprocess
    import sys

    if shutil.which("bash") is None or not os.path.exists("/proc/self/stat"):
        pytest.skip("needs bash and /proc")
    code = "from brdflab.timing import process_seconds; print(process_seconds())"
    out = subprocess.run(["bash", "-c", f'sleep 3 && exec "{sys.executable}" -c "{code}"'], capture_output=True,
                         text=True, timeout=60)
    assert float(out.stdout) < 2.5, out


def test_the_time_limit_predicts_the_next_pass_from_the_passes_after_the_first():
    """--time-limit decides whether the next pass fits from the rate after the first pass (which holds the
    one-off costs): a first pass of 5 s then passes at 0.1 s per spp predict 0.1 s per spp, not 1.7 s."""
    from brdflab.renderer import _seconds_per_spp

    assert _seconds_per_spp([(1, 5.0)]) == 5.0
    assert _seconds_per_spp([(1, 5.0), (2, 5.1), (4, 5.3)]) == pytest.approx(0.1)
