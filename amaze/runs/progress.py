"""What a long training loop shows while it works: a bar on a terminal, plain lines elsewhere.

A run on a terminal shows a ``tqdm`` bar (its budget, rate and ETA). A run
whose output goes to a file, a pipe or a cluster's log (``nohup``, a
replicate, a study's worker) cannot use a bar: it prints a plain line on
standard output when it starts, then at least every :data:`PROGRESS_EVERY`
seconds, and when it ends, so that hours of training are never hours of
silence::

    [12:03:41] edhucat careful seed 0: 35% of 3,000,000 steps, 1m20s elapsed, ETA 2m29s;
    stage 3, success 0.50

Every loop (evolution's generations, RL's rollouts, a curriculum's
branches, co-evolution's rounds) reports through :class:`Progress`.
"""

from __future__ import annotations

import sys
import time
from types import TracebackType
from typing import Any, TextIO

__all__ = ["PROGRESS_EVERY", "PROGRESS_MODES", "Progress", "format_duration"]

#: Seconds between two plain progress lines, at most.
PROGRESS_EVERY = 30.0
#: How a loop shows its progress: a bar (a terminal), plain lines, or nothing (a library call).
PROGRESS_MODES = ("bar", "lines", "off")


def format_duration(seconds: float) -> str:
    """``95`` -> ``"1m35s"``; ``3700`` -> ``"1h01m"``; ``4.2`` -> ``"4.2s"``."""
    if seconds < 60:
        return f"{seconds:.1f}s"
    minutes, secs = divmod(int(seconds), 60)
    if minutes < 60:
        return f"{minutes}m{secs:02d}s"
    hours, minutes = divmod(minutes, 60)
    return f"{hours}h{minutes:02d}m"


class Progress:
    """A loop's progress toward ``total`` (in ``unit``): a bar, or plain lines (see the module).

    ``mode`` is one of :data:`PROGRESS_MODES`: ``bar`` shows a ``tqdm`` bar
    (a terminal); ``lines`` prints lines to ``stream`` (standard output),
    every ``every`` seconds at most; ``off`` shows nothing. ``update`` takes
    how much is done so far (not an increment) and the loop's key figures,
    shown beside it.
    """

    def __init__(
        self,
        total: float | None,
        unit: str,
        desc: str,
        *,
        mode: str,
        initial: float = 0.0,
        every: float = PROGRESS_EVERY,
        stream: TextIO | None = None,
    ) -> None:
        self.total, self.unit, self.desc, self.every = total, unit, desc, every
        if mode not in PROGRESS_MODES:
            raise ValueError(f"progress {mode!r} is not one of {', '.join(PROGRESS_MODES)}")
        self.mode, self.stream = mode, stream
        self.done = float(initial)
        self.figures: dict[str, Any] = {}
        self.started = self.last_line = time.monotonic()
        self.bar: Any = None
        if mode == "bar":
            from tqdm import tqdm

            self.bar = tqdm(
                total=total, initial=initial, unit=unit, unit_scale=True, desc=desc,
                dynamic_ncols=True,
            )  # fmt: skip
        elif mode == "lines":
            self.line("started")

    def update(self, done: float, **figures: Any) -> None:
        """``done`` of the total is spent now; ``figures`` are shown beside it."""
        self.done = float(done)
        self.figures = figures
        if self.bar is not None:
            shown = self.done if self.total is None else min(self.done, self.total)
            self.bar.update(shown - self.bar.n)
            if figures:
                self.bar.set_postfix(figures, refresh=False)
        elif self.mode == "lines" and time.monotonic() - self.last_line >= self.every:
            self.line()

    def line(self, note: str = "") -> None:
        """One plain progress line, now."""
        elapsed = time.monotonic() - self.started
        if self.total:
            share = self.done / self.total
            text = f"{share:.0%} of {self.total:,.0f} {self.unit}"
            if 0 < share < 1 and note != "done":
                text += f", ETA {format_duration(elapsed * (1 - share) / share)}"
        else:
            text = f"{self.done:,.0f} {self.unit}"
        figures = ", ".join(f"{key} {value}" for key, value in self.figures.items())
        parts = [text, f"{format_duration(elapsed)} elapsed", note, figures]
        stamp = time.strftime("%H:%M:%S")
        stream = self.stream if self.stream is not None else sys.stdout
        text = "; ".join(part for part in parts if part)
        print(f"[{stamp}] {self.desc}: {text}", file=stream, flush=True)
        self.last_line = time.monotonic()

    def close(self) -> None:
        """End the bar, or print the last line."""
        if self.bar is not None:
            self.bar.close()
        elif self.mode == "lines":
            self.line("done")

    def __enter__(self) -> Progress:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        value: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        if kind is None:
            self.close()
        elif self.bar is not None:
            self.bar.close()
