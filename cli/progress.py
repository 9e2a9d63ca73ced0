"""Render progress: a ``tqdm`` bar on a terminal, plain lines otherwise.

tqdm fits the bar to the terminal width (and follows resizes), smooths the rate for the ETA and formats
sample counts; brdflab only adds the time limit: with ``--time-limit`` the bar's total is what fits in
the limit at the current rate, so the ETA never exceeds the time left. When stderr is not a terminal
(a log file, CI, a pipe), a plain line is printed at the first completed pass and then at most every
:data:`PLAIN_INTERVAL` seconds.

**The ETA comes from the rate of completed work only**: it is measured from the first completed work unit
on, never over the time before it, which holds one-off costs (starting the workers, loading the compiled
kernels or waiting for their first build, warming the caches) that the rest of the render does not pay
again. Until a second unit has completed there is no rate, and no ETA is shown (the plain line says
``ETA …`` only then; tqdm's bar starts counting at the first unit and shows ``?`` until it has a rate).
"""

from __future__ import annotations

import sys
import time

#: Seconds between two plain progress lines.
PLAIN_INTERVAL = 5.0


class Progress:
    """Callable ``(fraction done, stats)`` for :func:`brdflab.renderer.render`.

    Parameters
    ----------
    label
        Shown before the bar.
    total_samples, spp
        Camera samples and samples per pixel of the whole render.
    time_limit
        The ``--time-limit`` in seconds, if any.
    stream
        Where to write (default ``sys.stderr``).
    quiet
        Write nothing.
    clock
        Seconds, monotonic (tests pass a fake one).
    """

    def __init__(self, label: str, total_samples: int, spp: int, time_limit: float | None = None,
                 stream=None, quiet: bool = False, clock=time.perf_counter) -> None:
        self.label = label
        self.total = total_samples
        self.spp = spp
        self.time_limit = time_limit
        self.stream = stream if stream is not None else sys.stderr
        self.quiet = quiet
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.clock = clock
        self.t0 = clock()
        self.last = 0.0
        self.passes = 0
        self.bar = None
        #: (seconds, samples) at the first completed unit: where the rate is measured from.
        self.first: tuple[float, float] | None = None

    def rate(self, done: float, now: float) -> float | None:
        """Samples per second since the first completed unit; None until there is such a rate."""
        if self.first is None or now <= self.first[0] or done <= self.first[1]:
            return None
        return (done - self.first[1]) / (now - self.first[0])

    def _target(self, done: float, now: float) -> float:
        """Samples that will have been taken at the end: all of them, or what fits in the time limit (at the
        rate of completed work)."""
        rate = self.rate(done, now)
        if self.time_limit is None or rate is None:
            return self.total
        return min(self.total, max(done, done + rate * (self.time_limit - now)))

    def eta(self, done: float, now: float) -> float | None:
        """Seconds left at the rate of completed work; None before there is a rate."""
        rate = self.rate(done, now)
        return None if rate is None else max(0.0, self._target(done, now) - done) / rate

    def __call__(self, frac: float, stats) -> None:
        if self.quiet:
            return
        now = self.clock() - self.t0
        done = frac * self.total
        if self.first is None and done > 0:
            self.first = (now, done)
        target = self._target(done, now)
        if self.tty:
            if self.bar is None:
                from tqdm import tqdm

                # initial=done: tqdm's rate (and ETA) counts the work after the first unit only.
                self.bar = tqdm(total=target, initial=done, desc=self.label, unit="sample", unit_scale=True,
                                dynamic_ncols=True, file=self.stream, leave=True, mininterval=0.1)
            self.bar.total = target
            self.bar.update(done - self.bar.n)
            if frac >= 1 or done >= target:
                self.close()
            return
        first_pass = stats.spp > 0 and self.passes == 0
        if not (first_pass or frac >= 1 or now - self.last >= PLAIN_INTERVAL):
            return
        self.passes = max(self.passes, stats.spp)
        eta = 0.0 if frac >= 1 else self.eta(done, now)
        self.stream.write(f"{self.label}: {100 * frac:.1f}% ({stats.spp:,} of {self.spp:,} spp) after {now:.1f} s"
                          + ("" if eta is None else f", ETA {eta:.1f} s") + "\n")
        self.stream.flush()
        self.last = now

    def close(self, complete: bool = False) -> None:
        """End the bar (keeps its last state on screen); ``complete``: the render ended normally (a time limit
        may have ended it before the estimated total), show it full."""
        if self.bar is not None:
            if complete:
                self.bar.total = self.bar.n
                self.bar.refresh()
            self.bar.close()
            self.bar = None
