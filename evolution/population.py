"""Population policies and their fitness: P individuals x M episodes on one batch engine.

A **population policy** is a policy of the :mod:`amaze.evaluation.policy` protocol that
holds ``n_policies`` (P) individuals. It is played on one
:class:`~amaze.agents.engine.BatchEngine` of ``P * M`` agents: agent ``k`` belongs to
individual ``k // M`` and plays episode ``k % M`` of the maze set (M episodes
per individual, e.g. some mazes in their 4 rotations). Its ``reset(n_agents)``
hook tells it ``M = n_agents // P``. Any plain policy is a population of one.

:class:`PopulationEvaluator` prepares a maze set once (generation and
compilation), plays a whole population on it with
:func:`amaze.evaluation.policy.run_episodes` and returns a :class:`PopulationResult`:
per individual its fitness (the mean over its M episodes of the paper's
normalised reward R̄, the success or the reference's pretty reward), success
rate and mean rewards, and the budget spent: ``env_steps`` counts the steps of
the scored episodes only (those an RL learner would have taken; the agents
that keep stepping once their episode is over are not counted) and
``seconds`` the wall-clock time.

**Backends.** Algorithms only need an :class:`EvaluationBackend`, anything
with ``evaluate(policy) -> PopulationResult``; :class:`PopulationEvaluator` is
the local one. A distributed backend (Ray, say) can cut a population into
chunks with ``policy.subset(indices)`` (:class:`SplittablePopulation`; network
populations pickle as their spec and parameters), evaluate them on workers
with their own :class:`PopulationEvaluator` and join the results with
:meth:`PopulationResult.concatenate`, without the algorithms changing.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field, fields
from typing import Any, Protocol, runtime_checkable

import numpy as np

from amaze.agents.engine import BatchEngine
from amaze.agents.rewards import DEFAULT_DEADLINE_FACTOR, check_deadline_factor
from amaze.agents.robot import IOType, Robot, as_robot
from amaze.agents.tables import MazeTables, compile_mazes
from amaze.evaluation.policy import EpisodeResults, run_episodes
from amaze.maze import Maze, MazeSpec, as_mazes
from amaze.maze import rotations as maze_rotations  # the ``rotations`` flag shadows the name
from amaze.validation import check_integer
from evolution import EvolutionConfigError

__all__ = [
    "FITNESS",
    "OLD_FITNESS",
    "EvaluationBackend",
    "PopulationEvaluator",
    "PopulationPolicy",
    "PopulationResult",
    "SplittablePopulation",
    "fewest_steps",
]

#: Fitness measures: the mean over an individual's episodes of one of these.
#: ``path_progress`` is how far along its maze's solution an episode got (1 on
#: success, :attr:`~amaze.evaluation.policy.EpisodeResults.path_progress`): unlike
#: the rewards it tells apart agents that move toward the goal from those that stand
#: still, on mazes where none reaches it.
FITNESS: tuple[str, ...] = ("normalized_reward", "success_rate", "pretty_reward", "path_progress")
#: Fitness names of configs written before R̄ and the success rate had one name.
OLD_FITNESS = {"paper_reward": "normalized_reward", "success": "success_rate"}


def fewest_steps(mazes: Sequence[Maze | MazeSpec | str], robot: Robot | str) -> int:
    """The fewest env steps an individual can spend playing each of ``mazes`` once.

    With discrete actions an episode lasts at least its maze's shortest path
    (``len(solution) - 1`` steps); with continuous ones at least a step. A
    generation of P individuals costs at least P times this: the smallest unit
    of evolution, which a run starts only if its budget can pay it.
    """
    if as_robot(robot).outputs is not IOType.DISCRETE:
        return len(mazes)
    return sum(len(maze.solution) - 1 for maze in as_mazes(list(mazes)))


#: Engines kept by an evaluator (one per population size).
_MAX_ENGINES = 4


@runtime_checkable
class PopulationPolicy(Protocol):
    """P individuals acting together: agent ``k`` of ``P * M`` belongs to individual ``k // M``."""

    n_policies: int
    robot: Robot | str

    def __call__(self, observations: np.ndarray) -> np.ndarray: ...

    def reset(self, n_agents: int) -> None: ...


@runtime_checkable
class SplittablePopulation(PopulationPolicy, Protocol):
    """A population that can be cut into parts (for distributed evaluation)."""

    def subset(self, indices: Sequence[int] | np.ndarray) -> SplittablePopulation: ...


@dataclass(frozen=True)
class PopulationResult:
    """Scores of P individuals over M episodes each (arrays of shape ``(P,)``).

    ``episodes`` holds every episode (``P * M`` rows, agent ``k`` = individual
    ``k // M``, episode ``k % M``); :meth:`per_episode` reshapes a field to ``(P, M)``.
    """

    fitness: np.ndarray
    success_rate: np.ndarray
    normalized_reward: np.ndarray
    pretty_reward: np.ndarray
    env_steps: int
    seconds: float
    episodes: EpisodeResults | None = field(default=None, repr=False, compare=False)

    def __len__(self) -> int:
        return int(self.fitness.shape[0])

    @property
    def n_episodes(self) -> int:
        """Episodes per individual (M); 0 when the episodes were not kept."""
        if self.episodes is None or not len(self):
            return 0
        return len(self.episodes) // len(self)

    def per_episode(self, name: str) -> np.ndarray:
        """Field ``name`` of the episode results (:mod:`amaze.evaluation.policy`) as ``(P, M)``."""
        if self.episodes is None:
            raise EvolutionConfigError("this result does not hold its episodes")
        if name not in {f.name for f in fields(EpisodeResults)}:
            raise EvolutionConfigError(f"episodes have no field {name!r}")
        values = getattr(self.episodes, name)
        if values is None:
            raise EvolutionConfigError(f"these episodes did not record {name!r}")
        return values.reshape(len(self), -1)

    @property
    def best(self) -> int:
        """Index of the fittest individual (the first one on ties)."""
        return int(np.argmax(self.fitness))

    @classmethod
    def concatenate(
        cls, results: Sequence[PopulationResult], seconds: float | None = None
    ) -> PopulationResult:
        """The results of consecutive parts of a population, joined in order.

        Steps add up; ``seconds`` defaults to the sum of the parts' times (pass
        the wall-clock time when the parts ran concurrently).
        """
        if not results:
            raise EvolutionConfigError("concatenate: give at least one result")
        episodes = None
        if all(r.episodes is not None for r in results):
            episodes = EpisodeResults(
                **{
                    f.name: _joined([getattr(r.episodes, f.name) for r in results])
                    for f in fields(EpisodeResults)
                }
            )
        return cls(
            fitness=np.concatenate([r.fitness for r in results]),
            success_rate=np.concatenate([r.success_rate for r in results]),
            normalized_reward=np.concatenate([r.normalized_reward for r in results]),
            pretty_reward=np.concatenate([r.pretty_reward for r in results]),
            env_steps=sum(r.env_steps for r in results),
            seconds=float(sum(r.seconds for r in results) if seconds is None else seconds),
            episodes=episodes,
        )


def _joined(parts: list[np.ndarray | None]) -> np.ndarray | None:
    """The parts of one episode field joined in order; None when any part lacks it."""
    if any(part is None for part in parts):
        return None
    return np.concatenate(parts)


class EvaluationBackend(Protocol):
    """What the algorithms need to score a population (see the module docstring)."""

    def evaluate(self, policy: PopulationPolicy) -> PopulationResult: ...


class PopulationEvaluator:
    """Fitness of populations on one maze set (M episodes per individual).

    ``mazes`` (mazes, specs or maze strings) are played as given, once each
    (``rotations=True`` expands each to its 4 rotations first, see
    :func:`amaze.maze.rotations`). ``fitness`` is one of :data:`FITNESS`. Mazes
    are generated and compiled once (``tables``: their compiled tables, when a
    distributed backend ships them from where they were compiled); one engine
    is kept per population size (the first, for ``n_policies`` individuals, is
    built at once), all on the same tables.
    """

    def __init__(
        self,
        mazes: Maze | MazeSpec | str | Sequence[Maze | MazeSpec | str],
        robot: Robot | str,
        *,
        fitness: str = "normalized_reward",
        deadline_factor: float = DEFAULT_DEADLINE_FACTOR,
        rotations: bool = False,
        n_policies: int = 1,
        tables: MazeTables | None = None,
    ) -> None:
        if fitness not in FITNESS:
            raise EvolutionConfigError(f"fitness {fitness!r} is not one of {', '.join(FITNESS)}")
        try:
            self.robot = as_robot(robot)
            self.mazes: list[Maze] = as_mazes(maze_rotations(mazes) if rotations else mazes)
            self.deadline_factor = check_deadline_factor(deadline_factor)
            self.tables = (
                compile_mazes(self.mazes, self.robot, self.deadline_factor)
                if tables is None
                else tables
            )
        except EvolutionConfigError:
            raise
        except ValueError as error:
            raise EvolutionConfigError(str(error)) from None
        self.fitness = fitness
        self.maze_strings = [m.to_string() for m in self.mazes]
        self._engines: dict[int, BatchEngine] = {}
        # compiles the maze tables now (for populations of n_policies), checks the deadline factor
        self.engine(check_integer("n_policies", n_policies, minimum=1, error=EvolutionConfigError))

    @property
    def n_episodes(self) -> int:
        """Episodes per individual (M): the number of mazes played."""
        return len(self.mazes)

    def engine(self, n_policies: int) -> BatchEngine:
        """The engine of ``n_policies * M`` agents, agent ``k`` in maze ``k % M``."""
        engine = self._engines.get(n_policies)
        if engine is None:
            if len(self._engines) >= _MAX_ENGINES:
                self._engines.pop(next(iter(self._engines)))
            try:
                engine = BatchEngine(
                    self.mazes, self.robot, n_policies * self.n_episodes,
                    deadline_factor=self.deadline_factor, tables=self.tables,
                )  # fmt: skip
            except EvolutionConfigError:
                raise
            except ValueError as error:
                raise EvolutionConfigError(str(error)) from None
            self._engines[n_policies] = engine
        return engine

    def evaluate(self, policy: PopulationPolicy | Any) -> PopulationResult:
        """Play every individual of ``policy`` once in each maze and score it."""
        n_policies = check_integer(
            "n_policies", getattr(policy, "n_policies", 1), minimum=1, error=EvolutionConfigError
        )
        robot = getattr(policy, "robot", None)
        if robot is not None and as_robot(robot) != self.robot:
            raise EvolutionConfigError(
                f"the population drives {as_robot(robot)} robots, the evaluator {self.robot}"
            )
        engine = self.engine(n_policies)
        started = time.perf_counter()
        progress = self.fitness == "path_progress"
        episodes = run_episodes(engine, policy, path_progress=progress)
        seconds = time.perf_counter() - started
        shape = (n_policies, self.n_episodes)
        success = episodes.success.reshape(shape).mean(axis=1)
        paper = episodes.normalized_reward.reshape(shape).mean(axis=1)
        pretty = episodes.pretty_reward.reshape(shape).mean(axis=1)
        if progress:
            fitness = episodes.path_progress.reshape(shape).mean(axis=1)
        else:
            fitness = {"normalized_reward": paper, "success_rate": success, "pretty_reward": pretty}
            fitness = fitness[self.fitness].copy()
        return PopulationResult(
            fitness=fitness,
            success_rate=success,
            normalized_reward=paper,
            pretty_reward=pretty,
            env_steps=int(episodes.steps.sum()),
            seconds=seconds,
            episodes=episodes,
        )

    def __call__(self, policy: PopulationPolicy | Any) -> PopulationResult:
        return self.evaluate(policy)
