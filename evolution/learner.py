"""Evolution as a curriculum learner: a search algorithm trained stage after stage.

:class:`EvolutionLearner` implements :class:`amaze.curriculum.learner.Learner`
for any :class:`~evolution.algorithms.SearchAlgorithm` (CMA-ES, the NEAT-like
GA). It holds the algorithm's whole state (population, strategy, random
generators), the robot, the fitness measure, ``checkpoint_seconds`` and the
current training session.

* ``train(mazes, budget_steps, budget_seconds=..., checkpoint=...)`` plays
  generations (ask, evaluate on ``mazes`` as given, tell) until the session
  has spent ``budget_steps`` env steps or ``budget_seconds`` seconds (a
  generation is whole, so the last one may pass the budget by less than a
  generation; a seconds budget makes the session depend on the machine's
  speed), the fitness reached its maximum
  (*converged*: an individual whose every episode is optimal, R̄ = 1, for
  ``normalized_reward`` and ``pretty_reward``; every episode reached for
  ``success``), or the algorithm stopped (CMA-ES with no restart left). A
  new session starts with :meth:`~evolution.algorithms.SearchAlgorithm.forget_champion`:
  fitness on the previous mazes does not compare with fitness on these.
  The previous champion is played on the new mazes instead (its steps
  count in the session) and is the champion to beat: a branch never hands
  on an agent worse on its own mazes than the one it started from, even
  when CMA-ES restarts from a random mean mid-session, and a session
  whose inherited champion is already optimal there ends at once
  (converged).
  ``checkpoint()`` is called after the session's first generation, then after
  the first generation ending ``checkpoint_seconds`` after the previous call
  (0: every generation), and at the end.
* ``agent()`` is the session's champion (the best individual on the current
  mazes, the inherited champion included) as a policy.
* ``branch(seed)`` is a deep copy whose algorithm is reseeded with ``seed``
  (:meth:`~evolution.algorithms.SearchAlgorithm.reseed`), without a session.
* ``save(folder)`` writes ``learner.npz`` (the whole learner, a checkpoint of
  :mod:`amaze.runs.checkpoint` read back by :func:`load_learner` with the
  evolution codec: JSON plus arrays, naming no function) and, once there is
  a champion, ``champion.npz`` (an agent file: ``amaze run --controller
  FOLDER/champion.npz``).

Populations are played on the current backend (:mod:`evolution.backends`:
this process, or Ray actors with identical results).

Evaluations are deterministic and every draw comes from the algorithm's own
generators, so the same seed on the same mazes gives bit-identical results in
any process, and a learner saved mid-session, loaded and trained on with the
same mazes and budget ends bit-identical to one never interrupted.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from amaze.curriculum.learner import SessionWatch, TrainingOutcome, checked_session_budget
from amaze.runs.checkpoint import StateCodec, read_checkpoint, write_checkpoint
from amaze.validation import check_number
from evolution import EvolutionConfigError
from evolution.agent_file import policy_from_agent_arrays, save_agent
from evolution.algorithms import SearchAlgorithm, make_algorithm, population_size
from evolution.backends import Backend, current_backend
from evolution.checkpoint import evolution_codec
from evolution.population import FITNESS, EvaluationBackend, PopulationResult, fewest_steps

__all__ = ["LEARNER_FILE", "LEARNER_VERSION", "EvolutionLearner", "load_learner"]

LEARNER_FILE = "learner.npz"
CHAMPION_FILE = "champion.npz"
#: Version of the saved learner's layout; another version is refused.
LEARNER_VERSION = 1
#: R̄ (or the pretty reward) at or above this counts as optimal (1 for a run in l-1 steps).
OPTIMAL = 1.0 - 1e-9


@dataclass
class Session:
    """One training session: its mazes and budget, and what it spent and reached so far."""

    mazes: tuple[str, ...]
    budget_steps: int | None
    steps: int = 0
    seconds: float = 0.0
    eval_seconds: float = 0.0
    generations: int = 0
    converged: bool = False
    #: The best fitness told in the session (the champion's).
    champion_fitness: float | None = None
    #: Seconds of training the session may spend (``None``: no time limit).
    budget_seconds: float | None = None


@dataclass
class Champion:
    """An agent's arrays and metadata, as an agent file holds them."""

    arrays: dict[str, np.ndarray]
    architecture: dict[str, Any]
    fitness: float
    mazes: tuple[str, ...]
    generation: int = 0
    extra: dict[str, Any] = field(default_factory=dict)


class EvolutionLearner:
    """A search algorithm as a curriculum learner (see the module docstring)."""

    def __init__(
        self,
        algorithm: SearchAlgorithm,
        *,
        algo: str,
        robot: str,
        seed: int,
        fitness: str = "normalized_reward",
        checkpoint_seconds: float = 10.0,
    ) -> None:
        if fitness not in FITNESS:
            raise EvolutionConfigError(f"fitness {fitness!r} is not one of {', '.join(FITNESS)}")
        self.algorithm = algorithm
        self.algo = algo
        self.robot = robot
        self.seed = int(seed)
        self.fitness = fitness
        self.checkpoint_seconds = check_number(
            "checkpoint_seconds", checkpoint_seconds, minimum=0, error=EvolutionConfigError
        )
        self.session: Session | None = None
        #: The last finished session (its figures, for reports).
        self.last_session: Session | None = None
        self.champion: Champion | None = None
        #: Over the learner's whole life (its ancestors' included): generations, steps, seconds.
        self.generations = 0
        self.env_steps = 0
        self.eval_seconds = 0.0
        self.version = LEARNER_VERSION
        self._backend: tuple[tuple[str, ...], Backend, EvaluationBackend] | None = None

    @classmethod
    def new(
        cls,
        algo: str,
        options: Mapping[str, Any],
        robot: str,
        seed: int,
        *,
        fitness: str = "normalized_reward",
        checkpoint_seconds: float = 10.0,
    ) -> EvolutionLearner:
        """A fresh learner: algorithm ``algo`` with its JSON ``options``, seeded with ``seed``."""
        algorithm = make_algorithm(algo, options, robot, seed)
        return cls(
            algorithm,
            algo=algo,
            robot=robot,
            seed=seed,
            fitness=fitness,
            checkpoint_seconds=checkpoint_seconds,
        )

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["_backend"] = None  # engines are rebuilt from the session's mazes
        return state

    # -- the Learner protocol -----------------------------------------------------

    def train(
        self,
        mazes: Sequence[str],
        budget_steps: int | None,
        *,
        budget_seconds: float | None = None,
        checkpoint: Callable[[], None] | None = None,
        progress: Callable[[int], None] | None = None,
        watch: SessionWatch | None = None,
    ) -> TrainingOutcome:
        """A training session on ``mazes`` (as given), or the rest of the one saved mid-way.

        A ``watch`` (judging the session on other mazes) is refused: a
        generation's champion is the agent, chosen on the training mazes.
        """
        if watch is not None:
            raise EvolutionConfigError(
                "an evolution session is judged on its training mazes: a watch on other"
                " mazes is for the RL learners"
            )
        mazes = tuple(str(m) for m in mazes)
        if not mazes:
            raise EvolutionConfigError("a training session needs at least one maze")
        budget_steps, budget_seconds = checked_session_budget(
            budget_steps, budget_seconds, EvolutionConfigError
        )
        backend = self._evaluator(mazes)
        session = self.session
        if (
            session is None
            or session.mazes != mazes
            or session.budget_steps != budget_steps
            or session.budget_seconds != budget_seconds
        ):
            self.algorithm.forget_champion()
            session = self.session = Session(mazes, budget_steps, budget_seconds=budget_seconds)
            self._inherit_champion(session, backend)
        last_checkpoint: float | None = None
        while self._goes_on(session):
            started = time.perf_counter()
            self._generation(session, backend)
            session.seconds += time.perf_counter() - started
            if progress is not None:
                progress(session.steps)
            if checkpoint is not None and self._goes_on(session):
                if last_checkpoint is None or (
                    session.seconds - last_checkpoint >= self.checkpoint_seconds
                ):
                    started = time.perf_counter()
                    checkpoint()
                    session.seconds += time.perf_counter() - started
                    last_checkpoint = session.seconds
        if checkpoint is not None:
            checkpoint()  # the finished session: a resumed one ends here at once
        self.session, self.last_session = None, session
        return TrainingOutcome(session.steps, session.seconds, session.converged)

    def branch(self, seed: int) -> EvolutionLearner:
        """A deep copy without a session, its algorithm reseeded with ``seed``."""
        twin = copy.deepcopy(self)
        twin.algorithm.reseed(seed)
        twin.seed = int(seed)
        twin.session = twin.last_session = None
        return twin

    def agent(self) -> Any:
        """The champion of the session (the last one with a generation) as a policy."""
        champion = self.champion
        if champion is None:
            raise EvolutionConfigError(
                "the learner has evaluated no generation yet (budget too small?)"
            )
        return policy_from_agent_arrays(
            champion.arrays,
            {"architecture": champion.architecture, "robot": self.robot},
            where=f"the {self.algo} champion",
        )

    def save(self, folder: Path) -> None:
        """``learner.npz`` and, once there is a champion, ``champion.npz``, each atomically."""
        folder = Path(folder)
        champion = self.champion
        if champion is not None:
            save_agent(
                folder / CHAMPION_FILE,
                champion.arrays,
                {
                    "architecture": champion.architecture,
                    "robot": self.robot,
                    "mazes": list(champion.mazes),
                    "fitness": champion.fitness,
                    "fitness_measure": self.fitness,
                    "algorithm": self.algo,
                    "generation": champion.generation,
                    "seed": self.seed,
                },
            )
        write_checkpoint(folder / LEARNER_FILE, self, _codec())

    # -- figures --------------------------------------------------------------------

    @property
    def policy_steps_per_second(self) -> float:
        """Env steps played per second of evaluation, over the learner's life."""
        return self.env_steps / max(self.eval_seconds, 1e-9)

    # -- the loop's own ---------------------------------------------------------------

    def _goes_on(self, session: Session) -> bool:
        """The session has not converged or stopped, and has budget for another generation.

        A generation starts only if the steps left pay its smallest cost
        (:meth:`generation_steps`); it may then cost more, by less than a
        generation, which the session's steps record.
        """
        budget_seconds = getattr(session, "budget_seconds", None)
        steps_left = None if session.budget_steps is None else session.budget_steps - session.steps
        return (
            not session.converged
            and not self.algorithm.stopped
            and (budget_seconds is None or session.seconds < budget_seconds)
            and (steps_left is None or steps_left >= self.generation_steps(session.mazes))
        )

    def generation_steps(self, mazes: Sequence[str]) -> int:
        """The fewest env steps a generation of the algorithm can spend on ``mazes`` (as given)."""
        return population_size(self.algorithm) * _fewest_steps(tuple(mazes), self.robot)

    def _evaluator(self, mazes: tuple[str, ...]) -> EvaluationBackend:
        """The evaluator of ``mazes`` on the current backend (kept while both stay the same)."""
        backend = current_backend()
        if self._backend is None or self._backend[:2] != (mazes, backend):
            # The mazes come with their rotations already: they are played as given.
            evaluator = backend.evaluator(list(mazes), self.robot, fitness=self.fitness)
            self._backend = (mazes, backend, evaluator)
        return self._backend[2]

    def _inherit_champion(self, session: Session, backend: EvaluationBackend) -> None:
        """The previous champion, played on the new session's mazes, becomes the one to beat."""
        if self.champion is None:
            return
        started = time.perf_counter()
        result = backend.evaluate(self.agent())
        session.seconds += time.perf_counter() - started
        session.steps += result.env_steps
        session.eval_seconds += result.seconds
        self.env_steps += result.env_steps
        self.eval_seconds += result.seconds
        session.converged = self._converged(result)
        session.champion_fitness = float(result.fitness[0])
        self.champion = dataclasses.replace(
            self.champion, fitness=session.champion_fitness, mazes=session.mazes
        )

    def _generation(self, session: Session, backend: EvaluationBackend) -> None:
        algorithm = self.algorithm
        candidates = algorithm.ask()
        result = backend.evaluate(algorithm.population_policy(candidates))
        algorithm.tell(candidates, result.fitness)
        session.generations += 1
        session.steps += result.env_steps
        session.eval_seconds += result.seconds
        self.generations += 1
        self.env_steps += result.env_steps
        self.eval_seconds += result.seconds
        session.converged = self._converged(result)
        champion = algorithm.champion
        if champion is not None and (
            session.champion_fitness is None or champion[1] > session.champion_fitness
        ):
            session.champion_fitness = float(champion[1])
            arrays, architecture = algorithm.champion_arrays()
            self.champion = Champion(
                arrays={k: np.array(v) for k, v in arrays.items()},
                architecture=dict(architecture),
                fitness=float(champion[1]),
                mazes=session.mazes,
                generation=self.generations,
            )

    def _converged(self, result: PopulationResult) -> bool:
        """True if an individual played every episode at the fitness measure's maximum."""
        if self.fitness in ("success_rate", "path_progress"):  # progress 1: the goal
            reached = result.per_episode("success").astype(bool)
        else:
            reached = result.per_episode(self.fitness) >= OPTIMAL
        return bool(reached.all(axis=1).any())


@functools.lru_cache(maxsize=32)
def _fewest_steps(mazes: tuple[str, ...], robot: str) -> int:
    """:func:`~evolution.population.fewest_steps`, once per session's mazes."""
    return fewest_steps(mazes, robot)


def _codec() -> StateCodec:
    """What ``learner.npz`` may hold: the learner, its session and champion, and an algorithm."""
    return evolution_codec(EvolutionLearner, Session, Champion)


def load_learner(folder: Path) -> EvolutionLearner:
    """The learner saved in ``folder`` (:meth:`EvolutionLearner.save`).

    Raises :class:`~evolution.EvolutionConfigError` naming ``learner.npz`` if
    it is missing, damaged, names what a checkpoint may not, or is of another
    version.
    """
    path = Path(folder) / LEARNER_FILE
    if not (path.exists() or path.is_symlink()):
        raise EvolutionConfigError(f"learner {str(path)!r} does not exist")
    learner = read_checkpoint(path, _codec(), EvolutionConfigError, EvolutionLearner)
    version = getattr(learner, "version", None)
    if version != LEARNER_VERSION:
        raise EvolutionConfigError(
            f"learner {str(path)!r} is of version {version!r}, not {LEARNER_VERSION}"
        )
    if not isinstance(learner.algorithm, SearchAlgorithm):
        raise EvolutionConfigError(f"learner {str(path)!r} holds no search algorithm")
    learner._backend = None
    return learner
