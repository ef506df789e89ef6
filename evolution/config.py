"""The evolution run config (``config.json``, the ``amaze-evolve`` options).

:class:`EvolveConfig` defines a run of either loop: the direct regime
(:class:`evolution.run.EvolutionRun`, generations on fixed mazes) and the
curriculum regimes (:class:`evolution.curriculum.EvolutionCurriculumRun`).
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
from dataclasses import dataclass
from typing import Any

from amaze.agents.robot import as_robot
from amaze.curriculum.regimes import COEVOLUTION_REGIMES, REGIMES
from amaze.runs.config import option
from amaze.runs.regime import RegimeConfig
from amaze.validation import check_integer, check_number
from evolution import EvolutionConfigError
from evolution.algorithms import ALGORITHMS, algorithm_class
from evolution.neat.config import NeatConfig
from evolution.population import FITNESS, OLD_FITNESS
from evolution.slip import check_slip

__all__ = [
    "COEVOLUTION_CMAES",
    "COEVOLUTION_SYMMETRY",
    "EvolveConfig",
    "coevolution_cmaes",
    "coevolution_neat",
]


#: CMA-ES options of the coevolution regime that a config leaves out: one 16-unit
#: hidden layer and 16 IPOP restarts (a linear policy learns less there in the
#: same time; see docs/regimes/coevolution.md), and, for robots with discrete
#: actions, one network shared by the four directions (:data:`COEVOLUTION_SYMMETRY`).
COEVOLUTION_CMAES: dict[str, Any] = {"network": {"hidden": [16]}, "restarts": 16}
#: The network symmetry of the coevolution regime for robots with discrete actions
#: (DD, H): at 20 s, DD, 5 seeds, it lifted the median suite success from 0.49 to
#: 1.0; at 120 s, H15, from 0 to 0.94 (docs/regimes/coevolution.md, "Measured").
COEVOLUTION_SYMMETRY = "rotations"
#: NEAT's options that a config.json records when written before NEAT's ``symmetry``
#: existed: such a config keeps its meaning (no symmetry).
_NEAT_RECORDED = frozenset(f.name for f in dataclasses.fields(NeatConfig)) - {"symmetry"}


def coevolution_cmaes(robot: str) -> dict[str, Any]:
    """The coevolution regime's CMA-ES options for ``robot`` (a fresh copy).

    :data:`COEVOLUTION_CMAES`, with :data:`COEVOLUTION_SYMMETRY` for robots
    with discrete actions.
    """
    options = copy.deepcopy(COEVOLUTION_CMAES)
    if as_robot(robot).discrete_outputs:
        options["network"]["symmetry"] = COEVOLUTION_SYMMETRY
    return options


def coevolution_neat(robot: str) -> dict[str, Any]:
    """The coevolution regime's NEAT options for ``robot``: genomes shared by the directions.

    :data:`COEVOLUTION_SYMMETRY` for robots with discrete actions (at 40 M
    env steps, DD, on the same 3 seeds, it lifted NEAT's median suite success
    from 0.403 to 1.000; docs/regimes/coevolution.md, "Measured"); nothing for
    the others.
    """
    return {"symmetry": COEVOLUTION_SYMMETRY} if as_robot(robot).discrete_outputs else {}


@dataclass
class EvolveConfig(RegimeConfig):
    """Everything that defines an evolution run (stored as ``config.json``).

    In the direct and coevolution regimes, ``budget_steps``, ``budget_seconds``
    and ``max_generations`` may each be ``None`` (no limit), not all three;
    the coevolution regimes (:mod:`evolution.coevolution`,
    :mod:`evolution.edens_populations`) evolve their own mazes toward
    ``target``'s family, with the ``coevolution`` options, and fill the CMA-ES
    options they are not given from :func:`coevolution_cmaes`, NEAT's from
    :func:`coevolution_neat`. In a
    curriculum regime (``interpolation``, ``edhucat``, ``edens``;
    :mod:`evolution.curriculum`) the budget is ``budget_steps`` and/or
    ``budget_seconds``, shared between stages and branches, and the mazes are
    the curriculum's, leading to ``target``: ``max_generations`` and
    ``mazes`` are refused there.
    """

    error = EvolutionConfigError
    options_field = "algorithm"
    supported_regimes = REGIMES  # coevolution included (evolution.coevolution)
    agent_rules = ("best-fitness", "final", "best-eval")

    algo: str = option("cmaes", "search algorithm", choices=tuple(ALGORITHMS))
    fitness: str = option(
        "normalized_reward", "mean of this over the training episodes", choices=FITNESS
    )
    budget_steps: int | None = option(3_000_000, "environment steps of the scored episodes")
    budget_seconds: float | None = option(None, "wall-clock seconds")
    max_generations: int | None = option(
        None, "generations", regimes=("direct", *COEVOLUTION_REGIMES)
    )
    checkpoint_seconds: float = option(
        10.0, "seconds of run time between checkpoints (0: after every generation)"
    )
    slip: float = option(
        0.0,
        "probability that a training step's action is replaced by a random one"
        " (evolution.slip; robots with discrete actions)",
        regimes=COEVOLUTION_REGIMES,
    )
    algorithm: dict[str, Any] = option(
        default_factory=dict,
        help="the algorithm's options (CMAESConfig or NeatConfig fields)",
        command_line=False,
    )

    def validate(self) -> EvolveConfig:
        """Check every field; raise :class:`EvolutionConfigError` naming the bad value."""
        super().validate()
        algorithm_class(self.algo)  # an unknown name is refused, naming the choices
        self.fitness = OLD_FITNESS.get(self.fitness, self.fitness)  # an older config.json
        if self.fitness not in FITNESS:
            raise EvolutionConfigError(
                f"fitness {self.fitness!r} is not one of {', '.join(FITNESS)}"
            )
        for name in ("budget_steps", "max_generations"):
            value = getattr(self, name)
            if value is not None:
                setattr(self, name, check_integer(name, value, minimum=1, error=self.error))
        if self.budget_seconds is not None:
            self.budget_seconds = check_number(
                "budget_seconds",
                self.budget_seconds,
                minimum=0,
                strict_minimum=True,
                error=self.error,
            )
        if self.is_curriculum:
            self._check_curriculum()
        self._coevolution_defaults()
        if (self.budget_steps, self.budget_seconds, self.max_generations) == (None, None, None):
            raise EvolutionConfigError("a run needs a budget: budget_steps or budget_seconds")
        self.checkpoint_seconds = check_number(
            "checkpoint_seconds", self.checkpoint_seconds, minimum=0, error=self.error
        )
        self.slip = check_slip(self.slip)
        if self.slip and not as_robot(self.robot).discrete_outputs:
            raise EvolutionConfigError(
                f"slip {self.slip} needs a robot with discrete actions, not {self.robot}"
            )
        if not isinstance(self.algorithm, dict):
            raise EvolutionConfigError(f"algorithm {self.algorithm!r} is not a JSON object")
        # every option the algorithm uses, defaults filled in: config.json says what ran
        self.algorithm = algorithm_class(self.algo).config_class.from_dict(self.algorithm).to_dict()
        return self

    def _check_curriculum(self) -> None:
        """A curriculum's budget is env steps and/or seconds."""
        if self.budget_steps is None and self.budget_seconds is None:
            raise EvolutionConfigError(
                f"the {self.regime} regime needs budget_steps or budget_seconds"
            )

    def _coevolution_defaults(self) -> None:
        """CMA-ES's and NEAT's options of the coevolution regimes default to the regimes'.

        A config that gives a ``network`` gives all of it (its missing keys take
        :class:`~evolution.cmaes.CMAESConfig`'s defaults, symmetry ``none``),
        and a NEAT config that gives every option but ``symmetry`` keeps
        symmetry ``none``: a ``config.json`` written before symmetries existed
        keeps its meaning.
        """
        if self.regime not in COEVOLUTION_REGIMES or not isinstance(self.algorithm, dict):
            return
        if self.algo == "cmaes":
            self.algorithm = {**coevolution_cmaes(self.robot), **self.algorithm}
        elif self.algo == "neat" and not _NEAT_RECORDED <= set(self.algorithm):
            self.algorithm = {**coevolution_neat(self.robot), **self.algorithm}

    @classmethod
    def add_arguments(cls, parser: argparse.ArgumentParser) -> None:
        """The config's options, and ``--population-size`` (an option of every algorithm)."""
        super().add_arguments(parser)
        parser.add_argument(
            "--population-size",
            type=int,
            metavar="N",
            help="individuals per generation (algorithm option)",
        )

    @classmethod
    def adjust_command_line(cls, data: dict[str, Any], args: argparse.Namespace) -> dict[str, Any]:
        """``--budget-seconds`` alone is a wall-clock budget; ``--population-size`` is an option."""
        data = super().adjust_command_line(data, args)
        if getattr(args, "population_size", None) is not None:
            data["algorithm"] = {
                **data.get("algorithm", {}),
                "population_size": args.population_size,
            }
        return data
