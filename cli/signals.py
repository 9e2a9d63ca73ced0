"""Signals: SIGTERM and SIGHUP are treated like Ctrl-C (SIGINT).

Exit status of an interrupted run: 128 + the signal number — 130 (SIGINT), 143 (SIGTERM), 129 (SIGHUP).

* Outside a render (loading, validation, reports) a signal raises :class:`brdflab.errors.Interrupted`
  (a ``KeyboardInterrupt``), which :func:`brdflab.cli.main.main` turns into the exit status above:
  :func:`install_default_handlers`.
* During a render, :class:`GracefulStop`: the first signal asks the render to stop at the next pass
  boundary (the completed passes are written as the ``_partial_<N>spp`` pair); a second signal exits at
  once — the worker processes are killed, temporaries of an image write in progress are removed (once its
  running encoders return, which could otherwise create them again: milliseconds) and the process leaves
  with ``os._exit`` (no interpreter shutdown that could wait on a worker). Once the
  stopped render is written its exit status is decided: a signal after that still exits at once, with
  that status (:func:`_exit_decided`), and :func:`ignore_while_exiting` keeps a signal during the
  interpreter's shutdown (which restores the default handlers) from turning it into death by signal.
"""

from __future__ import annotations

import os
import signal
import sys
import threading

from brdflab.errors import Interrupted

#: The signals handled like Ctrl-C.
SIGNALS = tuple(s for s in (getattr(signal, n, None) for n in ("SIGINT", "SIGTERM", "SIGHUP")) if s is not None)


def exit_status(signum: int) -> int:
    """128 + the signal number (the shell's convention)."""
    return 128 + int(signum)


def _in_main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


def _raise_interrupted(signum, frame) -> None:
    raise Interrupted(signum)


def install_default_handlers() -> None:
    """Make SIGTERM and SIGHUP raise :class:`Interrupted` like Ctrl-C raises KeyboardInterrupt."""
    if not _in_main_thread():
        return
    for sig in SIGNALS:
        if sig != signal.SIGINT:
            signal.signal(sig, _raise_interrupted)


class GracefulStop:
    """Context manager for a render: ``stop`` is set by the first signal; a second one aborts at once."""

    def __init__(self, message: str = "saving the completed passes") -> None:
        self.stop = threading.Event()
        self.signum: int | None = None
        self.message = message
        self._previous: dict[int, object] = {}

    def _handle(self, signum, frame) -> None:
        if self.stop.is_set():
            self.abort(signum)
        self.signum = signum
        self.stop.set()
        name = signal.Signals(signum).name
        again = "Ctrl-C" if signum == signal.SIGINT else f"{name}"
        sys.stderr.write(f"\nbrdflab: {name} received — {self.message} ({again} again to abort)\n")
        sys.stderr.flush()

    @staticmethod
    def abort(signum: int) -> None:
        """Exit now: kill the render workers, remove write temporaries, ``os._exit(128 + signum)``."""
        from brdflab.imageio import remove_temporaries
        from brdflab.renderer import kill_workers

        kill_workers()
        remove_temporaries()
        try:
            sys.stderr.write(f"\nbrdflab: aborted by {signal.Signals(signum).name}; nothing written\n")
            sys.stderr.flush()
        except (OSError, ValueError):
            pass
        os._exit(exit_status(signum))

    def __enter__(self) -> GracefulStop:
        if _in_main_thread():
            for sig in SIGNALS:
                self._previous[sig] = signal.signal(sig, self._handle)
        return self

    def __exit__(self, *exc) -> None:
        stopped = self.stop.is_set() and self.signum is not None
        for sig, prev in self._previous.items():
            signal.signal(sig, _exit_decided(self.signum) if stopped else prev)
        self._previous.clear()


def _exit_decided(first: int):
    """A handler for after a stopped render was written: leave at once with the first signal's status."""

    def handler(signum, frame) -> None:
        try:
            sys.stderr.flush()
        except (OSError, ValueError):
            pass
        os._exit(exit_status(first))

    return handler


def ignore_while_exiting(status: int) -> None:
    """Before the interpreter shuts down with ``status``: if a signal decided it, ignore further signals.

    The shutdown restores the default handlers of Python-level ones, so a second SIGTERM arriving then
    would kill the process (status -15 to a parent) instead of letting it exit 143. Ignored signals stay
    ignored through the shutdown, which has nothing left to write or wait for.
    """
    if status in {exit_status(s) for s in SIGNALS} and _in_main_thread():
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):
                pass
        for sig in SIGNALS:
            signal.signal(sig, signal.SIG_IGN)
