"""Ctrl-C and SIGTERM held back while a file is written: a stop lands before or after it.

A signal that lands inside a library's writer (numpy's zip writer under
``np.savez``, a ``ZipFile`` being closed) leaves half-closed objects behind,
and the garbage collector prints their tracebacks at exit, after the
command's own one-line message. Checkpoints, checkpoint folders
(:mod:`amaze.runs.folder`) and agent files (:mod:`amaze.agents.agent_file`)
are therefore written under :func:`signals_deferred`. A foundation module: it
imports no other part of amaze, so that every layer can use it.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator
from typing import Any

__all__ = ["DEFERRED_SIGNALS", "signals_deferred"]

#: The signals :func:`signals_deferred` holds back: Ctrl-C and SIGTERM.
DEFERRED_SIGNALS = (signal.SIGINT, signal.SIGTERM)


@contextlib.contextmanager
def signals_deferred() -> Iterator[None]:
    """Meanwhile, hold SIGINT and SIGTERM back; afterwards, deliver the first that came.

    The signal is raised again once the previous handlers are back, so it acts
    as it would have (``KeyboardInterrupt``, a ``Terminated`` of
    :mod:`amaze.runs.command`, the default exit), only later. Off the main
    thread, where Python runs no signal handler, nothing changes.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received: list[int] = []

    def hold(signum: int, frame: object) -> None:
        received.append(signum)

    previous: dict[int, Any] = {}
    try:
        for signum in DEFERRED_SIGNALS:
            handler = signal.getsignal(signum)
            if handler is not None:  # None: a handler not set from Python, left alone
                previous[signum] = signal.signal(signum, hold)
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        if received:
            signal.raise_signal(received[0])
