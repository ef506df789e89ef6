"""The ``amaze-train`` command: train SB3 A2C/PPO baselines into run folders.

::

    amaze-train --algo ppo --regime direct --robot DD --budget-steps 100000 --seed 0 --out runs/ppo
    amaze-train --resume runs/ppo
    amaze-train --algo ppo --budget-seconds 600 --out runs/ppo-10min   # a wall-clock budget
    amaze-train --algo ppo --regime edhucat --curator random --stages 3 --budget-steps 30000 \\
        --branches 2 --out runs/edhucat
    amaze-train --replay runs/edhucat --out runs/edhucat-again   # the same curriculum
    amaze-train --algo a2c --seed 3 --replicates 5 --out runs/a2c   # runs/a2c/seed-3 ... seed-7

The options are the fields of :class:`~rl_baselines.config.TrainConfig`
(``--help`` lists them) plus the run options of every training command
(:class:`amaze.runs.command.TrainingCommand`). ``--config FILE.json`` holds SB3
hyperparameters (``{"n_steps": 128, ...}``) or a whole config; command-line
options win over it. ``--regime interpolation|edhucat`` runs the curriculum loop
(:mod:`rl_baselines.curriculum`), with ``--curator``, ``--stages``, ``--branches``
and ``--target``. A progress bar shows on a terminal; TensorBoard logs go to the
run folder's ``tensorboard/``. Bad input prints one line ``error: ...``
and exits with status 2.
"""

from __future__ import annotations

from amaze.runs.command import TrainingCommand
from rl_baselines.config import TrainConfig

__all__ = ["COMMAND", "entry_point", "main"]

COMMAND = TrainingCommand(
    prog="amaze-train",
    description=(
        "Train A2C/PPO agents on AMaze mazes: stable-baselines3's, or the compiled JAX"
        " learners' (--framework jax). Continuous robots (CC7, CC15...) train with"
        ' --framework jax and a network: --preset fast, or the config\'s "network".'
    ),
    module="rl_baselines.cli",
    # imported once the options and the config are checked: torch and SB3 load then
    run_class="rl_baselines.train:SB3Run",
    config_class=TrainConfig,
    # a JAX run's saved trainers, checked before JAX or torch is imported
    check_resume="rl_baselines.jax.storage:check_saved_trainers",
)
main = COMMAND.main
entry_point = COMMAND.entry_point

if __name__ == "__main__":
    entry_point()
