"""Test session set-up shared by every test file."""

import signal


def pytest_sessionstart(session):
    # The interrupt tests (test_signals, test_run, test_viz) expect Python's own SIGINT handler,
    # in this process and in the children it starts; a shell that starts pytest in the
    # background without job control has it ignored instead, and Python keeps that.
    signal.signal(signal.SIGINT, signal.default_int_handler)
