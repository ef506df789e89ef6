"""A Ctrl-C or SIGTERM sent from inside a library's writer, for tests of deferred signals."""

from __future__ import annotations

import os
import signal
from collections.abc import Callable
from typing import Any

import pytest


class Stopped(Exception):
    """What the test's handler raises for the signal it receives."""


def stop_inside(
    monkeypatch: pytest.MonkeyPatch, owner: Any, name: str, sent: int, write: Callable[[], object]
) -> None:
    """Run ``write()`` with ``owner.name`` sending ``sent`` to this process before it runs.

    Asserts that the signal is raised (as :class:`Stopped`) only after the
    patched function has run to its end, and that the handlers are restored.
    """
    real = getattr(owner, name)
    reached: list[str] = []

    def interrupted(*args: Any, **kwargs: Any) -> Any:
        os.kill(os.getpid(), sent)  # lands in the middle of the serialisation
        reached.append("after the signal")
        return real(*args, **kwargs)

    def stop(signum: int, frame: object) -> None:
        raise Stopped(signum)

    monkeypatch.setattr(owner, name, interrupted)
    previous = {s: signal.signal(s, stop) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        with pytest.raises(Stopped) as stopped:
            write()
        assert stopped.value.args == (sent,)
        assert reached == ["after the signal"]
        assert signal.getsignal(signal.SIGINT) is stop and signal.getsignal(signal.SIGTERM) is stop
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
