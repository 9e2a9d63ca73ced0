"""Image writes against an abort (a second signal): no temporary survives, whichever thread the signal lands
on and wherever the writer threads are (not yet begun, encoding, done).

A stress run of ``tests/test_signals.py::test_second_signal_exits_at_once_without_orphans`` left a temporary
in 3 of 60 runs before these rules (an encoder that opened its temporary by name after the abort removed it;
a signal delivered to another thread between a temporary's creation and its registration), 0 of 120 after.
"""

from __future__ import annotations

import os
import signal
import threading
import time

import pytest

from brdflab import imageio


@pytest.fixture
def gate(monkeypatch):
    """A fresh writer gate for one test (remove_temporaries closes it for good: it is meant for an exiting
    process)."""
    monkeypatch.setattr(imageio, "_JOBS", {"running": 0, "closed": False})
    monkeypatch.setattr(imageio, "_TEMPORARIES", set())
    return imageio._JOBS


def _slow_writer(started: threading.Event, delay: float, done: threading.Event | None = None):
    def writer(tmp: str) -> None:
        started.set()
        time.sleep(delay)
        with open(tmp, "wb") as f:  # opened by name late, as an encoder may do
            f.write(b"late")
        if done is not None:
            done.set()
    return writer


@pytest.mark.parametrize("wait", [imageio.WRITER_WAIT, 0.0])
def test_abort_waits_for_a_running_encoder_before_removing(tmp_path, gate, monkeypatch, wait):
    """A writer job that opens its (registered) temporary by name after a delay: the abort waits for it and
    removes the file; without the wait (the negative control) the file comes back after the removal."""
    monkeypatch.setattr(imageio, "WRITER_WAIT", wait)
    tmp = str(tmp_path / ".brdflab-x.tmp.exr")
    open(tmp, "wb").close()  # as mkstemp leaves it
    imageio._TEMPORARIES.add(tmp)
    started = threading.Event()

    def job():
        with imageio._job([False], [0]) as go:
            assert go
            _slow_writer(started, 0.3)(tmp)

    th = threading.Thread(target=job)
    th.start()
    assert started.wait(30)  # hang bound
    imageio.remove_temporaries()
    th.join(30)  # hang bound
    assert os.path.exists(tmp) == (wait == 0)


def test_a_writer_that_had_not_begun_never_begins_after_an_abort(tmp_path, gate):
    imageio.remove_temporaries()
    assert gate["closed"]
    calls = []
    with pytest.raises(imageio.ImageError, match="write cancelled"):
        imageio.write_files([(tmp_path / "a.exr", calls.append), (tmp_path / "a.png", calls.append)])
    assert calls == [] and list(tmp_path.iterdir()) == []


def test_an_interrupted_write_waits_for_its_encoders_and_leaves_nothing(tmp_path, gate):
    """An exception in the waiting thread (a signal's) cancels the jobs not yet begun and removes the
    temporaries only after the running encoder returned."""
    started, done = threading.Event(), threading.Event()
    timer = threading.Timer(0.1, lambda: signal.pthread_kill(threading.main_thread().ident, signal.SIGUSR1))
    old = signal.signal(signal.SIGUSR1, _raise)
    try:
        timer.start()
        with pytest.raises(_Boom):
            imageio.write_files([(tmp_path / "a.exr", _slow_writer(started, 0.5, done))])
    finally:
        signal.signal(signal.SIGUSR1, old)
        timer.cancel()
    assert started.is_set() and done.is_set()  # the exception left only after the encoder returned ...
    assert list(tmp_path.iterdir()) == []  # ... and then its temporary was removed


class _Boom(Exception):
    pass


def _raise(signum, frame):
    raise _Boom


def test_signals_are_held_even_when_another_thread_takes_them():
    """Python runs handlers in the main thread whatever thread the system picks: a signal sent while the main
    thread holds them reaches the handler only after the held section, once, with the handler in place."""
    got = []
    old = signal.signal(signal.SIGTERM, lambda signum, frame: got.append(("handled", signum)))
    try:
        with imageio._signals_held():
            th = threading.Thread(target=lambda: os.kill(os.getpid(), signal.SIGTERM))
            th.start()
            th.join()
            t0 = time.monotonic()
            while time.monotonic() - t0 < 0.2:  # Python bytecode runs: an unheld handler would run here
                got.append("inside") if not got else None
            assert got == ["inside"]
        assert got == ["inside", ("handled", signal.SIGTERM)]
    finally:
        signal.signal(signal.SIGTERM, old)
