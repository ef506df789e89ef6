"""KernelChoice: the faster of two equivalent kernels, found by timing them (simulated time)."""

from __future__ import annotations

import itertools
import pickle

import pytest

from amaze.agents.kernel_choice import (
    MAX_RECHECK_SECONDS,
    RECHECK_SECONDS,
    TRIAL_CALLS,
    KernelChoice,
)


class Machine:
    """Simulated time: each kernel call advances it by that kernel's current cost."""

    def __init__(self, serial: float, parallel: float) -> None:
        self.now = 0.0
        self.cost = {False: serial, True: parallel}
        self.ran: list[bool] = []

    def clock(self) -> float:
        return self.now

    def kernel(self, parallel: bool):
        def run(x: int) -> int:
            self.now += self.cost[parallel]
            self.ran.append(parallel)
            return 2 * x

        return run

    def choice(self, parallel: bool | None = None) -> KernelChoice:
        return KernelChoice(self.kernel(False), self.kernel(True), parallel, clock=self.clock)


def run(choice: KernelChoice, calls: int) -> None:
    for x in range(calls):
        assert choice(x) == 2 * x


def test_fixed_choices_never_switch() -> None:
    for parallel in (False, True):
        machine = Machine(serial=1.0, parallel=1e-3 if not parallel else 1.0)
        choice = machine.choice(parallel)
        run(choice, 50)
        assert machine.ran == [parallel] * 50 and not choice.adaptive
        assert choice.calls[parallel] == 50 and choice.switches == 0


def test_the_faster_kernel_is_chosen_after_trying_both() -> None:
    trial = TRIAL_CALLS + 1  # the first call of a trial is not timed
    for serial, parallel, best in ((40e-6, 20e-6, True), (40e-6, 2e-3, False)):
        machine = Machine(serial, parallel)
        choice = machine.choice()
        run(choice, 2 * trial + 100)
        assert machine.ran[: 2 * trial] == [False] * trial + [True] * trial
        assert set(machine.ran[2 * trial :]) == {best} and choice.parallel == best
        assert choice.switches == 0  # the first decision is no switch


def test_a_slowed_down_kernel_is_tried_against_the_other_at_once() -> None:
    """Another process takes a core: the parallel kernel's calls stall, the serial one wins."""
    machine = Machine(serial=40e-6, parallel=20e-6)
    choice = machine.choice()
    run(choice, 50)
    assert choice.parallel
    machine.cost[True] = 3e-3
    run(choice, 20)  # the smoothed time per call doubles within a few calls
    assert not choice.parallel and choice.switches == 1
    slow = sum(machine.ran[50:])
    assert slow < 10  # a few slow calls, then the trial of the serial kernel
    run(choice, 200)
    assert not any(machine.ran[-200:])  # 200 serial calls take 8 ms, long before a recheck


def test_a_kernel_slower_than_the_other_was_is_tried_against_it() -> None:
    """A moderate slowdown (less than twice) that makes the other kernel the faster."""
    machine = Machine(serial=30e-6, parallel=20e-6)
    choice = machine.choice()
    run(choice, 50)
    assert choice.parallel
    machine.cost[True] = 36e-6
    run(choice, 100)
    assert not choice.parallel and choice.switches == 1
    assert sum(machine.ran[50:]) < 30


def test_a_disturbed_call_or_two_do_not_trigger_a_trial() -> None:
    """Two slow calls in a row (an interrupt, a page fault) are no trend."""
    machine = Machine(serial=30e-6, parallel=20e-6)
    choice = machine.choice()
    run(choice, 50)
    for _ in range(3):
        machine.cost[True] = 5e-3
        run(choice, 2)
        machine.cost[True] = 20e-6
        run(choice, 50)
    assert all(machine.ran[50:]) and choice.switches == 0


def test_the_other_kernel_is_tried_again_less_and_less_often() -> None:
    """While the machine stays busy, trials of the parallel kernel back off; when it is quiet
    again, the next trial finds out."""
    machine = Machine(serial=1e-3, parallel=50e-3)
    choice = machine.choice()
    trial_starts = []
    for _ in range(40000):
        before = choice.parallel
        choice(0)
        if choice.parallel and not before:
            trial_starts.append(machine.now)
    gaps = [b - a for a, b in itertools.pairwise(trial_starts)]
    trial = (TRIAL_CALLS + 1) * 50e-3
    assert len(gaps) == 5
    assert gaps[0] == pytest.approx(RECHECK_SECONDS + trial, rel=0.01)
    assert all(b > 1.5 * a for a, b in itertools.pairwise(gaps))
    assert max(gaps) == pytest.approx(MAX_RECHECK_SECONDS + trial, rel=0.01)
    assert sum(machine.ran) / len(machine.ran) < 0.002  # few calls spent on trials
    machine.cost[True] = 0.2e-3  # quiet again
    run(choice, int(MAX_RECHECK_SECONDS / 1e-3) + 100)
    assert choice.parallel and choice.switches == 1


def test_a_choice_pickles() -> None:
    choice = KernelChoice(abs, abs, None)
    clone = pickle.loads(pickle.dumps(choice))
    assert clone(-3) == 3 and clone.adaptive
