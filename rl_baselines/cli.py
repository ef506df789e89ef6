"""The ``amaze-train`` command: train SB3 A2C/PPO baselines into run folders.

::

    amaze-train --algo ppo --regime direct --robot DD --budget-steps 100000 --seed 0 --out runs/ppo
    amaze-train --resume runs/ppo
    amaze-train --algo a2c --seed 3 --replicates 5 --out runs/a2c   # runs/a2c/seed-3 ... seed-7

``--config FILE.json`` holds SB3 hyperparameters (``{"n_steps": 128, ...}``), or a
whole config with a ``hyperparameters`` key; command-line options win over it.
Replicates run as parallel worker processes (``--workers``, default one per
core; see :mod:`amaze.runs.replicates`), each writing its output to its folder's
``log.txt``. SB3's progress bar shows on a terminal (``--progress`` /
``--no-progress`` decide otherwise); TensorBoard logs go to the run folder's
``tensorboard/``. Bad input prints one line ``error: ...`` and exits with status 2.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from typing import Any

from amaze.runs.command import CommandParser, read_json_object
from rl_baselines import RLConfigError

__all__ = ["entry_point", "main"]


def _parser() -> argparse.ArgumentParser:
    p = CommandParser(prog="amaze-train", description="Train SB3 A2C/PPO agents on AMaze mazes.")
    p.add_argument("--algo", choices=("a2c", "ppo"))
    p.add_argument("--regime", choices=("direct", "interpolation"))
    p.add_argument("--robot")
    p.add_argument("--budget-steps", type=int)
    p.add_argument("--seed", type=int)
    p.add_argument("--out")
    p.add_argument("--eval-every", type=int)
    p.add_argument("--n-envs", type=int)
    p.add_argument("--config", help="JSON file: hyperparameters or a whole config")
    p.add_argument("--resume", metavar="DIR", help="continue the run in DIR")
    p.add_argument("--replicates", type=int, default=1, help="seeds S..S+K-1, in OUT/seed-<s>")
    p.add_argument("--workers", type=int, help="replicates run at once (default: one per core)")
    p.add_argument(
        "--progress",
        action=argparse.BooleanOptionalAction,
        help="SB3's progress bar (default: on when stderr is a terminal)",
    )
    return p


def _config(args: argparse.Namespace) -> dict[str, Any]:
    data: dict[str, Any] = {}
    if args.config:
        loaded = read_json_object(args.config, RLConfigError)
        data = loaded if "hyperparameters" in loaded else {"hyperparameters": loaded}
    for name in ("algo", "regime", "robot", "budget_steps", "seed", "eval_every", "n_envs"):
        value = getattr(args, name)
        if value is not None:
            data[name] = value
    return data


def _replicates(args: argparse.Namespace, argv: Sequence[str]) -> int:
    """Run seeds S..S+K-1 as parallel worker processes, each in ``OUT/seed-<s>``."""
    from amaze.runs.replicates import replicate_command

    try:
        return replicate_command(
            "rl_baselines.cli", argv, args.seed, args.replicates, args.out, args.workers
        )
    except ValueError as error:
        raise RLConfigError(str(error)) from None


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command; return the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    args = _parser().parse_args(argv)
    try:
        progress = sys.stderr.isatty() if args.progress is None else args.progress
        if args.resume:
            from rl_baselines.train import resume

            result = resume(args.resume, progress_bar=progress)
        elif args.replicates != 1:
            return _replicates(args, argv)
        else:
            if not args.out:
                raise RLConfigError("--out is required (or --resume DIR)")
            from rl_baselines.train import train

            result = train(_config(args), args.out, progress_bar=progress)
    except RLConfigError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    s = result.summary
    print(
        f"env steps {result.env_steps}, {result.seconds:.1f} s, converged {result.converged}:"
        f" success_rate {s['success_rate']:.3f}, normalized_reward"
        f" {s['normalized_reward']:.3f}, input_recognition {s['input_recognition']}"
    )
    return 0


def entry_point() -> None:
    """Console-script entry point."""
    raise SystemExit(main())


if __name__ == "__main__":
    entry_point()
