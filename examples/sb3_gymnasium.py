"""Stable-Baselines3 PPO on the gymnasium environment ``AMaze-v0``.

``import amaze`` registers ``AMaze-v0`` with gymnasium, so any library that
trains on gymnasium environments trains on mazes:
``gymnasium.make("AMaze-v0", maze=..., robot=...)`` is one robot in one maze.
Here four of them, one per rotation of the maze (the robot starting from each
corner), make SB3's vectorised environment; SB3's ``EvalCallback`` watches
the agent on the same four rotations during training and keeps the best
model. At the end, the model is wrapped as a policy of the project
(:class:`rl_baselines.agent.SB3Agent`) and scored with the evaluation protocol
that scores every agent (:func:`amaze.evaluation.protocol.evaluate`).

Run it::

    python examples/sb3_gymnasium.py            # 100 k env steps: about 30 s on 2 CPU cores
    python examples/sb3_gymnasium.py --tiny     # a few hundred steps: a smoke test

Needs only the project's dependencies (stable-baselines3, gymnasium, torch).
"""

from __future__ import annotations

import argparse
import tempfile
import time

import gymnasium
import numba
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import EvalCallback
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv

import amaze  # noqa: F401  (registers AMaze-v0 with gymnasium)
from amaze.evaluation.protocol import evaluate
from amaze.maze import rotations
from rl_baselines.agent import SB3Agent

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--tiny", action="store_true", help="a few hundred steps (for the tests)")
parser.add_argument("--maze", default="M4_5x5_C1", help="the maze to learn (4 rotations)")
parser.add_argument("--steps", type=int, default=100_000, help="env steps to train for")
parser.add_argument("--seed", type=int, default=0)
args = parser.parse_args()
steps = 512 if args.tiny else args.steps
# Small networks and small batches: one thread each is fastest. torch and the batch engine's
# numba kernels share one OpenMP runtime, where threads left spinning by one slow the other.
torch.set_num_threads(1)
numba.set_num_threads(1)

# -- environments: the maze started from each of its four corners ----------------

mazes = rotations(args.maze)  # M4_5x5_NW_C1, M4_5x5_NE_C1, M4_5x5_C1 (SW), M4_5x5_SE_C1


def make_env(maze: str):
    # Monitor records each episode's return and length for SB3's logs and callbacks
    return lambda: Monitor(gymnasium.make("AMaze-v0", maze=maze, robot="DD"))


train_env = DummyVecEnv([make_env(maze) for maze in mazes])
eval_env = DummyVecEnv([make_env(maze) for maze in mazes])

# -- PPO with an evaluation callback ----------------------------------------------

n_steps = 64 if args.tiny else 512  # steps per environment per rollout (4 environments)
model = PPO("MlpPolicy", train_env, n_steps=n_steps, batch_size=64, seed=args.seed, verbose=0)

with tempfile.TemporaryDirectory() as folder:
    # every eval_freq steps of each environment: one deterministic episode per rotation;
    # the best model so far is saved as best_model.zip in folder
    callback = EvalCallback(
        eval_env,
        n_eval_episodes=len(mazes),
        eval_freq=n_steps,
        best_model_save_path=folder,
        log_path=folder,  # evaluations.npz, and callback.evaluations_results
        deterministic=True,
        verbose=0,
    )
    print(f"PPO on {args.maze} (4 rotations), {steps:,} env steps")
    started = time.perf_counter()
    model.learn(total_timesteps=steps, callback=callback)
    print(f"trained {model.num_timesteps:,} env steps in {time.perf_counter() - started:.1f} s")
    print(
        f"EvalCallback: {len(callback.evaluations_results)} evaluations,"
        f" best mean return {callback.best_mean_reward:.1f},"
        f" last {callback.last_mean_reward:.1f}"
    )
    best = PPO.load(f"{folder}/best_model.zip", device="cpu")

# -- the project's evaluation protocol ---------------------------------------------

# SB3Agent turns a model into a policy: observations (n, 8) -> deterministic actions (n,)
for name, trained in (("final model", model), ("best model", best)):
    report = evaluate(SB3Agent(trained, "DD"), "DD", [args.maze], rotations=4, inputs=False)
    print(
        f"{name} on {args.maze}, 4 rotations: success rate {report.success_rate:.2f},"
        f" mean R̄ {report.normalized_reward:+.3f}"
    )
suite = evaluate(SB3Agent(best, "DD"), "DD")  # the standard suite: 18 mazes x 4 rotations
print(
    f"best model on the standard suite: success rate {suite.success_rate:.2f},"
    f" mean R̄ {suite.normalized_reward:+.3f}, input recognition {suite.input_recognition:.2f}"
)
