"""A long set-up on a terminal: one line that counts its seconds, erased when it ends; on a pipe
nothing of it."""

import io
import logging
import subprocess
import sys
import time

from contactopt._progress import LiveLine, progress, task


class _Terminal(io.StringIO):
    def isatty(self):
        return True


def test_live_line_counts_the_seconds_and_is_erased():
    stream = _Terminal()
    live = LiveLine(stream, delay=0.2, interval=0.05)
    progress.addHandler(live)
    old = progress.level
    progress.setLevel(logging.DEBUG)
    try:
        with task("factorizing a matrix of 10 unknowns"):
            time.sleep(0.6)
        shown = stream.getvalue()
        with task("a short one"):
            pass
        time.sleep(0.15)
    finally:
        progress.removeHandler(live)
        progress.setLevel(old)
        live.close()
    assert "\rfactorizing a matrix of 10 unknowns … 0 s" in shown.replace("\033[K", "")
    assert shown.endswith("\r\033[K")                       # erased at the end
    assert "a short one" not in stream.getvalue()          # shorter than the delay: never shown


def test_a_pipe_gets_no_live_line(tmp_path, config_file):
    """`contactopt state` with its output piped: no carriage return, no progress record."""
    proc = subprocess.run([sys.executable, "-m", "contactopt.cli", "state", str(config_file()), "--out",
                           str(tmp_path / "s")], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert "\r" not in proc.stderr and "factorizing" not in proc.stderr
