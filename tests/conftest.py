"""Compile (or load from numba's disk cache) every kernel once, before the first test, and say
how long it took, so the compile time is not charged to whichever test happens to run first."""

import signal

from mjrft.field.warmup import warm_up

_COMPILE = {}


def pytest_sessionstart(session):
    # The interrupt tests (test_signals, test_run, test_viz, test_guard) expect Python's own
    # SIGINT handler, in this process and in the children it starts; a shell that starts pytest
    # in the background without job control has it ignored instead, and Python keeps that.
    signal.signal(signal.SIGINT, signal.default_int_handler)
    _COMPILE["seconds"] = warm_up()


def pytest_terminal_summary(terminalreporter):
    seconds = _COMPILE.get("seconds")
    if seconds is not None:
        terminalreporter.write_line(
            f"mjrft: numba kernels compiled or loaded from cache in {seconds:.1f} s before the "
            "first test (mjrft.field.warmup)"
        )
