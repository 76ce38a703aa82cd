"""Ctrl-C and SIGTERM during a fit stop it at the next step, never inside one.

Python raises KeyboardInterrupt wherever the main thread happens to be when the signal arrives.
Inside torch.func.vmap (every batched encoder call) that leaves functorch's layer stack
half-pushed, and the fit then dies with "INTERNAL ASSERT FAILED ... DynamicLayer.cpp" and a
traceback instead of stopping cleanly (seen in the SIGTERM test). While a fit runs, the signals
are only noted; the training loop calls `check()` between steps, which hands the signal to the
handler that was there before (the command line's, or Python's own for Ctrl-C) and raises
KeyboardInterrupt at that safe point. A second signal before the next check is handled at once.
"""
from __future__ import annotations

import contextlib
import signal
import threading

_SIGNALS = (signal.SIGINT, signal.SIGTERM)
_active: list["_Deferred"] = []


class _Deferred:
    def __init__(self) -> None:
        self.previous: dict[int, object] = {}
        self.pending: int | None = None

    def handle(self, signum, frame) -> None:
        if self.previous.get(signum) == signal.SIG_IGN:  # e.g. a batch worker, whose parent owns Ctrl-C
            return
        if self.pending is None:
            self.pending = signum
            return
        self.deliver(signum, frame)  # asked twice: the user means now

    def deliver(self, signum: int, frame=None) -> None:
        previous = self.previous.get(signum)
        if callable(previous):
            previous(signum, frame)  # the command line's SIGTERM handler records that it was SIGTERM
        raise KeyboardInterrupt


@contextlib.contextmanager
def deferred_signals():
    """Within this block (main thread only), SIGINT and SIGTERM wait for the next `check()`."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    guard = _Deferred()
    for sig in _SIGNALS:
        guard.previous[sig] = signal.signal(sig, guard.handle)
    _active.append(guard)
    try:
        yield
    finally:
        _active.remove(guard)
        for sig, previous in guard.previous.items():
            if previous is not None:  # None: a handler not set from Python, which cannot be restored
                signal.signal(sig, previous)


def check() -> None:
    """Raise KeyboardInterrupt (through the earlier handler) if a signal arrived since the block began."""
    if _active and _active[-1].pending is not None:
        _active[-1].deliver(_active[-1].pending)


def pending() -> bool:
    """True when a signal arrived inside the current block."""
    return bool(_active) and _active[-1].pending is not None
