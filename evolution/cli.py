"""The ``amaze-evolve`` command: evolve maze-navigating agents into run folders.

::

    amaze-evolve --algo cmaes --robot DD --budget-steps 3000000 --seed 0 --out runs/cma
    amaze-evolve --algo neat --mazes M4_10x10_C1,M5_10x10_U --budget-seconds 600 --out runs/neat
    amaze-evolve --resume runs/cma
    amaze-evolve --algo cmaes --seed 0 --replicates 5 --out runs/cma   # runs/cma/seed-0 ... seed-4

Mazes (default: the paper's direct-training maze) are played in their 4
rotations. ``--config FILE.json`` holds a whole config (the keys of
:class:`~evolution.run.EvolveConfig`) or only the algorithm's options;
command-line options win over it. Replicates run as parallel worker processes
(:mod:`amaze.runs.replicates`). The progress bar (generation, best and mean
fitness, steps/s, ETA) shows on a terminal. Bad input prints one line
``error: ...`` and exits with status 2.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from typing import Any

from amaze.errors import AmazeError
from amaze.runs.command import CommandParser, read_json_object
from evolution import EvolutionConfigError

__all__ = ["entry_point", "main"]


def _parser() -> argparse.ArgumentParser:
    p = CommandParser(
        prog="amaze-evolve", description="Evolve agents (CMA-ES, NEAT-like) in mazes."
    )
    p.add_argument("--algo", choices=("cmaes", "neat"))
    p.add_argument("--mazes", help="training mazes, comma-separated (each in its 4 rotations)")
    p.add_argument("--robot", help="DD (default), a hybrid (H15) or a continuous (CC15) robot")
    p.add_argument("--fitness", choices=("paper_reward", "success", "pretty_reward"))
    p.add_argument("--budget-steps", type=int, help="environment steps (default 3000000)")
    p.add_argument("--budget-seconds", type=float, help="wall-clock seconds")
    p.add_argument("--max-generations", type=int)
    p.add_argument("--population-size", type=int)
    p.add_argument("--seed", type=int)
    p.add_argument("--out")
    p.add_argument("--config", help="JSON file: a whole config or the algorithm's options")
    p.add_argument("--resume", metavar="DIR", help="continue the run in DIR")
    p.add_argument("--replicates", type=int, default=1, help="seeds S..S+K-1, in OUT/seed-<s>")
    p.add_argument("--workers", type=int, help="replicates run at once (default: one per core)")
    p.add_argument(
        "--progress",
        action=argparse.BooleanOptionalAction,
        help="progress bar (default: on when stderr is a terminal)",
    )
    return p


def _config(args: argparse.Namespace) -> dict[str, Any]:
    from evolution.run import EvolveConfig

    data: dict[str, Any] = {}
    if args.config:
        loaded = read_json_object(args.config, EvolutionConfigError)
        whole = set(loaded) <= set(EvolveConfig.__dataclass_fields__)
        data = loaded if whole else {"algorithm": loaded}
    for name in ("algo", "robot", "fitness", "budget_steps", "seed", "max_generations"):
        value = getattr(args, name)
        if value is not None:
            data[name] = value
    if args.budget_seconds is not None:
        data["budget_seconds"] = args.budget_seconds
        if args.budget_steps is None and "budget_steps" not in data:
            data["budget_steps"] = None  # a wall-clock budget alone
    if args.mazes is not None:
        data["mazes"] = [m.strip() for m in args.mazes.split(",") if m.strip()]
    if args.population_size is not None:
        data["algorithm"] = {**data.get("algorithm", {}), "population_size": args.population_size}
    return data


def _replicates(args: argparse.Namespace, argv: Sequence[str]) -> int:
    """Run seeds S..S+K-1 as parallel worker processes, each in ``OUT/seed-<s>``."""
    from amaze.runs.replicates import replicate_command

    try:
        return replicate_command(
            "evolution.cli", argv, args.seed, args.replicates, args.out, args.workers
        )
    except ValueError as error:
        raise EvolutionConfigError(str(error)) from None


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command; return the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    args = _parser().parse_args(argv)
    progress = sys.stderr.isatty() if args.progress is None else args.progress
    try:
        if args.resume:
            from evolution.run import resume

            result = resume(args.resume, progress_bar=progress)
            out = args.resume
        elif args.replicates != 1:
            return _replicates(args, argv)
        else:
            if not args.out:
                raise EvolutionConfigError("--out is required (or --resume DIR)")
            from evolution.run import evolve

            result = evolve(_config(args), args.out, progress_bar=progress)
            out = args.out
    except (EvolutionConfigError, AmazeError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    s = result.summary
    recognition = s["input_recognition"]
    print(
        f"{result.generations} generations, {result.env_steps} env steps, {result.seconds:.1f} s"
        f" ({s['policy_steps_per_second'] / 1e6:.2f} M policy-steps/s);"
        f" champion fitness {result.fitness:.3f}; standard suite: success"
        f" {s['success_rate']:.3f}, normalized_reward {s['normalized_reward']:.3f},"
        f" input_recognition {'n/a' if recognition is None else f'{recognition:.3f}'}"
    )
    print(f"run folder: {out} (champion.npz, summary.json, progress.csv, fitness.png)")
    return 0


def entry_point() -> None:
    """Console-script entry point."""
    raise SystemExit(main())


if __name__ == "__main__":
    entry_point()
