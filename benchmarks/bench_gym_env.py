"""Throughput of the single-agent gymnasium environment ``AMaze-v0`` (steps per second).

One environment, ``gymnasium.make("AMaze-v0", maze=..., robot=...)``, stepped
with random actions drawn beforehand (a list of Python ints, or of float pairs
for continuous robots; never ``action_space.sample()`` inside the timing), and
reset whenever an episode ends. Each repeat times ``--steps`` steps; the median
over ``--repeats`` is printed, for the environment as ``gymnasium.make`` returns
it (with gymnasium's order-enforcing and passive-checker wrappers) and for the
bare ``MazeEnv``. Goal on a 2-core machine: >= 200k steps/s for ``DD``.

With ``--reference-python PATH`` the same loop also runs against the reference
library amaze-benchmarker 1.0's gymnasium wrapper
(``amaze.extensions.sb3.maze_env.MazeEnv``), bare and inside the same two
gymnasium wrappers, in a separate throw-away virtual environment (never a
dependency of this project; its wrapper needs stable-baselines3)::

    python3 -m venv /tmp/refvenv
    /tmp/refvenv/bin/pip install amaze-benchmarker==1.0 stable-baselines3 pillow tensorboard
    python benchmarks/bench_gym_env.py --reference-python /tmp/refvenv/bin/python
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from typing import Any

REFERENCE_SCRIPT = """
import json, logging, statistics, sys, time
logging.disable(logging.CRITICAL)
import gymnasium
from gymnasium.wrappers import OrderEnforcing, PassiveEnvChecker
from amaze.simu.maze import Maze
from amaze.simu.robot import Robot
from amaze.extensions.sb3.maze_env import MazeEnv
maze, robot, steps, repeats = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
actions = json.loads(sys.stdin.read())
def make(wrapped):
    env = MazeEnv(Maze.BuildData.from_string(maze), Robot.BuildData.from_string(robot))
    return OrderEnforcing(PassiveEnvChecker(env)) if wrapped else env
def rate(env):
    rates = []
    for _ in range(repeats):
        env.reset(seed=0)
        step, reset = env.step, env.reset
        start = time.perf_counter()
        for action in actions:
            _, _, terminated, truncated, _ = step(action)
            if terminated or truncated:
                reset()
        rates.append(len(actions) / (time.perf_counter() - start))
    return statistics.median(rates)
print(json.dumps({"make": rate(make(True)), "bare": rate(make(False))}))
"""


def random_actions(robot: str, steps: int, seed: int = 0) -> list[Any]:
    """``steps`` random actions as plain Python values: ints 0..3 or ``[ax, ay]`` pairs."""
    import numpy as np

    rng = np.random.default_rng(seed)
    if robot.startswith("C"):
        return rng.uniform(-1, 1, size=(steps, 2)).astype(np.float32).tolist()
    return rng.integers(0, 4, size=steps).tolist()


def timed_loop(env: Any, actions: list[Any], repeats: int) -> list[float]:
    """Steps per second of each repeat (the environment is reset when an episode ends)."""
    rates = []
    for _ in range(repeats):
        env.reset(seed=0)
        step: Callable[[Any], Any] = env.step
        reset = env.reset
        start = time.perf_counter()
        for action in actions:
            _, _, terminated, truncated, _ = step(action)
            if terminated or truncated:
                reset()
        rates.append(len(actions) / (time.perf_counter() - start))
    return rates


def ours(maze: str, robot: str, actions: list[Any], repeats: int) -> dict[str, float]:
    """Median steps/s of ``AMaze-v0`` as ``gymnasium.make`` returns it, and bare."""
    import gymnasium

    import amaze  # noqa: F401  (registers AMaze-v0)

    made = gymnasium.make("AMaze-v0", maze=maze, robot=robot)
    timed_loop(made, actions[:1000], 1)  # warm up (first-step checks, lazy tables)
    return {
        "make": statistics.median(timed_loop(made, actions, repeats)),
        "bare": statistics.median(timed_loop(made.unwrapped, actions, repeats)),
    }


def reference(
    python: str, maze: str, robot: str, actions: list[Any], repeats: int
) -> dict[str, float]:
    """The same loop in amaze-benchmarker 1.0, run by ``python`` from a scratch directory."""
    env = {**os.environ, "QT_QPA_PLATFORM": "offscreen", "KGD_AMAZE_NOCACHE": "1"}
    with tempfile.TemporaryDirectory() as scratch:  # the reference writes ./resources
        result = subprocess.run(
            [python, "-c", REFERENCE_SCRIPT, maze, robot, str(len(actions)), str(repeats)],
            input=json.dumps(actions),
            cwd=scratch,
            env=env,
            capture_output=True,
            text=True,
            check=False,
        )
    if result.returncode != 0:
        raise SystemExit(f"the reference run failed:\n{result.stderr.strip()}")
    return json.loads(result.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--maze", default="M0_10x10_C1")
    parser.add_argument("--robots", nargs="+", default=["DD"], help="e.g. DD H15 CC15")
    parser.add_argument("--steps", type=int, default=200_000, help="steps per repeat")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--reference-python", metavar="PATH", help="python of a reference venv")
    args = parser.parse_args(argv)
    print(f"AMaze-v0 in {args.maze}, {args.steps} steps x {args.repeats} repeats, median steps/s")
    for robot in args.robots:
        actions = random_actions(robot, args.steps)
        rates = ours(args.maze, robot, actions, args.repeats)
        line = f"{robot:>5}: amaze-evo make {rates['make']:9.0f}  bare {rates['bare']:9.0f}"
        if args.reference_python:
            ref_steps = min(args.steps, 50_000)  # the reference is slow
            ref = reference(args.reference_python, args.maze, robot, actions[:ref_steps], 3)
            line += (
                f"   reference make {ref['make']:8.0f}  bare {ref['bare']:8.0f}"
                f"   ratio {rates['make'] / ref['make']:4.1f}x"
            )
        print(line, flush=True)


if __name__ == "__main__":
    sys.exit(main())
