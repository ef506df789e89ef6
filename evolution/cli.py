"""The ``amaze-evolve`` command: evolve maze-navigating agents into run folders.

::

    amaze-evolve --algo cmaes --robot DD --budget-steps 3000000 --seed 0 --out runs/cma
    amaze-evolve --algo neat --mazes M4_10x10_C1,M5_10x10_U --budget-seconds 600 --out runs/neat
    amaze-evolve --resume runs/cma
    amaze-evolve --algo cmaes --seed 0 --replicates 5 --out runs/cma   # runs/cma/seed-0 ... seed-4
    amaze-evolve --regime edhucat --curator random --stages 3 --out runs/edh   # a curriculum
    amaze-evolve --replay runs/edh --out runs/edh-again   # the same curriculum decisions again
    amaze-evolve --algo cmaes --backend ray --actors 16 --out runs/cma   # populations on Ray

The options are the fields of :class:`~evolution.run.EvolveConfig` (``--help``
lists them) plus the run options of every training command
(:class:`amaze.runs.command.TrainingCommand`). ``--config FILE.json`` holds a
whole config or only the algorithm's options; command-line options win over
it. Bad input prints one line ``error: ...`` and exits with status 2.

``--backend ray [--address ADDR] [--actors N]`` plays each population on N
Ray actors (:mod:`evolution.backends`; default: one per CPU of the cluster)
with results identical to the local backend's. ``--actors`` counts
evaluation actors inside one run; ``--workers`` counts replicates.
"""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Iterator

from amaze.runs.command import TrainingCommand
from evolution.backends import RayBackend, make_backend, use_backend
from evolution.run import EvolutionRun


def _add_arguments(group: argparse._ArgumentGroup) -> None:
    group.add_argument(
        "--actors",
        type=int,
        metavar="N",
        help="Ray actors that play each population (with --backend ray;"
        " default: one per CPU of the cluster)",
    )


@contextlib.contextmanager
def _evaluation_backend(args: argparse.Namespace) -> Iterator[object]:
    """The run's evaluation backend, from ``--backend``, ``--address`` and ``--actors``."""
    backend = make_backend(args.backend, actors=args.actors, address=args.address)
    try:
        with use_backend(backend):
            yield backend
    finally:
        if isinstance(backend, RayBackend):
            backend.close()


__all__ = ["COMMAND", "entry_point", "main"]

COMMAND = TrainingCommand(
    prog="amaze-evolve",
    description="Evolve agents (CMA-ES, NEAT-like) in mazes.",
    module="evolution.cli",
    run_class=EvolutionRun,
    add_arguments=_add_arguments,
    run_context=_evaluation_backend,
)
main = COMMAND.main
entry_point = COMMAND.entry_point

if __name__ == "__main__":
    entry_point()
