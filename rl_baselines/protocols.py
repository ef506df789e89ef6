"""Named protocols of ``amaze-train``: sets of options that reproduce a published setting.

``--protocol paper-code`` is the AMaze paper's RL protocol as its training
scripts ran it (reference repository, commit c4feded: ``from_scratch.py``,
``interpolation.py``, ``edhucat.py``), where that differs from the paper's
text. Each difference is an option of its own; the protocol only fills the
options a config leaves unset (given ones win), and ``config.json`` records
every value, so a run says what it ran:

==================  ==========================================================
regime              options
==================  ==========================================================
every one           ``hyperparameters.learning_rate`` 1e-3 (the text says SB3's
                    defaults, 7e-4 for A2C and 3e-4 for PPO)
``direct``          ``agent_rule`` ``best-eval-reward`` (``EvalCallback``'s
                    best model, the only model the script saved),
                    ``eval_every`` ``budget_steps // 100`` (its 100 evaluations)
``interpolation``   ``stage_eval_target`` the paper's training maze and
                    ``target`` its evaluation maze (the script trained on the
                    series its interpolator wrote as evaluation, and evaluated
                    on the other), ``stage_evaluations`` 100, ``agent_rule``
                    ``best-eval-reward`` (each stage's best model),
                    ``final_training`` off
``edhucat``         ``final_training`` off (each stage's final model was saved)
==================  ==========================================================

What the scripts did that this protocol does not reproduce is listed in
``docs/trainers/rl.md`` ("Reproducing Table 3").
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from typing import Any

from amaze.evaluation.suite import PAPER_EVALUATION_MAZE, PAPER_TRAINING_MAZE

__all__ = [
    "PAPER_CODE_EVALUATIONS",
    "PAPER_CODE_LEARNING_RATE",
    "PROTOCOLS",
    "PROTOCOL_REGIMES",
    "protocol_values",
    "with_learning_rate",
]

#: The named protocols.
PROTOCOLS = ("paper-code",)
#: The regimes the protocols describe (the paper's three).
PROTOCOL_REGIMES = ("direct", "interpolation", "edhucat")
#: The learning rate of every A2C and PPO model of the paper's scripts.
PAPER_CODE_LEARNING_RATE = 1e-3
#: Evaluations per run (direct) or per stage (interpolation) of the paper's scripts (``--evals``).
PAPER_CODE_EVALUATIONS = 100


def protocol_values(
    protocol: str, regime: str, budget_steps: int | None, given: Collection[str]
) -> dict[str, Any]:
    """The options ``protocol`` sets in ``regime``, leaving out those in ``given``.

    ``hyperparameters`` is returned whole when the protocol adds to it: the
    caller replaces the config's with it. Raises ``ValueError`` naming what
    the protocol cannot describe (an unknown name, another regime, no steps
    budget where evaluations are spaced by it).
    """
    if protocol not in PROTOCOLS:
        raise ValueError(f"unknown protocol {protocol!r} (choose from {', '.join(PROTOCOLS)})")
    values: dict[str, Any] = {}
    if regime == "direct":
        if budget_steps is None:
            raise ValueError(
                "protocol 'paper-code' spaces its 100 evaluations by budget_steps: give one"
            )
        values = {
            "agent_rule": "best-eval-reward",
            "eval_every": max(1, budget_steps // PAPER_CODE_EVALUATIONS),
        }
    elif regime == "interpolation":
        values = {
            "target": PAPER_EVALUATION_MAZE,
            "stage_eval_target": PAPER_TRAINING_MAZE,
            "stage_evaluations": PAPER_CODE_EVALUATIONS,
            "agent_rule": "best-eval-reward",
            "final_training": False,
        }
    elif regime == "edhucat":
        values = {"final_training": False}
    else:
        raise ValueError(
            f"protocol 'paper-code' describes the direct, interpolation and edhucat regimes,"
            f" not {regime!r}"
        )
    return {name: value for name, value in values.items() if name not in given}


def with_learning_rate(hyperparameters: Mapping[str, Any]) -> dict[str, Any]:
    """``hyperparameters`` with the scripts' learning rate, unless they set one."""
    return {"learning_rate": PAPER_CODE_LEARNING_RATE, **hyperparameters}
