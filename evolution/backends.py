"""Where populations are played: in this process, or split across Ray actors.

A **backend** makes the evaluator of a maze set (an
:class:`~evolution.population.EvaluationBackend`: ``evaluate(policy) ->
PopulationResult``)::

    evaluator = backend.evaluator(mazes, robot, fitness="normalized_reward", rotations=True)
    result = evaluator.evaluate(algorithm.population_policy(candidates))

* :class:`LocalBackend` (the default) returns a
  :class:`~evolution.population.PopulationEvaluator`: the batch engine in this
  process.
* :class:`RayBackend` (``amaze-evolve --backend ray [--address ADDR] [--actors N]``)
  keeps N Ray actors (default: one per free CPU of the cluster), each with one
  numba thread. An evaluator generates and compiles its mazes once, here, and
  puts them in Ray's object store once; each actor reads them at its first
  evaluation on that maze set and keeps its own batch engines on them, so a
  generation sends only the population's parameters. A population is cut
  into N consecutive parts (``policy.subset``), one per actor, and the parts'
  results are joined in population order
  (:meth:`~evolution.population.PopulationResult.concatenate`). An
  individual's episodes do not depend on the other individuals of its
  batch, so the results are bit-identical to the local backend's, and a run
  reaches the same champion with either.

  **Failures.** An actor whose process dies (killed, out of memory, its node
  lost) is restarted by Ray and its part of the generation retried
  (:data:`ACTOR_RESTARTS` times); the restarted actor reads the maze set
  from the object store again. The generation's result is unchanged.

The backend of a run is the one :func:`use_backend` set around it (the
command line sets it from ``--backend``); runs and learners ask
:func:`current_backend`. Ray is imported only when a :class:`RayBackend`
is made.
"""

from __future__ import annotations

import contextlib
import contextvars
import os
import time
from collections import OrderedDict
from collections.abc import Iterator, Sequence
from typing import Any, Protocol

import numpy as np

from amaze.agents.rewards import DEFAULT_DEADLINE_FACTOR
from amaze.agents.robot import Robot, as_robot
from amaze.agents.tables import MazeTables
from amaze.maze import Maze, MazeSpec
from amaze.runs.cluster import cluster_cpus, connect
from amaze.validation import check_integer
from evolution import EvolutionConfigError
from evolution.population import (
    EvaluationBackend,
    PopulationEvaluator,
    PopulationPolicy,
    PopulationResult,
)

__all__ = [
    "ACTOR_RESTARTS",
    "Backend",
    "EvaluationActor",
    "LocalBackend",
    "RayBackend",
    "RayEvaluator",
    "current_backend",
    "make_backend",
    "use_backend",
]

#: Restarts of a dead actor, and retries of its part of a generation, before the run fails.
ACTOR_RESTARTS = 3
#: Seconds the actors of a new backend may take to start.
ACTOR_START_SECONDS = 300.0
#: Seconds to wait for CPUs that actors just stopped are giving back.
FREEING_SECONDS = 5.0
#: Maze sets an actor keeps engines for (a co-evolution run changes its set every generation).
ACTOR_MAZE_SETS = 4


class Backend(Protocol):
    """What makes evaluators: :class:`LocalBackend`, :class:`RayBackend`.

    The keywords are those of :class:`~evolution.population.PopulationEvaluator`.
    """

    def evaluator(
        self,
        mazes: Maze | MazeSpec | str | Sequence[Maze | MazeSpec | str],
        robot: Robot | str,
        *,
        fitness: str = "normalized_reward",
        deadline_factor: float = DEFAULT_DEADLINE_FACTOR,
        rotations: bool = False,
        n_policies: int = 1,
    ) -> EvaluationBackend: ...


class LocalBackend:
    """Populations played in this process (:class:`~evolution.population.PopulationEvaluator`)."""

    name = "local"

    def evaluator(
        self,
        mazes: Maze | MazeSpec | str | Sequence[Maze | MazeSpec | str],
        robot: Robot | str,
        **options: Any,
    ) -> PopulationEvaluator:
        """A :class:`PopulationEvaluator` (``options``: its keywords, as :class:`Backend`'s)."""
        return PopulationEvaluator(mazes, robot, **options)

    def __repr__(self) -> str:
        return "LocalBackend()"


_LOCAL = LocalBackend()
_CURRENT: contextvars.ContextVar[Backend | None] = contextvars.ContextVar(
    "evaluation backend", default=None
)


def current_backend() -> Backend:
    """The backend runs evaluate on (:class:`LocalBackend` unless :func:`use_backend` says)."""
    return _CURRENT.get() or _LOCAL


@contextlib.contextmanager
def use_backend(backend: Backend) -> Iterator[Backend]:
    """Evaluate on ``backend`` inside the ``with`` block (then on the previous one again)."""
    token = _CURRENT.set(backend)
    try:
        yield backend
    finally:
        _CURRENT.reset(token)


class EvaluationActor:
    """A Ray actor's state: one numba thread, evaluators of the last maze sets it was given.

    Plain class, made a Ray actor by :class:`RayBackend` (``ray.remote`` at run
    time, so that importing this module never imports Ray).
    """

    def __init__(self) -> None:
        import numba

        numba.set_num_threads(1)  # one actor per CPU: threads would only fight each other
        self.evaluators: OrderedDict[str, PopulationEvaluator] = OrderedDict()

    def evaluate(
        self, key: str, maze_set: list[Any], fitness: str, part: PopulationPolicy
    ) -> PopulationResult:
        """Play ``part`` on the maze set ``key``; ``maze_set`` wraps its object reference.

        The reference comes inside a list so that Ray hands it over unresolved:
        the maze set is read from the object store only by an actor that does
        not hold it yet.
        """
        evaluator = self.evaluators.get(key)
        if evaluator is None:
            import ray

            mazes, tables = ray.get(maze_set[0])
            evaluator = PopulationEvaluator(
                mazes,
                tables.robot,
                fitness=fitness,
                deadline_factor=tables.deadline_factor,
                n_policies=part.n_policies,
                tables=tables,
            )
            self.evaluators[key] = evaluator
            while len(self.evaluators) > ACTOR_MAZE_SETS:
                self.evaluators.popitem(last=False)
        self.evaluators.move_to_end(key)
        return evaluator.evaluate(part)

    def pid(self) -> int:
        """The actor's process id (to watch it, or to kill it in a failure test)."""
        return os.getpid()


class RayBackend:
    """Populations split across Ray actors (see the module docstring).

    ``actors``: how many (default: one per CPU of the cluster that no other
    task or actor holds); ``address``: the cluster
    (:func:`amaze.runs.cluster.connect`). Each actor holds one CPU for its
    life, so more actors than free CPUs are refused at once: Ray would wait,
    without a word, for CPUs that never come.
    """

    name = "ray"

    def __init__(self, actors: int | None = None, address: str | None = None) -> None:
        if actors is not None:
            actors = check_integer(
                "--actors", actors, minimum=1, maximum=4096, error=EvolutionConfigError
            )
        self.ray = connect(address)
        free = _free_cpus(self.ray, wanted=actors or 1)
        if actors is None:
            actors = free
        if actors < 1 or actors > free:
            raise EvolutionConfigError(
                f"--actors {actors}: the Ray cluster has {free} free CPUs of"
                f" {cluster_cpus(self.ray)}, and each actor needs one"
            )
        self.n_actors = actors
        actor_class = self.ray.remote(
            num_cpus=1, max_restarts=ACTOR_RESTARTS, max_task_retries=ACTOR_RESTARTS
        )(EvaluationActor)
        self.actors = [actor_class.remote() for _ in range(self.n_actors)]
        try:  # placed and started (their CPUs held) before the backend is used
            self.ray.get([actor.pid.remote() for actor in self.actors], timeout=ACTOR_START_SECONDS)
        except self.ray.exceptions.GetTimeoutError:
            self.close()
            raise EvolutionConfigError(
                f"{self.n_actors} Ray actors did not start within {ACTOR_START_SECONDS:.0f} s"
                " (are the cluster's CPUs taken?)"
            ) from None

    def evaluator(
        self,
        mazes: Maze | MazeSpec | str | Sequence[Maze | MazeSpec | str],
        robot: Robot | str,
        **options: Any,
    ) -> RayEvaluator:
        """The evaluator of ``mazes`` on the actors (``options``: as :class:`Backend`'s).

        The mazes are generated, compiled and checked here, once; ``n_policies``
        (the engine to build at once) is the actors' business.
        """
        options.pop("n_policies", None)
        return RayEvaluator(self, PopulationEvaluator(mazes, robot, **options))

    def actor_pids(self) -> list[int]:
        """The process ids of the actors, in order."""
        return self.ray.get([actor.pid.remote() for actor in self.actors])

    def close(self) -> None:
        """Stop the actors and wait (a little) for their CPUs to be free; the cluster stays up."""
        if not self.actors:
            return
        free = _free_cpus(self.ray, wanted=0)
        for actor in self.actors:
            self.ray.kill(actor)
        _free_cpus(self.ray, wanted=free + len(self.actors))
        self.actors = []

    def __enter__(self) -> RayBackend:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"RayBackend(actors={self.n_actors})"


def _free_cpus(ray: Any, wanted: int, seconds: float | None = None) -> int:
    """The cluster's free CPUs, once there are ``wanted`` or ``seconds`` have passed.

    Ray frees the CPUs of a killed actor a moment after ``ray.kill`` returns.
    """
    deadline = time.monotonic() + (FREEING_SECONDS if seconds is None else seconds)
    while True:
        free = int(ray.available_resources().get("CPU", 0))
        if free >= wanted or time.monotonic() > deadline:
            return free
        time.sleep(0.02)


class RayEvaluator:
    """The evaluator of one maze set on a :class:`RayBackend`'s actors."""

    def __init__(self, backend: RayBackend, local: PopulationEvaluator) -> None:
        self.backend = backend
        #: The maze set compiled here: its figures, and the evaluator of unsplittable policies.
        self.local = local
        maze_set: tuple[list[Maze], MazeTables] = (local.mazes, local.tables)
        self._maze_set = backend.ray.put(maze_set)
        self.key = self._maze_set.hex()

    @property
    def n_episodes(self) -> int:
        """Episodes per individual (M): the number of mazes played."""
        return self.local.n_episodes

    def evaluate(self, policy: PopulationPolicy | Any) -> PopulationResult:
        """Play every individual of ``policy`` once in each maze, split across the actors.

        A policy that cannot be split (one agent, not a population) is played here.
        """
        n_policies = int(getattr(policy, "n_policies", 1))
        if not hasattr(policy, "subset") or n_policies < 2:
            return self.local.evaluate(policy)
        robot = getattr(policy, "robot", None)
        if robot is not None and as_robot(robot) != self.local.robot:
            raise EvolutionConfigError(
                f"the population drives {as_robot(robot)} robots, the evaluator {self.local.robot}"
            )
        started = time.perf_counter()
        parts = np.array_split(np.arange(n_policies), min(n_policies, self.backend.n_actors))
        futures = [
            actor.evaluate.remote(
                self.key, [self._maze_set], self.local.fitness, policy.subset(indices)
            )
            for actor, indices in zip(self.backend.actors, parts, strict=False)
        ]
        results = self.backend.ray.get(futures)
        return PopulationResult.concatenate(results, seconds=time.perf_counter() - started)

    def __call__(self, policy: PopulationPolicy | Any) -> PopulationResult:
        return self.evaluate(policy)


def make_backend(name: str, *, actors: int | None = None, address: str | None = None) -> Backend:
    """The backend named by ``--backend`` (``local`` or ``ray``) with its options."""
    if name == "local":
        if actors is not None:
            raise EvolutionConfigError(f"--actors {actors} needs --backend ray")
        return LocalBackend()
    if name == "ray":
        return RayBackend(actors=actors, address=address)
    raise EvolutionConfigError(f"--backend {name!r} is not one of local, ray")
