"""HeldSignals: a signal inside the block is held, then delivered once to the previous handler."""

from __future__ import annotations

import signal
import threading

import pytest

from mjrft.field.signals import HeldSignals


def test_ctrl_c_inside_is_raised_after_the_block():
    done = []
    with pytest.raises(KeyboardInterrupt):
        with HeldSignals() as held:
            signal.raise_signal(signal.SIGINT)
            done.append("rest of the block")  # not cut in two
    assert done == ["rest of the block"] and held.pending == [signal.SIGINT]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_own_handler_runs_once_after_the_block():
    calls = []
    previous = signal.signal(signal.SIGTERM, lambda s, f: calls.append(s))
    try:
        with HeldSignals((signal.SIGINT, signal.SIGTERM)):
            signal.raise_signal(signal.SIGTERM)
            signal.raise_signal(signal.SIGTERM)
            assert calls == []
        assert calls == [signal.SIGTERM]
    finally:
        signal.signal(signal.SIGTERM, previous)


def test_a_block_leaving_with_an_exception_delivers_nothing():
    with pytest.raises(ValueError):
        with HeldSignals() as held:
            signal.raise_signal(signal.SIGINT)
            raise ValueError("the block failed")
    assert held.pending == [signal.SIGINT]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_outside_the_main_thread_nothing_changes():
    seen = []

    def body():
        with HeldSignals():
            seen.append(signal.getsignal(signal.SIGINT))

    t = threading.Thread(target=body)
    t.start()
    t.join()
    assert seen == [signal.default_int_handler]
