"""Ctrl-C and SIGTERM wait while a file is written (amaze.signals), agent files included."""

from __future__ import annotations

import os
import signal
import threading
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from amaze.agents.agent_file import read_agent, save_agent
from amaze.signals import signals_deferred
from tests.stops import stop_inside

ARCHITECTURE = {"type": "mlp", "hidden": [3]}


@pytest.fixture(autouse=True)
def _python_ctrl_c() -> Iterator[None]:
    """Python's own Ctrl-C handler during each test, whatever the suite was started with
    (a shell starts a background job with SIGINT ignored, and Python then keeps it so)."""
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, before)


def test_signals_deferred_delivers_ctrl_c_after_the_block() -> None:
    done = []
    with pytest.raises(KeyboardInterrupt):
        with signals_deferred():
            os.kill(os.getpid(), signal.SIGINT)
            done.append("the block went on")
    assert done == ["the block went on"]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_signals_deferred_changes_nothing_off_the_main_thread() -> None:
    seen = []

    def body() -> None:
        with signals_deferred():
            seen.append(signal.getsignal(signal.SIGINT))

    thread = threading.Thread(target=body)
    thread.start()
    thread.join()
    assert seen == [signal.default_int_handler]


@pytest.mark.parametrize("sent", [signal.SIGINT, signal.SIGTERM])
def test_a_stop_while_an_agent_file_is_written_lands_after_the_whole_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, sent: int
) -> None:
    """A signal from inside numpy's zip writer is raised once the file is in place, whole."""
    path = tmp_path / "agent.npz"
    arrays = {"w": np.arange(5.0)}
    metadata = {"architecture": ARCHITECTURE, "robot": "DD"}
    stop_inside(monkeypatch, np, "savez", sent, lambda: save_agent(path, arrays, metadata))
    arrays, _ = read_agent(path)
    np.testing.assert_array_equal(arrays["w"], np.arange(5.0))
    assert [p.name for p in tmp_path.iterdir()] == ["agent.npz"]  # no temporary file left
