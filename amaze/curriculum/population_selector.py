"""EDEnS over maze populations: the selector evolves how the maze population evolves.

EDEnS (Godin-Dubois, Cussat-Blanc and Duthen, SSCI 2020) copies the whole
state into ``m`` alternatives, keeps the environment's controller in the first
and mutates it in the others, runs one epoch of each without outside
feedback, and keeps one alternative, drawn at random from the Pareto front of
several criteria; alternatives that went extinct are rejected. In the
``edens-populations`` regime the state is the agents' search state plus the
co-evolved maze population (:class:`~amaze.curriculum.maze_population.MazePopulation`),
and the environment's *controller* is what shapes that population: the
:data:`CONTROLLER_FIELDS` of its
:class:`~amaze.curriculum.maze_population.MazePopulationConfig` (replay,
staleness, temperature, the score, the share and size of mutations, the sides
of new mazes). ``batch`` and ``capacity`` are not mutated: every alternative
plays the same number of mazes per generation, so alternatives cost the same
and compare at equal budgets.

This module holds what is trainer-free: the selector's options
(:class:`SelectorConfig`), the controller's mutation
(:func:`mutate_controller`), the criteria an alternative is judged on
(:data:`CRITERIA`, :class:`Outcome`) and the pick (:func:`choose`). The
loop that plays the alternatives is :mod:`amaze.runs.edens_populations`.

**Criteria** (all maximised; :attr:`SelectorConfig.criteria` picks among them):

* ``validation_success_rate`` and ``validation_fitness``: the success rate
  and the run's fitness measure (R̄ by default) of the alternative's best
  agent on the run's validation mazes, played at the end of its epoch:
  generalisation to the target's family, judged on mazes no alternative
  trains on;
* ``difficulty_reached``: the mean, over the members of its maze population,
  of a member's difficulty times the agents' success rate at its last play:
  how hard the mazes are that its agents do solve (a population of easy
  mazes, or of hard mazes nobody solves, scores low);
* ``diversity``: the mean distance between two members in the metric space
  (:meth:`~amaze.curriculum.maze_population.MazePopulation.diversity`).

*Learning progress* is not a criterion of its own: every alternative starts
from the same parent, so its progress on the validation mazes orders the
alternatives exactly as ``validation_fitness`` does.

An alternative is **extinct** when its agents reached the goal in no episode
of the epoch (batches and validation); extinct alternatives are rejected
unless all are. Every draw comes from :func:`selector_rng`, a stream of the
run's seed, the epoch and a purpose, so a resumed run draws the same.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from amaze.curriculum.edens import pareto_front
from amaze.curriculum.maze_population import (
    CoevolutionError,
    MazePopulation,
    MazePopulationConfig,
    options_from_dict,
)
from amaze.maze.spec import MIN_SIZE, MazeSpec
from amaze.validation import check_integer

__all__ = [
    "CONTROLLER_FIELDS",
    "CRITERIA",
    "Outcome",
    "SelectorConfig",
    "SelectorState",
    "choose",
    "controller_of",
    "criteria_values",
    "mutate_controller",
    "selector_rng",
]

#: The maze population options an alternative's controller may change.
CONTROLLER_FIELDS = (
    "replay_probability", "staleness", "temperature", "score", "mutation_probability",
    "edits", "min_size", "max_size",
)  # fmt: skip
#: What an alternative may be judged on (see the module docstring), all maximised.
CRITERIA = ("validation_success_rate", "validation_fitness", "difficulty_reached", "diversity")
#: The default criteria: generalisation, its fitness and the difficulty reached.
DEFAULT_CRITERIA = ("validation_success_rate", "validation_fitness", "difficulty_reached")
#: Standard deviation of a probability's Gaussian step, and of log(temperature)'s.
PROBABILITY_STEP = 0.15
TEMPERATURE_STEP = 0.5
#: The smallest side a mutated controller gives new mazes (unless its parent's is smaller).
SMALLEST_SIDE = 5
#: Bounds of a mutated ``temperature`` and ``edits``.
TEMPERATURE_RANGE = (0.05, 1.0)
EDITS_RANGE = (1, 8)
#: The stream of the selector's draws, apart from the population's and the algorithm's.
_SELECTOR_STREAM = 0xED5


@dataclass(frozen=True)
class SelectorConfig:
    """The selector's options (the run config's ``selector`` object).

    ``alternatives`` (``m``): the copies of the state an epoch plays, the
    first with the parent's controller; ``epoch``: generations (rounds) each
    alternative plays before the pick; ``mutations``: the most controller
    fields a mutated alternative changes (1 to that many, drawn);
    ``criteria``: the names of :data:`CRITERIA` the Pareto front is built on.
    """

    alternatives: int = 3
    epoch: int = 20
    mutations: int = 2
    criteria: tuple[str, ...] = DEFAULT_CRITERIA

    def __post_init__(self) -> None:
        for name, low, high in (
            ("alternatives", 1, 64),
            ("epoch", 1, 100_000),
            ("mutations", 1, len(CONTROLLER_FIELDS)),
        ):
            value = check_integer(
                f"selector {name}", getattr(self, name), minimum=low, maximum=high,
                error=CoevolutionError,
            )  # fmt: skip
            object.__setattr__(self, name, value)
        criteria = self.criteria
        if isinstance(criteria, str) or not isinstance(criteria, Sequence) or not criteria:
            raise CoevolutionError(f"selector criteria {criteria!r} must be a non-empty list")
        unknown = [c for c in criteria if c not in CRITERIA]
        if unknown or len(set(criteria)) != len(criteria):
            raise CoevolutionError(
                f"selector criteria {list(criteria)!r}: give distinct names among"
                f" {', '.join(CRITERIA)}"
            )
        object.__setattr__(self, "criteria", tuple(criteria))

    @classmethod
    def from_dict(cls, data: Mapping[str, Any] | None) -> SelectorConfig:
        """The options of a JSON object: missing keys take their defaults, unknown ones fail."""
        return options_from_dict(cls, data, "selector")

    def to_dict(self) -> dict[str, Any]:
        return {**dataclasses.asdict(self), "criteria": list(self.criteria)}


def selector_rng(seed: int, epoch: int, purpose: str) -> np.random.Generator:
    """The generator of one of the selector's decisions: the run's seed, the epoch, a purpose."""
    words = [int(b) for b in purpose.encode("utf-8")]
    return np.random.default_rng(np.random.SeedSequence([seed, _SELECTOR_STREAM, epoch, *words]))


def mutate_controller(
    config: MazePopulationConfig, target: str, rng: np.random.Generator, most: int
) -> tuple[MazePopulationConfig, tuple[str, ...]]:
    """``config`` with 1 to ``most`` of its :data:`CONTROLLER_FIELDS` changed, and their names.

    Probabilities take a Gaussian step (clipped to [0, 1]), the temperature a
    log-normal one (within :data:`TEMPERATURE_RANGE`), ``edits`` and the
    sides a step of one (sides within ``[5, the target's larger side]``, or
    from ``config.min_size`` if smaller; the smaller side never above the
    larger), the score flips. A field drawn whose
    value cannot change (a side at its bound stepped outward) is clipped back
    and may leave the controller as it was: the names list what was drawn.
    """
    spec = MazeSpec.from_string(target)
    longest = max(spec.width, spec.height, MIN_SIZE)
    count = int(rng.integers(1, most + 1))
    names = tuple(
        CONTROLLER_FIELDS[int(i)]
        for i in sorted(rng.choice(len(CONTROLLER_FIELDS), size=count, replace=False))
    )
    values = config.to_dict()
    values["max_size"] = config.max_size or max(longest, config.min_size)
    for name in names:
        value = values[name]
        if name == "score":
            values[name] = "regret" if value == "learnability" else "learnability"
        elif name == "temperature":
            step = np.exp(rng.normal(0, TEMPERATURE_STEP))
            values[name] = float(np.clip(value * step, *TEMPERATURE_RANGE))
        elif name == "edits":
            values[name] = int(np.clip(value + rng.choice((-1, 1)), *EDITS_RANGE))
        elif name in ("min_size", "max_size"):
            floor = min(SMALLEST_SIDE, config.min_size)
            values[name] = int(np.clip(value + rng.choice((-1, 1)), floor, longest))
        else:
            values[name] = float(np.clip(value + rng.normal(0, PROBABILITY_STEP), 0.0, 1.0))
    if values["min_size"] > values["max_size"]:
        values["min_size"], values["max_size"] = values["max_size"], values["min_size"]
    return MazePopulationConfig.from_dict(values), names


def controller_of(config: MazePopulationConfig) -> dict[str, Any]:
    """The :data:`CONTROLLER_FIELDS` of ``config``, as JSON (``epochs.jsonl``, ``summary.json``)."""
    values = config.to_dict()
    return {name: values[name] for name in CONTROLLER_FIELDS}


def difficulty_reached(mazes: MazePopulation) -> float:
    """Mean over the members of difficulty times success rate at the last play (0 if none)."""
    members = mazes.member_records()
    if not members:
        return 0.0
    return float(np.mean([r.difficulty * np.nan_to_num(r.success_rate) for r in members]))


def criteria_values(
    mazes: MazePopulation, validation_success_rate: float, validation_fitness: float
) -> dict[str, float]:
    """Every one of :data:`CRITERIA` for an alternative at the end of its epoch."""
    return {
        "validation_success_rate": float(validation_success_rate),
        "validation_fitness": float(validation_fitness),
        "difficulty_reached": difficulty_reached(mazes),
        "diversity": mazes.diversity(),
    }


@dataclass
class Outcome:
    """One alternative of an epoch, once played: its controller, what it reached, its state.

    ``learner`` and ``mazes`` are the alternative's learner state and maze
    population at the end of its epoch (the chosen one's go on).
    """

    index: int
    controller: MazePopulationConfig
    mutated: tuple[str, ...]
    criteria: dict[str, float]
    solved: bool
    learner: Any = field(default=None, repr=False)
    mazes: MazePopulation | None = field(default=None, repr=False)


def choose(
    outcomes: Sequence[Outcome], criteria: Sequence[str], rng: np.random.Generator
) -> tuple[Outcome, list[Outcome], list[Outcome]]:
    """The pick, the Pareto front it was drawn from, and the living alternatives.

    Extinct alternatives (``solved`` false) are rejected unless all are; the
    front is built on ``criteria`` among the others and one member drawn
    uniformly from ``rng``.
    """
    alive = [o for o in outcomes if o.solved] or list(outcomes)
    front = pareto_front(alive, lambda o: tuple(o.criteria[name] for name in criteria))
    return front[int(rng.integers(len(front)))], front, alive


@dataclass
class SelectorState:
    """The selector's part of a checkpoint: the epoch under way and every epoch's record.

    ``parent_learner`` and ``parent_mazes`` are the state the epoch's
    alternatives start from; ``controllers`` and ``mutated`` what each
    alternative was given; ``current`` the alternative being played and
    ``played`` its rounds so far; ``outcomes`` the alternatives already
    played; ``solved`` whether the current alternative's agents reached a
    goal so far; ``decisions`` one JSON object per finished epoch
    (``epochs.jsonl``).
    """

    epoch: int = 0
    parent_learner: Any = None
    parent_mazes: MazePopulation | None = None
    controllers: list[MazePopulationConfig] = field(default_factory=list)
    mutated: list[tuple[str, ...]] = field(default_factory=list)
    current: int = 0
    played: int = 0
    solved: bool = False
    outcomes: list[Outcome] = field(default_factory=list)
    decisions: list[dict[str, Any]] = field(default_factory=list)

    @property
    def under_way(self) -> bool:
        """Whether an epoch has begun and not yet been decided."""
        return self.parent_mazes is not None
