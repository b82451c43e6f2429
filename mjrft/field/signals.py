"""Holding Ctrl-C (and other signals) back over a block that must not be cut in two.

Installing a field, sending a recording's buffered frames and completing a run's files each
change several things that only make sense together; a KeyboardInterrupt between two of them
would leave the process or the files half-done. Inside ``HeldSignals`` the signals are only
recorded; leaving the block restores the previous handlers and delivers each recorded signal to
them once (so Ctrl-C raises KeyboardInterrupt there, and a handler of your own runs), unless
the block is leaving with an exception. Python runs signal handlers in the main thread only, so
elsewhere nothing is changed.
"""

from __future__ import annotations

import signal
import threading


class HeldSignals:
    """Record `signals` (default SIGINT) over a ``with`` block, then deliver them to the previous
    handlers. ``pending`` lists those that arrived, in order, without repeats."""

    def __init__(self, signals: tuple[int, ...] = (signal.SIGINT,)) -> None:
        self.signals = tuple(signals)
        self.pending: list[int] = []
        self._previous: dict[int, object] = {}

    def __enter__(self) -> HeldSignals:
        self.pending = []
        if threading.current_thread() is threading.main_thread():
            for sig in self.signals:
                previous = signal.getsignal(sig)
                if previous is not None:  # None: a handler not set from Python; leave it
                    self._previous[sig] = signal.signal(sig, self._record)
        return self

    def _record(self, signum: int, frame: object) -> None:
        if signum not in self.pending:
            self.pending.append(signum)

    def __exit__(self, kind, value, traceback) -> None:
        previous, self._previous = self._previous, {}
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        if kind is None:
            for sig in self.pending:
                if sig in previous:
                    signal.raise_signal(sig)  # runs the restored handler
