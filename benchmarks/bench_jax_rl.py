"""End-to-end training speed of the JAX A2C and PPO beside SB3's, in the paper's setting.

The paper's setting: robot ``DD``, 4 environments on the training maze's 4
rotations, SB3's default hyperparameters (``MlpPolicy``). Measured in one run,
on one CPU core:

* JAX PPO and A2C (:class:`rl_baselines.jax.JaxTrainer`): env steps per second
  of ``learn`` (rollouts on the JAX environment and updates, compiled
  together), after a first call that compiles (its seconds printed apart);
  median of ``--repeats``;
* SB3 PPO and A2C (torch, 1 thread) on :class:`rl_baselines.vec_env.SB3VecEnv`
  (the numba engine), ``learn(--sb3-steps)``, median of ``--repeats``;
* with ``--full`` (DD only): the wall time of a whole 3 M-step JAX PPO run from
  a fresh trainer, compilation included, and its final success rate.

``--robot H15`` (or another hybrid robot) measures the CNN policies instead
(:class:`rl_baselines.networks.SmallCNN` and its JAX twin), with smaller
``--ppo-steps``/``--a2c-steps``/``--sb3-steps`` to keep it short (the CNN
costs far more per step than the MLP).

``--robot CC7`` (or another continuous robot) measures continuous actions: SB3
with its small CNN and diagonal Gaussian on :class:`~rl_baselines.vec_env.SB3VecEnv`,
the JAX learners with a Gaussian over a ``network`` (JSON, ``--network``; for
continuous robots the ``fast`` preset's, ``{"hidden": [16], "symmetry":
"rotations"}``, by default: the JAX learners have no SB3-kind Gaussian policy).
``--network`` also puts a network in the JAX learners of a discrete robot.

One core: the process pins itself to one CPU (``os.sched_setaffinity``, as
``taskset -c <cpu>``; ``--cpu``) before importing JAX, and sets
``XLA_FLAGS=--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1``
(XLA's CPU runtime then runs single-threaded) and ``torch.set_num_threads(1)``.

Usage: ``python benchmarks/bench_jax_rl.py [--robot DD] [--network JSON] [--repeats 3] [--full]
[--json]``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from typing import Any

ONE_CORE_XLA = "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1"


def _one_core(cpu: int) -> None:
    """Pin the process to ``cpu`` and make XLA and torch single-threaded (before imports)."""
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {cpu})
    os.environ["XLA_FLAGS"] = f"{os.environ.get('XLA_FLAGS', '')} {ONE_CORE_XLA}".strip()
    os.environ.setdefault("OMP_NUM_THREADS", "1")


def learn_rate(trainer: Any, steps: int, repeats: int) -> tuple[float, float]:
    """``(env steps/s of trainer.learn(steps), median of repeats; seconds of the first call)``.

    The first call (at most one compiled block) compiles; its seconds are apart.
    """
    import jax

    start = time.perf_counter()
    trainer.learn(min(steps, trainer.chunk * trainer.hyperparameters.rollout_size))
    jax.block_until_ready(trainer.state)
    first_call = time.perf_counter() - start
    rates = []
    for _ in range(repeats):
        before = trainer.num_timesteps
        start = time.perf_counter()
        trainer.learn(steps)
        jax.block_until_ready(trainer.state)
        rates.append((trainer.num_timesteps - before) / (time.perf_counter() - start))
    return statistics.median(rates), first_call


def jax_rates(
    algo: str, steps: int, repeats: int, robot: str = "DD", network: dict[str, Any] | None = None
) -> dict[str, Any]:
    """JAX ``algo``'s env steps/s of ``learn(steps)``, after a compiling first call."""

    from amaze.evaluation.suite import PAPER_TRAINING_MAZE
    from amaze.maze import rotations
    from rl_baselines.jax import JaxTrainer

    trainer = JaxTrainer(
        algo, robot, rotations(PAPER_TRAINING_MAZE), {}, seed=0, n_envs=4, network=network
    )
    rate, compile_s = learn_rate(trainer, steps, repeats)
    return {
        "algo": f"jax-{algo}",
        "steps_per_s": rate,
        "first_call_s": compile_s,
    }


def sb3_rates(algo: str, steps: int, repeats: int, robot: str = "DD") -> dict[str, Any]:
    """SB3 ``algo``'s env steps/s of ``learn(steps)`` (SB3 defaults, the run's policy)."""
    import torch

    from amaze.evaluation.suite import PAPER_TRAINING_MAZE
    from amaze.maze import rotations
    from rl_baselines.learner import new_sb3_model
    from rl_baselines.vec_env import SB3VecEnv

    torch.set_num_threads(1)
    rates = []
    for repeat in range(repeats):
        env = SB3VecEnv(rotations(PAPER_TRAINING_MAZE), robot, 4, seed=repeat)
        model = new_sb3_model(algo, robot, env, repeat, {}, None)
        start = time.perf_counter()
        model.learn(steps)
        rates.append(model.num_timesteps / (time.perf_counter() - start))
    return {"algo": f"sb3-{algo}", "steps_per_s": statistics.median(rates)}


def full_ppo_run(total: int) -> dict[str, Any]:
    """Wall time of a fresh JAX PPO run of ``total`` env steps, compilation included."""
    import jax
    import numpy as np

    from amaze.evaluation.suite import PAPER_TRAINING_MAZE
    from amaze.maze import rotations
    from rl_baselines.jax import JaxTrainer

    start = time.perf_counter()
    trainer = JaxTrainer("ppo", "DD", rotations(PAPER_TRAINING_MAZE), {}, seed=0)
    stats = trainer.learn(total)
    jax.block_until_ready(trainer.state)
    seconds = time.perf_counter() - start
    last = slice(-10, None)
    episodes = int(np.sum(stats.episodes[last]))
    return {
        "steps": trainer.num_timesteps,
        "seconds": seconds,
        "last_10_rollouts_success": int(np.sum(stats.successes[last])) / max(episodes, 1),
        "last_10_rollouts_episodes": episodes,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--robot", default="DD", help="DD, a hybrid robot (H15) or a continuous one (CC7)"
    )
    parser.add_argument(
        "--network", type=json.loads, metavar="JSON",
        help="the JAX learners' network spec (default: SB3's policy; the fast preset's for"
        " continuous robots)",
    )  # fmt: skip
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--ppo-steps", type=int, default=8 * 8192, help="JAX PPO steps/repeat")
    parser.add_argument("--a2c-steps", type=int, default=200_000, help="JAX A2C steps/repeat")
    parser.add_argument("--sb3-steps", type=int, default=10_000, help="SB3 steps per repeat")
    parser.add_argument("--full", action="store_true", help="also time a 3M-step JAX PPO run")
    parser.add_argument("--full-steps", type=int, default=3_000_000)
    parser.add_argument("--cpu", type=int, default=0, help="the core to run on")
    parser.add_argument("--json", action="store_true", help="print JSON instead of tables")
    args = parser.parse_args()
    if args.full and args.robot != "DD":
        parser.error(f"--full times the paper's 3 M-step DD run, not robot {args.robot}")
    from amaze.agents import as_robot
    from rl_baselines.presets import FAST_NETWORK

    try:
        continuous = not as_robot(args.robot).discrete_outputs
    except ValueError as error:
        parser.error(f"--robot {args.robot}: {error}")
    network = args.network if args.network is not None or not continuous else FAST_NETWORK
    if network is not None and not isinstance(network, dict):
        parser.error(f"--network {network!r}: a JSON object, e.g. '{{\"hidden\": [16]}}'")
    if network is not None:
        from rl_baselines import RLConfigError
        from rl_baselines.jax.spec import network_spec

        try:
            network_spec(args.robot, network)
        except RLConfigError as error:
            parser.error(f"--network: {error}")
    _one_core(args.cpu)
    rows = [
        jax_rates("ppo", args.ppo_steps, args.repeats, args.robot, network),
        jax_rates("a2c", args.a2c_steps, args.repeats, args.robot, network),
        sb3_rates("ppo", args.sb3_steps, args.repeats, args.robot),
        sb3_rates("a2c", args.sb3_steps, args.repeats, args.robot),
    ]
    full = full_ppo_run(args.full_steps) if args.full else None
    if args.json:
        print(json.dumps({"training": rows, "full_ppo_run": full}, indent=2))
        return
    jax_policy = "SB3's policy" if network is None else f"network {json.dumps(network)}"
    print(f"{args.robot}, 4 envs, training maze rotations, SB3 defaults, 1 core (cpu {args.cpu}), "
          f"median of {args.repeats}; JAX learners: {jax_policy}")  # fmt: skip
    print(f"{'learner':>8} {'env steps/s':>12} {'first call s':>13}")
    for r in rows:
        first = f"{r['first_call_s']:>13.1f}" if "first_call_s" in r else f"{'':>13}"
        print(f"{r['algo']:>8} {r['steps_per_s']:>12,.0f} {first}")
    if full is not None:
        print(f"\nJAX PPO, {full['steps']:,} steps from scratch (compilation included): "
              f"{full['seconds']:.1f} s; success in the last 10 rollouts "
              f"{full['last_10_rollouts_success']:.0%} of {full['last_10_rollouts_episodes']} "
              "episodes")  # fmt: skip


if __name__ == "__main__":
    main()
