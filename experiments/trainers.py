"""Which trainer runs an algorithm, and what a study's trainer names mean.

A study crosses *trainers* (how the mazes an agent meets are chosen: a
regime, and for EDHuCAT the curator standing in for the paper's human) with
*algorithms* (how the agent learns). The algorithm decides the package that
runs it: ``a2c`` and ``ppo`` are :mod:`rl_baselines` (stable-baselines3),
``cmaes`` and ``neat`` are :mod:`evolution`. Both are imported only when a
run needs them (torch is slow to import).

A study may also name *variants* of an algorithm (``[variants]``, read by
:func:`parse_variants`): ``ppo-fast = "ppo"`` is PPO at options of its own,
a treatment apart from ``ppo``, run and checked as its base.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from amaze.errors import UsageError
from amaze.evaluation.suite import PAPER_TRAINING_MAZE
from amaze.runs.lifecycle import Run
from experiments.comparisons import NAME_RULE, is_name

__all__ = [
    "ALGORITHMS",
    "DOMAIN_RANDOMISATION_MAZES",
    "RL_ALGORITHMS",
    "TRAINERS",
    "parse_variants",
    "run_class",
    "trainer_fields",
]

#: The algorithms of each package.
RL_ALGORITHMS = ("a2c", "ppo")
EVOLUTION_ALGORITHMS = ("cmaes", "neat")
ALGORITHMS = (*RL_ALGORITHMS, *EVOLUTION_ALGORITHMS)

#: Domain randomisation's fixed mazes: 8 of the paper's training maze's family, sides 8 to 20,
#: seeds apart from the evaluation suite's and the validation and unseen mazes'.
DOMAIN_RANDOMISATION_MAZES = [
    f"M{31 + i}_{side}x{side}_C1_l.25_L.25_t.5_T.5"
    for i, side in enumerate((8, 10, 11, 13, 15, 17, 18, 20))
]
#: A study's trainer names, with the config fields each sets.
TRAINERS: dict[str, dict[str, Any]] = {
    "direct": {"regime": "direct"},
    "interpolation": {"regime": "interpolation"},
    "edhucat-careful": {"regime": "edhucat", "curator": "careful"},
    "edhucat-moderate": {"regime": "edhucat", "curator": "moderate"},
    "edhucat-risky": {"regime": "edhucat", "curator": "risky"},
    "edhucat-random": {"regime": "edhucat", "curator": "random"},
    # the automated curator in the same loop as the strategies (the edens regime is open-ended)
    "edhucat-edens": {"regime": "edhucat", "curator": "edens"},
    # careful advised by EDEnS: it takes each proposal with probability p (curator_options)
    "edhucat-follow-edens": {"regime": "edhucat", "curator": "follow", "advisor": "edens"},
    "edens": {"regime": "edens"},
    "coevolution": {"regime": "coevolution"},
    # EDEnS choosing how the co-evolved maze population evolves (RL: the jax framework only)
    "edens-populations": {"regime": "edens-populations"},
    # the direct regime on fixed family mazes
    "domain-randomisation": {
        "regime": "direct",
        "mazes": DOMAIN_RANDOMISATION_MAZES,
        "evaluation_maze": PAPER_TRAINING_MAZE,  # the curricula's evaluation set
    },
}


def run_class(algo: Any) -> type[Run]:
    """The run class of the package that runs ``algo``."""
    if algo in RL_ALGORITHMS:
        from rl_baselines.train import SB3Run

        return SB3Run
    if algo in EVOLUTION_ALGORITHMS:
        from evolution.run import EvolutionRun

        return EvolutionRun
    raise UsageError(f"algorithm {algo!r} (choose from {', '.join(ALGORITHMS)})")


def trainer_fields(trainer: Any) -> dict[str, Any]:
    """The config fields of the trainer called ``trainer``."""
    if trainer not in TRAINERS:
        raise UsageError(f"trainer {trainer!r} (choose from {', '.join(TRAINERS)})")
    return dict(TRAINERS[trainer])


def parse_variants(value: Any, bad: Callable[[str], Exception]) -> dict[str, str]:
    """A study's ``[variants]``: each variant's name and its base, one of :data:`ALGORITHMS`.

    ``bad`` makes the error of a bad value. A name is refused where it could be read as
    another: an algorithm's, a trainer's, ``all`` (``[options.all]``), or one of these or
    another variant's in other letter cases (run folders on a case-blind filesystem, the
    report's ``PPO``); a base that is a variant is refused too (one level, no chains).
    """
    if not isinstance(value, dict):
        raise bad(f"variants {value!r:.80} is not a table of names = algorithms")
    taken = {name.lower() for name in (*ALGORITHMS, *TRAINERS, "all")}
    for name, base in value.items():
        if not is_name(name):
            raise bad(f"variant name {name!r:.80} is not {NAME_RULE}")
        if name.lower() in taken:
            raise bad(f"variant name {name!r} is already an algorithm's, a trainer's or 'all'")
        if not isinstance(base, str) or base not in ALGORITHMS:
            raise bad(
                f"variant {name!r} = {base!r:.80}: its base is not one of"
                f" {', '.join(ALGORITHMS)} (a variant is of an algorithm, not of a variant)"
            )
        taken.add(name.lower())
    return dict(value)
