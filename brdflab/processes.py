"""Process utilities below every other layer: what a child process needs to die with its parent.

Used by the fork pool's workers (:mod:`brdflab.workers`) and by the kernel build's child
(:mod:`brdflab.kernels.aot`); it imports nothing of brdflab, so the lowest layers can use it.
"""

from __future__ import annotations

import signal

#: ``prctl`` option: the signal the kernel sends this process when its parent dies (Linux).
PR_SET_PDEATHSIG = 1


def die_with_parent() -> None:
    """Ask Linux to SIGKILL this process when its parent dies (``prctl(PR_SET_PDEATHSIG)``); a no-op elsewhere."""
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    except (OSError, AttributeError):
        pass
