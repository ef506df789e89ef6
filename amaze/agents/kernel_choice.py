"""Serial or parallel: which of two equivalent kernels to run, decided by timing both.

A multi-threaded (numba ``prange``) kernel wins on a machine with idle cores and
loses badly on a shared one: every call ends at a barrier, and a worker thread
that waits for a core another process holds stalls the call for a scheduler
time slice (milliseconds, against some 30 µs for 4096 discrete agent-steps).
Neither the batch size nor the load average (a one-minute mean, blind to a
process started seconds ago) says which case holds now, so
:class:`KernelChoice` measures: it times a few calls of each kernel, runs the
faster, and tries the other again from time to time (less often while it keeps
losing), and at once when the chosen one slows down, to twice its time or past
the other's last time. The kernels give identical results, so the choice
changes how long a step takes, never what it returns.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

#: Timed calls of a kernel per trial, after one untimed call (which pays for
#: waking threads or refilling caches after the other kernel ran).
TRIAL_CALLS = 3
#: Seconds between two trials of the kernel not chosen; doubled after each
#: trial it loses, up to :data:`MAX_RECHECK_SECONDS`, and reset by a switch.
RECHECK_SECONDS = 1.0
MAX_RECHECK_SECONDS = 16.0
#: The other kernel is tried at once when the chosen one's calls take longer
#: than ``SLOWDOWN`` times the time it was chosen with, or ``MARGIN`` times the
#: other's time when last tried.
SLOWDOWN = 2.0
MARGIN = 1.1
# weight of one call in the running time per call, and the most one call can
# move it (a single call disturbed by an interrupt must not trigger a trial)
_SMOOTHING = 0.125
_MAX_JUMP = 4.0
# calls of the chosen kernel whose median confirms a slowdown
_RECENT = 5


class KernelChoice:
    """Runs ``serial`` or ``parallel_kernel`` (same arguments, same results), the faster one.

    ``parallel=None`` chooses by timing (see the module docstring); True or
    False runs that kernel on every call. Calling the instance runs the chosen
    kernel and returns what it returns. ``clock`` (seconds, monotonic) is
    :func:`time.perf_counter` unless a test gives its own.

    ``parallel`` tells which kernel the next call runs; ``calls`` counts the
    calls that ran each (``calls[True]``: parallel), trials included, and
    ``switches`` how often a trial changed the choice made by an earlier one.
    """

    def __init__(
        self,
        serial: Callable[..., Any],
        parallel_kernel: Callable[..., Any],
        parallel: bool | None = None,
        *,
        clock: Callable[[], float] = time.perf_counter,
    ) -> None:
        self.kernels = (serial, parallel_kernel)
        self.adaptive = parallel is None
        self.parallel = bool(parallel)
        self.calls = [0, 0]
        self.switches = 0
        self._clock = clock
        # seconds per call of each kernel when last tried (None: not yet)
        self._cost: list[float | None] = [None, None]
        self._chosen: bool | None = None  # the choice of the last trial
        self._trial: list[float] = []  # timed calls of the trial in progress
        self._trying = self.adaptive  # a trial is in progress
        self._running = 0.0  # smoothed seconds per call of the chosen kernel
        self._recent = [0.0] * _RECENT  # its last calls, a ring
        self._next = 0  # where the ring's next call goes
        self._limit = 0.0  # a trial starts at once when its calls take longer than this
        self._recheck = RECHECK_SECONDS
        self._next_trial = 0.0

    def __call__(self, *args: Any) -> Any:
        parallel = self.parallel
        self.calls[parallel] += 1
        if not self.adaptive:
            return self.kernels[parallel](*args)
        start = self._clock()
        result = self.kernels[parallel](*args)
        now = self._clock()
        seconds = now - start
        if self._trying:
            self._try(parallel, seconds, now)
        else:
            self._recent[self._next] = seconds
            self._next = (self._next + 1) % _RECENT
            running = self._running
            running += _SMOOTHING * (min(seconds, _MAX_JUMP * running) - running)
            self._running = running
            if running > self._limit or now >= self._next_trial:
                # the smoothed time says "slower" at once, the median of the last
                # calls whether it lasts (a call or two disturbed by an interrupt
                # or a page fault do not make a trend)
                recent = sorted(self._recent)[_RECENT // 2]
                if recent > self._limit or now >= self._next_trial:
                    self._cost[parallel] = recent
                    self._start_trial(not parallel)
                else:
                    self._running = recent
        return result

    def _start_trial(self, parallel: bool) -> None:
        self.parallel = parallel
        self._trying = True
        self._trial = []

    def _try(self, parallel: bool, seconds: float, now: float) -> None:
        """Count one call of a trial of ``parallel``, of ``seconds``, that ended at ``now``."""
        trial = self._trial
        trial.append(seconds)
        if len(trial) <= TRIAL_CALLS:  # the first call is not counted
            return
        self._cost[parallel] = sorted(trial[1:])[TRIAL_CALLS // 2]
        if self._cost[not parallel] is None:  # the first choice: try the other kernel too
            self._start_trial(not parallel)
            return
        serial_cost, parallel_cost = self._cost
        assert serial_cost is not None and parallel_cost is not None
        best = parallel_cost < serial_cost
        if best == self._chosen:  # no change: try the other less often
            self._recheck = min(2 * self._recheck, MAX_RECHECK_SECONDS)
        else:
            self.switches += self._chosen is not None
            self._recheck = RECHECK_SECONDS
        self._chosen = best
        self.parallel = best
        self._trying = False
        self._running = self._cost[best]
        self._recent = [self._running] * _RECENT
        other = serial_cost if best else parallel_cost
        self._limit = min(SLOWDOWN * self._running, MARGIN * other)
        self._next_trial = now + self._recheck
