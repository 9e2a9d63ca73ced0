"""Coalesced updates for the live explorer: a burst of widget changes computes once, on the latest values."""

from __future__ import annotations

import time

#: Milliseconds a burst of widget changes may take to arrive before the views follow the latest of them.
DEBOUNCE_MS = 40
#: A served explorer waits for this many quiet milliseconds after the last change (trailing edge) …
QUIET_MS = 60
#: … but never longer than this after the first pending change, so that a long drag still shows its way.
MAX_WAIT_MS = 1000


class Coalescer:
    """Run ``fn`` once for a burst of requests, on the latest state (issue 43: 40 arrow-key presses on α made
    40 updates of ~2.5 s each, the last one 91 s later, while the header contradicted the sliders).

    A request only marks work pending and schedules one run if none is scheduled; the run computes from the
    widgets' values as they are then. Requests that arrive while an update computes (they queue on the server)
    are cheap marks, so after a burst one more update runs, on the last value.

    With ``quiet_ms`` > 0 the run waits until no request came for that long (checked when the scheduled run
    fires; it schedules itself again otherwise), at most ``max_wait_ms`` after the first pending request: the
    changes of a burst that queued behind a running update arrive one after another, and without the quiet
    period each gap between them started another full update on an intermediate value. ``on_request`` is called
    on every request (the explorer stops its stale background render there). ``clock`` gives seconds.
    """

    def __init__(self, fn, schedule, quiet_ms: float = 0.0, max_wait_ms: float = MAX_WAIT_MS, on_request=None,
                 clock=time.monotonic) -> None:
        self.fn, self.schedule = fn, schedule
        self.quiet, self.max_wait = quiet_ms / 1000.0, max_wait_ms / 1000.0
        self.on_request, self.clock = on_request, clock
        self.pending = self.scheduled = False
        self.first = self.last = 0.0
        self.runs = 0
        """Updates computed so far (shown in the status line's hidden ``updates`` span, for tests)."""

    def on_change(self, attr, old, new) -> None:
        """A widget's callback (Bokeh's signature): :meth:`request`."""
        self.request()

    def request(self) -> None:
        """Ask for an update."""
        if self.on_request is not None:
            self.on_request()
        now = self.clock()
        if not self.pending:
            self.first = now
        self.pending, self.last = True, now
        if not self.scheduled:
            self.scheduled = True
            self.schedule(self._run)

    def _run(self) -> None:
        now = self.clock()
        if self.pending and now - self.last < self.quiet and now - self.first < self.max_wait:
            self.schedule(self._run)  # changes are still arriving: wait for the burst's end
            return
        self.scheduled = False
        if self.pending:
            self.pending = False
            self.runs += 1
            self.fn()
