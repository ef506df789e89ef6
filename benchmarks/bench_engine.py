"""Throughput of the batch engine: agent-steps per second, per robot kind.

Many agents with random actions (drawn beforehand, not timed) on the paper's
complex 20x20 mazes ``M<seed>_20x20_C1_l.25_L.25_t.5_T.5``; each repeat times
``--steps`` calls of ``BatchEngine.step`` and the median over ``--repeats`` is
printed. Goals on a 2-core machine: discrete >= 50 M, hybrid (H15) >= 2 M,
continuous (CC15) >= 1 M agent-steps/s.

By default the engine picks its serial or parallel kernels (``BatchEngine``'s
``parallel=None``); ``--parallel on`` / ``off`` forces one family.

Usage: ``python benchmarks/bench_engine.py [--agents 4096] [--modes DD H15 CC15] [--parallel on]``
"""

from __future__ import annotations

import argparse
import statistics
import time

import numba
import numpy as np

from amaze.agents.engine import BatchEngine

MAZE = "M{seed}_20x20_C1_l.25_L.25_t.5_T.5"


def bench(
    robot: str, n_agents: int, n_mazes: int, steps: int, repeats: int, parallel: bool | None = None
) -> tuple[list[float], bool]:
    """Agent-steps per second of each repeat for ``robot``, and whether it ran in parallel."""
    mazes = [MAZE.format(seed=s) for s in range(n_mazes)]
    engine = BatchEngine(mazes, robot, n_agents, parallel=parallel)
    rng = np.random.default_rng(0)
    if robot.startswith("C"):
        actions = rng.uniform(-1, 1, size=(steps, n_agents, 2))
    else:
        actions = rng.integers(0, 4, size=(steps, n_agents), dtype=np.int64)
    engine.step(actions[0])  # compile / warm up
    rates = []
    for _ in range(repeats):
        engine.reset()
        start = time.perf_counter()
        for t in range(steps):
            engine.step(actions[t])
        elapsed = time.perf_counter() - start
        rates.append(steps * n_agents / elapsed)
    return rates, engine.parallel


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--agents", type=int, default=4096)
    parser.add_argument("--mazes", type=int, default=16, help="distinct maze seeds")
    parser.add_argument("--steps", type=int, default=0, help="steps per repeat (0: per mode)")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--modes", nargs="+", default=["DD", "H15", "CC15"])
    parser.add_argument("--parallel", choices=["auto", "on", "off"], default="auto")
    args = parser.parse_args(argv)
    parallel = {"auto": None, "on": True, "off": False}[args.parallel]
    print(f"numba threads: {numba.get_num_threads()}, agents: {args.agents}")
    default_steps = {"D": 500, "H": 100, "C": 100}
    for robot in args.modes:
        steps = args.steps or default_steps[robot[0]]
        rates, used_parallel = bench(robot, args.agents, args.mazes, steps, args.repeats, parallel)
        print(
            f"{robot:>5}: median {statistics.median(rates) / 1e6:8.2f} M agent-steps/s"
            f"  (min {min(rates) / 1e6:.2f}, max {max(rates) / 1e6:.2f};"
            f" {args.repeats} x {steps} steps, {'parallel' if used_parallel else 'serial'})"
        )


if __name__ == "__main__":
    main()
