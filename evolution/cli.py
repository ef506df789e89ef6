"""The ``amaze-evolve`` command: evolve maze-navigating agents into run folders.

::

    amaze-evolve --algo cmaes --robot DD --budget-steps 3000000 --seed 0 --out runs/cma
    amaze-evolve --algo neat --mazes M4_10x10_C1,M5_10x10_U --budget-seconds 600 --out runs/neat
    amaze-evolve --resume runs/cma
    amaze-evolve --algo cmaes --seed 0 --replicates 5 --out runs/cma   # runs/cma/seed-0 ... seed-4
    amaze-evolve --regime edhucat --curator random --stages 3 --out runs/edh   # a curriculum
    amaze-evolve --replay runs/edh --out runs/edh-again   # the same curriculum decisions again

The options are the fields of :class:`~evolution.run.EvolveConfig` (``--help``
lists them) plus the run options of every training command
(:class:`amaze.runs.command.TrainingCommand`). ``--config FILE.json`` holds a
whole config or only the algorithm's options; command-line options win over
it. Bad input prints one line ``error: ...`` and exits with status 2.
"""

from __future__ import annotations

from amaze.runs.command import TrainingCommand
from evolution.run import EvolutionRun

__all__ = ["COMMAND", "entry_point", "main"]

COMMAND = TrainingCommand(
    prog="amaze-evolve",
    description="Evolve agents (CMA-ES, NEAT-like) in mazes.",
    module="evolution.cli",
    run_class=EvolutionRun,
)
main = COMMAND.main
entry_point = COMMAND.entry_point

if __name__ == "__main__":
    entry_point()
