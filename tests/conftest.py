"""Compile (or load from numba's disk cache) every kernel once, before the first test, and say
how long it took, so the compile time is not charged to whichever test happens to run first."""

from mjrft.field.warmup import warm_up

_COMPILE = {}


def pytest_sessionstart(session):
    _COMPILE["seconds"] = warm_up()


def pytest_terminal_summary(terminalreporter):
    seconds = _COMPILE.get("seconds")
    if seconds is not None:
        terminalreporter.write_line(
            f"mjrft: numba kernels compiled or loaded from cache in {seconds:.1f} s before the "
            "first test (mjrft.field.warmup)"
        )
