"""The paper's Table 3, as data, so a report can set a study's numbers beside it.

K. Godin-Dubois, K. Miras and A. V. Kononova, "AMaze: an intuitive benchmark
generator for fast prototyping of generalizable agents", Frontiers (2024),
Table 3 ("Aggregated maximum and median performance by trainer and
algorithm"). Each agent was trained with SB3's A2C or PPO (default
hyperparameters, 3 M env steps) and scored on the 18 evaluation mazes x 4
rotations (R̄ and success) and by input recognition. The paper's EDHuCAT
curator was a person; a study's ``edhucat-*`` trainers are scripted
strategies standing in for one (:mod:`amaze.curriculum.strategies`).
"""

from __future__ import annotations

__all__ = ["PAPER_CITATION", "PAPER_TABLE3", "paper_trainer"]

PAPER_CITATION = (
    "Godin-Dubois, Miras and Kononova (2024), AMaze: an intuitive benchmark generator"
    " for fast prototyping of generalizable agents, Table 3"
)

#: ``PAPER_TABLE3[statistic][metric][(trainer, algorithm)]``, as printed in the paper.
PAPER_TABLE3: dict[str, dict[str, dict[tuple[str, str], float]]] = {
    "max": {
        "normalized_reward": {
            ("direct", "a2c"): -2.58,
            ("direct", "ppo"): -0.873,
            ("interpolation", "a2c"): -2.51,
            ("interpolation", "ppo"): -1.2,
            ("edhucat", "a2c"): -0.498,
            ("edhucat", "ppo"): -0.498,
        },
        "success_rate": {
            ("direct", "a2c"): 0.347,
            ("direct", "ppo"): 0.778,
            ("interpolation", "a2c"): 0.403,
            ("interpolation", "ppo"): 0.708,
            ("edhucat", "a2c"): 0.792,
            ("edhucat", "ppo"): 0.806,
        },
        "input_recognition": {
            ("direct", "a2c"): 0.753,
            ("direct", "ppo"): 0.777,
            ("interpolation", "a2c"): 0.74,
            ("interpolation", "ppo"): 0.785,
            ("edhucat", "a2c"): 0.75,
            ("edhucat", "ppo"): 0.781,
        },
    },
    "median": {
        "normalized_reward": {
            ("direct", "a2c"): -2.8,
            ("direct", "ppo"): -3.39,
            ("interpolation", "a2c"): -3.02,
            ("interpolation", "ppo"): -1.57,
            ("edhucat", "a2c"): -2.87,
            ("edhucat", "ppo"): -1.87,
        },
        "success_rate": {
            ("direct", "a2c"): 0.34,
            ("direct", "ppo"): 0.326,
            ("interpolation", "a2c"): 0.257,
            ("interpolation", "ppo"): 0.618,
            ("edhucat", "a2c"): 0.514,
            ("edhucat", "ppo"): 0.667,
        },
        "input_recognition": {
            ("direct", "a2c"): 0.743,
            ("direct", "ppo"): 0.715,
            ("interpolation", "a2c"): 0.729,
            ("interpolation", "ppo"): 0.755,
            ("edhucat", "a2c"): 0.717,
            ("edhucat", "ppo"): 0.747,
        },
    },
}


def paper_trainer(trainer: str) -> str | None:
    """The paper's trainer a study's trainer corresponds to (``None``: the paper has none)."""
    if trainer in ("direct", "interpolation"):
        return trainer
    if trainer.startswith("edhucat"):
        return "edhucat"
    return None
