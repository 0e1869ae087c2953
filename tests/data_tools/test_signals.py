"""Signals held while an output's files are renamed into place, and a run ended at once."""
import os
import signal
import subprocess
import sys
import threading
from pathlib import Path

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
    # A signal given twice during the block is acted on once, after it.
    seen = []
    old = signal.signal(signal.SIGTERM, lambda n, frame: seen.append(n))
    try:
        with signals_held():
            os.kill(os.getpid(), signal.SIGTERM)
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


#: Ends at once while a folder, a link to a folder and a file are being built; a file built
#: earlier is finished, and no longer the run's to remove.
_END_AT_ONCE = """
import os, sys
from pathlib import Path
from data_tools.signals import building, end_at_once
d = Path(sys.argv[1])
(d / "done.png").write_bytes(b"x")
with building(d / "done.png"):
    pass
(d / "target").mkdir()
(d / "target" / "kept").write_bytes(b"x")
os.symlink("target", d / "link")
(d / "stage").mkdir()
(d / "stage" / "half.png").write_bytes(b"x")
with building(d / "stage"), building(d / "link"), building(d / "part.tmp"):
    (d / "part.tmp").write_bytes(b"x")
    end_at_once(3, [lambda: (d / "first").write_text(""), lambda: 1 / 0, lambda: (d / "last").write_text("")])
print("not reached")
"""


def test_ending_at_once_removes_what_is_being_built_and_calls_every_cleanup(tmp_path):
    p = subprocess.run([sys.executable, "-c", _END_AT_ONCE, tmp_path], capture_output=True, text=True, timeout=120,
                       cwd=Path(__file__).parents[2])
    assert (p.returncode, p.stdout) == (3, ""), p.stderr
    # The link goes, not what it points to; a cleanup that fails does not stop the next.
    assert sorted(f.name for f in tmp_path.iterdir()) == ["done.png", "first", "last", "target"]
    assert (tmp_path / "target" / "kept").exists()
