"""Fixed costs of a run: process age (start-up) and the one-line summary of start-up, load and write times.

The ``render`` command prints :func:`fixed_costs_line` under the render summary, and ``brdflab bench``
records the same figures, so that the costs outside the render loop (interpreter and imports, OBJ parse,
BVH build, EXR + PNG write) stay visible next to samples per second.
"""

from __future__ import annotations

import os
import time

_IMPORTED = time.perf_counter()


#: A process whose age exceeds its own CPU time by more than this was not starting up all that time: a shell
#: ran other commands first and then exec'd brdflab in its place (``bash -c "pip install … && brdflab …"``
#: execs its last command, which keeps the shell's start time).
IDLE_START_LIMIT = 2.0


def process_seconds() -> float:
    """Seconds since this process started (Linux: from ``/proc``, 10 ms resolution; elsewhere since this
    module was first imported).

    When the process is older than its own CPU time (user + system) by more than :data:`IDLE_START_LIMIT`
    seconds, the process was exec'd by a shell that had been running other commands (an install, say): its
    CPU time is returned instead, since start-up (interpreter and imports) is CPU-bound.
    """
    try:
        with open("/proc/self/stat", "rb") as f:
            start_ticks = int(f.read().rsplit(b")", 1)[1].split()[19])
        with open("/proc/uptime", "rb") as f:
            uptime = float(f.read().split()[0])
        age = max(0.0, uptime - start_ticks / os.sysconf("SC_CLK_TCK"))
    except (OSError, ValueError, IndexError):
        return time.perf_counter() - _IMPORTED
    cpu = sum(os.times()[:2])
    return cpu if age > cpu + IDLE_START_LIMIT else age


def fixed_costs_line(startup: float, load: dict[str, float], write: tuple[float, float], whole: float) -> str:
    """``fixed costs 0.52 s: start-up 0.21 s, load 0.22 s (OBJ 0.14, BVH 0.03), write 0.09 s (EXR 0.09 ∥
    PNG 0.05); whole run 6.80 s``, with the compiled kernels' load (the prebuilt module, or numba and its
    cached machine code) and build time (first run only) when the compiled engine ran
    (:func:`brdflab.kernels.costs`). ``load`` is a :attr:`Scene.timings <brdflab.scene.loader.Scene.timings>`
    dict, ``write`` the (EXR, PNG) seconds of :func:`brdflab.imageio.write_images` (written in parallel)."""
    from brdflab.kernels import costs

    write_s = max(write)
    k = costs()
    kernels_s = k["import"] + k["compile"]
    total = startup + load.get("total", 0.0) + write_s + kernels_s
    kern = (f", compiled kernels {kernels_s:.2f} s (load {k['import']:.2f}, build "
            f"{k['compile']:.2f})") if kernels_s else ""
    return (f"fixed costs {total:.2f} s: start-up {startup:.2f} s, load {load.get('total', 0.0):.2f} s "
            f"(OBJ {load.get('obj', 0.0):.2f}, BVH {load.get('bvh', 0.0):.2f}), write {write_s:.2f} s "
            f"(EXR {write[0]:.2f} ∥ PNG {write[1]:.2f}){kern}; whole run {whole:.2f} s")
