"""Throughput of the SB3 adapter and of SB3 training on it (env steps per second).

1. Stepping, random actions drawn beforehand (seeded): :class:`SB3VecEnv` (one
   batch engine) against SB3's ``DummyVecEnv`` over N ``gymnasium.make("AMaze-v0")``
   environments, for N = 8, 16, 64 (``--n-envs``); each repeat times ``--steps``
   vector steps, the median over ``--repeats`` is printed.
2. Training: PPO and A2C (SB3 defaults, ``MlpPolicy``, torch with 1 thread) on the
   training maze's 4 rotations with ``SB3VecEnv``: env steps per second and the
   share of wall-clock time spent inside the environment's ``step_wait``.

Usage: ``python benchmarks/bench_sb3.py [--robot DD] [--train-steps 20000] [--json]``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from typing import Any

import gymnasium
import numpy as np
import torch
from stable_baselines3 import A2C, PPO
from stable_baselines3.common.vec_env import DummyVecEnv

import amaze  # noqa: F401  (registers AMaze-v0)
from amaze.evaluation.suite import PAPER_TRAINING_MAZE
from amaze.maze import rotations
from rl_baselines.vec_env import SB3VecEnv


def _rate(env: Any, actions: np.ndarray, repeats: int) -> float:
    rates = []
    for _ in range(repeats):
        env.reset()
        start = time.perf_counter()
        for batch in actions:
            env.step(batch)
        rates.append(actions.size / (time.perf_counter() - start))
    return statistics.median(rates)


def _maker(maze: str, robot: str) -> Any:
    """A factory of one ``AMaze-v0`` environment, as ``DummyVecEnv`` wants."""
    return lambda: gymnasium.make("AMaze-v0", maze=maze, robot=robot)


def stepping(robot: str, sizes: list[int], steps: int, repeats: int) -> list[dict[str, Any]]:
    """Steps/s of SB3VecEnv and DummyVecEnv for each number of environments."""
    mazes = rotations(PAPER_TRAINING_MAZE)
    rows = []
    for n in sizes:
        actions = np.random.default_rng(n).integers(0, 4, size=(steps, n))
        ours = SB3VecEnv(mazes, robot, n, seed=0)
        dummy = DummyVecEnv([_maker(mazes[k % len(mazes)], robot) for k in range(n)])
        rows.append(
            {
                "n_envs": n,
                "maze_vec_env": _rate(ours, actions, repeats),
                "dummy_vec_env": _rate(dummy, actions, repeats),
            }
        )
        dummy.close()
    return rows


class _TimedEnv(SB3VecEnv):
    """SB3VecEnv that adds up the time spent in ``step_wait``."""

    env_seconds = 0.0

    def step_wait(self) -> Any:
        start = time.perf_counter()
        result = super().step_wait()
        self.env_seconds += time.perf_counter() - start
        return result


def training(robot: str, steps: int, n_envs: int, repeats: int) -> list[dict[str, Any]]:
    """Env steps/s of PPO and A2C training (SB3 defaults) and the env's share of the time."""
    torch.set_num_threads(1)
    rows = []
    for name, cls in (("ppo", PPO), ("a2c", A2C)):
        rates, shares = [], []
        for repeat in range(repeats):
            env = _TimedEnv(rotations(PAPER_TRAINING_MAZE), robot, n_envs, seed=repeat)
            model = cls("MlpPolicy", env, seed=repeat, device="cpu", verbose=0)
            start = time.perf_counter()
            model.learn(steps)
            seconds = time.perf_counter() - start
            rates.append(model.num_timesteps / seconds)
            shares.append(env.env_seconds / seconds)
        rows.append(
            {
                "algo": name,
                "n_envs": n_envs,
                "steps_per_s": statistics.median(rates),
                "env_share": statistics.median(shares),
            }
        )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="DD")
    parser.add_argument("--n-envs", type=int, nargs="+", default=[8, 16, 64])
    parser.add_argument("--steps", type=int, default=2000, help="vector steps per repeat")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--train-steps", type=int, default=20_000)
    parser.add_argument("--train-envs", type=int, default=4)
    parser.add_argument("--train-repeats", type=int, default=3)
    parser.add_argument("--json", action="store_true", help="print JSON instead of tables")
    args = parser.parse_args()
    step_rows = stepping(args.robot, args.n_envs, args.steps, args.repeats)
    train_rows = training(args.robot, args.train_steps, args.train_envs, args.train_repeats)
    if args.json:
        print(json.dumps({"stepping": step_rows, "training": train_rows}, indent=2))
        return
    print(f"stepping, robot {args.robot}, random actions (env steps/s, median of {args.repeats})")
    print(f"{'n_envs':>6} {'SB3VecEnv':>12} {'DummyVecEnv':>12} {'speed-up':>9}")
    for r in step_rows:
        ratio = r["maze_vec_env"] / r["dummy_vec_env"]
        print(f"{r['n_envs']:>6} {r['maze_vec_env']:>12,.0f} {r['dummy_vec_env']:>12,.0f} "
              f"{ratio:>8.1f}x")  # fmt: skip
    print(f"\ntraining, robot {args.robot}, torch 1 thread, {args.train_steps} steps, "
          f"median of {args.train_repeats}")  # fmt: skip
    print(f"{'algo':>5} {'n_envs':>6} {'steps/s':>9} {'env share':>10}")
    for r in train_rows:
        print(f"{r['algo']:>5} {r['n_envs']:>6} {r['steps_per_s']:>9,.0f} {r['env_share']:>9.1%}")


if __name__ == "__main__":
    main()
