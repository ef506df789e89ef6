"""Throughput of the batch engine: agent-steps per second, per robot kind.

Many agents with random actions (drawn beforehand, not timed) on the paper's
complex 20x20 mazes ``M<seed>_20x20_C1_l.25_L.25_t.5_T.5``; each repeat resets
and times ``--steps`` steps, and the median over ``--repeats`` is printed with
the smallest and largest rate. Goals on a 2-core machine: discrete >= 50 M,
hybrid (H15) >= 2 M, continuous (CC15) >= 1 M agent-steps/s, and ``DD`` in the
vector environment at 4096 envs >= 70 M agent-steps/s while another CPU-bound
process runs.

``--target engine`` (the default) steps a ``BatchEngine``; ``--target vector``
steps the gymnasium vector environment as users make it,
``gymnasium.make_vec("AMaze-v0", num_envs=N, vectorization_mode="vector_entry_point", ...)``,
end-of-episode ``infos`` included.

``--load quiet`` measures on the machine as it is; ``--load busy`` starts a
CPU-bound competitor process (a Python busy loop) after the warm-up, measures
while it runs and stops it; ``--load both`` prints the quiet row, then the busy
one, from the same engine, whose kernel choice made on the quiet machine must
then adapt. Run it on an otherwise idle machine.

By default the engine picks its serial or parallel kernels by timing them
(``BatchEngine``'s ``parallel=None``); ``--parallel on`` / ``off`` forces one
family. Each row says which kernels ran: the share of timed calls that ran the
parallel one and how often the choice switched.

Usage: ``python benchmarks/bench_engine.py [--agents 4096] [--modes DD H15 CC15]
[--target engine|vector] [--load quiet|busy|both] [--parallel auto|on|off]``;
the issue's figure: ``python benchmarks/bench_engine.py --target vector --modes DD --load both``.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import gymnasium
import numba
import numpy as np

import amaze  # noqa: F401  (registers AMaze-v0)
from amaze.agents.engine import BatchEngine

MAZE = "M{seed}_20x20_C1_l.25_L.25_t.5_T.5"
#: Untimed steps before the first repeat: compilation, and the engine's first
#: choice of kernels (a few calls of each).
WARMUP_STEPS = 50
#: Seconds the competitor runs before the busy measurement starts.
SETTLE_SECONDS = 0.5


@contextmanager
def competitor() -> Iterator[None]:
    """A CPU-bound process (a Python busy loop) running for the duration of the block."""
    process = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        time.sleep(SETTLE_SECONDS)
        yield
    finally:
        process.kill()
        process.wait()


class Target:
    """What is stepped: the engine itself, or the vector environment on it."""

    def __init__(
        self, target: str, robot: str, n_agents: int, n_mazes: int, parallel: bool | None
    ) -> None:
        mazes = [MAZE.format(seed=s) for s in range(n_mazes)]
        if target == "engine":
            self.engine = BatchEngine(mazes, robot, n_agents, parallel=parallel)
            self.step: Callable[[np.ndarray], object] = self.engine.step
            self.reset: Callable[[], object] = self.engine.reset
        else:
            env = gymnasium.make_vec(
                "AMaze-v0",
                num_envs=n_agents,
                vectorization_mode="vector_entry_point",
                maze=mazes,
                robot=robot,
                parallel=parallel,
            )
            self.engine = env.unwrapped.engine
            self.step = env.step
            self.reset = env.reset

    def kernels(self) -> tuple[int, int, int]:
        """Calls so far of the serial and the parallel kernel, and switches between them."""
        choice = self.engine.kernel_choice
        return choice.calls[0], choice.calls[1], choice.switches


def bench(target: Target, actions: np.ndarray, repeats: int) -> tuple[list[float], str]:
    """Agent-steps per second of each repeat, and which kernels ran."""
    steps, n_agents = actions.shape[:2]
    serial0, parallel0, switches0 = target.kernels()
    rates = []
    for _ in range(repeats):
        target.reset()
        step = target.step
        start = time.perf_counter()
        for t in range(steps):
            step(actions[t])
        elapsed = time.perf_counter() - start
        rates.append(steps * n_agents / elapsed)
    serial, parallel, switches = target.kernels()
    calls = serial - serial0 + parallel - parallel0
    share = (parallel - parallel0) / calls
    if not target.engine.kernel_choice.adaptive:
        used = "parallel" if share else "serial"
    else:
        used = f"auto: parallel {100 * share:.0f}% of calls, {switches - switches0} switches"
    return rates, used


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--agents", type=int, default=4096)
    parser.add_argument("--mazes", type=int, default=16, help="distinct maze seeds")
    parser.add_argument("--steps", type=int, default=0, help="steps per repeat (0: per mode)")
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--modes", nargs="+", default=["DD", "H15", "CC15"])
    parser.add_argument("--target", choices=["engine", "vector"], default="engine")
    parser.add_argument("--load", choices=["quiet", "busy", "both"], default="quiet")
    parser.add_argument("--parallel", choices=["auto", "on", "off"], default="auto")
    args = parser.parse_args(argv)
    parallel = {"auto": None, "on": True, "off": False}[args.parallel]
    loads = ["quiet", "busy"] if args.load == "both" else [args.load]
    print(
        f"numba threads: {numba.get_num_threads()}, {args.target}, agents: {args.agents},"
        f" {args.repeats} repeats"
    )
    default_steps = {"D": 2000, "H": 100, "C": 100}
    for robot in args.modes:
        steps = args.steps or default_steps[robot[0]]
        rng = np.random.default_rng(0)
        if robot.startswith("C"):
            actions = rng.uniform(-1, 1, size=(steps, args.agents, 2))
        else:
            actions = rng.integers(0, 4, size=(steps, args.agents), dtype=np.int64)
        target = Target(args.target, robot, args.agents, args.mazes, parallel)
        target.reset()
        for t in range(WARMUP_STEPS):
            target.step(actions[t % steps])
        for load in loads:
            if load == "busy":
                with competitor():
                    rates, used = bench(target, actions, args.repeats)
            else:
                rates, used = bench(target, actions, args.repeats)
            median = statistics.median(rates) / 1e6
            print(
                f"{robot:>5} {load:>5}: median {median:8.2f} M agent-steps/s"
                f"  (min {min(rates) / 1e6:.2f}, max {max(rates) / 1e6:.2f};"
                f" {steps} steps per repeat; {used})"
            )


if __name__ == "__main__":
    main()
