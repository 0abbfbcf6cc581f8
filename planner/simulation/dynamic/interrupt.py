"""Ctrl-C while a compiled engine runs Python callbacks.

A C++ solver that calls Python user functions (Exudyn's force, right-hand side and pre-step
functions) catches what they raise: a ``KeyboardInterrupt`` raised inside one is swallowed,
reported as the engine's own failure (a run "diverged") or ignored, and the solve goes on. So
for the length of a solve, SIGINT only *asks* to stop: :class:`DeferredInterrupt` records the
request, the engine's pre-step function returns False at the next step (``requested``), and
when the solve has returned the ``with`` block raises ``KeyboardInterrupt`` in plain Python,
where the CLI turns it into one line and exit 130 like every other command.

Only the main thread's default handler is replaced (a worker process that ignores SIGINT, or
a program with a handler of its own, keeps it), and the previous handler is always restored.
"""
from __future__ import annotations

import signal
import threading

__all__ = ["DeferredInterrupt"]


class DeferredInterrupt:
    """``with DeferredInterrupt() as stop: engine.solve()`` — ``stop.requested`` turns True on
    SIGINT during the block; on leaving it (without another exception) KeyboardInterrupt is
    raised if it did."""

    def __init__(self):
        self.requested = False
        self._previous = None

    def _ask(self, signum, frame):
        self.requested = True

    def __enter__(self) -> "DeferredInterrupt":
        self.requested = False
        if threading.current_thread() is threading.main_thread() and \
                signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            self._previous = signal.signal(signal.SIGINT, self._ask)
        return self

    def __exit__(self, exc_type, exc, tb) -> bool:
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)
            self._previous = None
        if self.requested and exc_type is None:
            raise KeyboardInterrupt
        return False
