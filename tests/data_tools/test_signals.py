"""Signals held while an output's files are renamed into place."""
import os
import signal
import threading

import pytest

from data_tools.signals import signals_held


def test_a_ctrl_c_during_the_block_comes_after_it():
    done = []
    old = signal.signal(signal.SIGINT, signal.default_int_handler)     # a test runner's worker may ignore it
    try:
        with pytest.raises(KeyboardInterrupt):
            with signals_held():
                signal.raise_signal(signal.SIGINT)
                done.append("first")
                signal.raise_signal(signal.SIGINT)      # twice: acted on once
                done.append("second")
        assert done == ["first", "second"]
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    finally:
        signal.signal(signal.SIGINT, old)


def test_the_handlers_are_put_back():
    seen = []
    old = signal.signal(signal.SIGTERM, lambda n, frame: seen.append(n))
    try:
        with signals_held():
            os.kill(os.getpid(), signal.SIGTERM)
            assert seen == []
        assert seen == [signal.SIGTERM]
        with signals_held():
            pass
        signal.raise_signal(signal.SIGTERM)
        assert seen == [signal.SIGTERM] * 2
    finally:
        signal.signal(signal.SIGTERM, old)


def test_off_the_main_thread_nothing_is_held():
    errors = []

    def block():
        try:
            with signals_held():
                pass
        except Exception as exc:  # noqa: BLE001
            errors.append(exc)
    t = threading.Thread(target=block)
    t.start()
    t.join()
    assert errors == []
