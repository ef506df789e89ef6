"""Training speed of JAX PPO with the shared network spec, beside SB3's defaults, in one run.

End to end (rollouts on the JAX environment and updates, compiled together:
``JaxTrainer.learn``), after a first call that compiles (its seconds printed
apart); env steps per second, median of ``--repeats``. Four settings on the
paper's training maze (its 4 rotations, one environment each at least):

* ``sb3-defaults``: SB3's PPO defaults and ``MlpPolicy`` (64-64, Tanh), 4
  environments: the paper's baseline;
* ``sb3-defaults, network``: the same hyperparameters with the network spec
  (``--network``, default 16 hidden units and the rotation symmetry);
* ``throughput``: many environments, short rollouts, large minibatches, few
  epochs (``--envs``, ``--n-steps``, ``--batch-size``, ``--epochs``: PureJaxRL's
  and CleanRL's JAX PPO kind of setting), SB3's MLP;
* ``throughput, network``: both.

Usage: ``python benchmarks/bench_rl_network.py [--robot DD] [--repeats 3] [--json]``;
``--robot H15`` reads the pooled retina, ``--robot H15 --filters 4`` convolves it.
XLA uses every core it is given (``--threads 1`` pins one core); say how loaded
the machine was beside the figures.
"""

from __future__ import annotations

import argparse
import json
import os
from typing import Any

# run as a script: its folder is on the path
from bench_jax_rl import ONE_CORE_XLA, learn_rate


def rate(
    robot: str,
    hyperparameters: dict[str, Any],
    n_envs: int,
    network: dict[str, Any] | None,
    steps: int,
    repeats: int,
) -> dict[str, Any]:
    """Env steps/s of ``learn(steps)`` (median of ``repeats``) after a compiling first call."""
    from amaze.evaluation.suite import PAPER_TRAINING_MAZE
    from amaze.maze import rotations
    from rl_baselines.jax import JaxTrainer

    mazes = rotations(PAPER_TRAINING_MAZE)
    trainer = JaxTrainer(
        "ppo", robot, mazes, hyperparameters, seed=0, n_envs=n_envs, network=network
    )
    # at least one whole compiled block a repeat
    steps = max(steps, trainer.chunk * trainer.hyperparameters.rollout_size)
    steps_per_s, first_call = learn_rate(trainer, steps, repeats)
    return {"steps_per_s": steps_per_s, "first_call_s": first_call}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="DD", help="DD, or a hybrid robot such as H15")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--steps", type=int, default=1 << 19, help="env steps per repeat")
    parser.add_argument("--hidden", type=int, nargs="*", default=[16])
    parser.add_argument("--symmetry", default="rotations", choices=("none", "rotations"))
    parser.add_argument(
        "--filters", type=int, default=0, help="image robots: 3x3 filters instead of the pool"
    )
    parser.add_argument("--envs", type=int, default=64)
    parser.add_argument("--n-steps", type=int, default=64)
    parser.add_argument("--batch-size", type=int, default=1024)
    parser.add_argument("--epochs", type=int, default=4)
    parser.add_argument("--threads", type=int, choices=(0, 1), default=0, help="1: one core")
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    parser.add_argument(
        "--only-throughput",
        action="store_true",
        help="skip the two SB3-defaults settings (an image robot's CNN at 4 environments takes"
        " minutes a repeat)",
    )
    args = parser.parse_args()
    if args.threads == 1:
        if hasattr(os, "sched_setaffinity"):
            os.sched_setaffinity(0, {0})
        os.environ["XLA_FLAGS"] = f"{os.environ.get('XLA_FLAGS', '')} {ONE_CORE_XLA}".strip()
    network = {"hidden": args.hidden, "symmetry": args.symmetry}
    if args.filters:
        network["filters"] = args.filters
    throughput = {
        "n_steps": args.n_steps,
        "batch_size": args.batch_size,
        "n_epochs": args.epochs,
    }
    settings = [
        ("sb3-defaults", {}, 4, None),
        ("sb3-defaults, network", {}, 4, network),
        ("throughput", throughput, args.envs, None),
        ("throughput, network", throughput, args.envs, network),
    ]
    if args.only_throughput:
        settings = settings[2:]
    rows = []
    for name, hyperparameters, n_envs, net in settings:
        # SB3's defaults roll out 2,048 x 4 steps: a quarter of the steps keeps them short
        steps = args.steps // 4 if n_envs == 4 else args.steps
        figures = rate(args.robot, hyperparameters, n_envs, net, steps, args.repeats)
        rows.append({"setting": name, "n_envs": n_envs, **figures})
    if args.json:
        print(json.dumps({"robot": args.robot, "network": network, "rows": rows}, indent=2))
        return
    print(f"robot {args.robot}, network {network}, throughput {throughput}, {args.envs} envs")
    print(f"{'setting':26} {'envs':>5} {'env steps/s':>12} {'first call s':>13}")
    for row in rows:
        print(
            f"{row['setting']:26} {row['n_envs']:>5} {row['steps_per_s']:>12,.0f}"
            f" {row['first_call_s']:>13.1f}"
        )


if __name__ == "__main__":
    main()
