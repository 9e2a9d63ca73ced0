"""Coalesced updates for the live explorer: a burst of widget changes computes once, on the latest values."""

from __future__ import annotations

#: Milliseconds a burst of widget changes may take to arrive before the views follow the latest of them.
DEBOUNCE_MS = 40


class Coalescer:
    """Run ``fn`` once for a burst of requests, on the latest state (issue 43: 40 arrow-key presses on α made
    40 updates of ~2.5 s each, the last one 91 s later, while the header contradicted the sliders).

    A request only marks work pending and schedules one run if none is scheduled; the run computes from the
    widgets' values as they are then. Requests that arrive while an update computes (they queue on the server)
    are cheap marks, so after a burst one more update runs, on the last value.
    """

    def __init__(self, fn, schedule) -> None:
        self.fn, self.schedule = fn, schedule
        self.pending = self.scheduled = False
        self.runs = 0
        """Updates computed so far (shown in the status line's hidden ``updates`` span, for tests)."""

    def on_change(self, attr, old, new) -> None:
        """A widget's callback (Bokeh's signature): :meth:`request`."""
        self.request()

    def request(self) -> None:
        """Ask for an update."""
        self.pending = True
        if not self.scheduled:
            self.scheduled = True
            self.schedule(self._run)

    def _run(self) -> None:
        self.scheduled = False
        if self.pending:
            self.pending = False
            self.runs += 1
            self.fn()
