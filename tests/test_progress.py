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
    assert re.match(r"rendering: 1\.0% \(1 of 100 spp\) after [\d.]+ s, ETA [\d.]+ s", lines[0])
    assert lines[1].startswith("rendering: 100.0% (100 of 100 spp)")


def test_eta_respects_the_time_limit():
    p = Progress("rendering", 10**9, 1000, time_limit=10.0, stream=io.StringIO())
    # 1 % done after 1 s: at this rate 10 % fits in the 10 s limit, so the target (and the ETA) is that.
    assert p._target(10**7, 1.0) == 10**8
    assert Progress("r", 10**9, 1000, stream=io.StringIO())._target(10**7, 1.0) == 10**9


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
