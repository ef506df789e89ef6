"""Helpers of the tests that watch processes: waiting for a condition, telling a live process."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from collections.abc import Callable
from pathlib import Path

import pytest


def wait_until(condition: Callable[[], object], timeout: float = 120.0) -> None:
    """Return once ``condition()`` is true; fail the test after ``timeout`` seconds."""
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.05)


def process_running(pid: int) -> bool:
    """Whether process ``pid`` exists and is not a zombie (Linux's ``/proc``)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return False
    return state not in ("Z", "X")


def kill_after_rows(argv: list[str], progress: Path, rows: int, cwd: Path) -> None:
    """Start ``argv``, SIGKILL it once ``progress`` (a CSV) has more than ``rows`` lines.

    Fails the test if the process ends first or takes over two minutes.
    """
    process = subprocess.Popen(argv, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 120
    while not (progress.exists() and len(progress.read_text().splitlines()) > rows):
        if process.poll() is not None or time.monotonic() > deadline:
            process.kill()
            pytest.fail("the run ended before it could be killed")
        time.sleep(0.002)
    os.kill(process.pid, signal.SIGKILL)
    process.wait()
