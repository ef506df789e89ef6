"""A co-evolved maze population: a level buffer that evolves beside the agents.

The ``coevolution`` regime trains agents on a population of mazes that
changes with them, instead of a fixed list (domain randomisation) or a
curator's stages. Each generation of agents is played on a *batch* of mazes
drawn from :class:`MazePopulation`; how the agents fared on each maze scores
it, the scores decide which mazes stay and which are replayed. The mechanics
borrow from three published systems, with their known bugs avoided:

**Scores** (:data:`SCORES`; each from one generation's results on the maze,
every agent of the population in its 4 rotations):

* ``learnability`` (default): ``p (1 - p)``, ``p`` the fraction of those
  episodes that reached the goal. It peaks at ``p = 1/2``: a maze that half
  the population solves is the one that *ranks* the agents, which is all a
  rank-based search (CMA-ES, NEAT's selection) learns from; mazes that every
  agent or no agent solves teach nothing now and score 0.
* ``regret``: a max-MC regret (Robust PLR): the highest R̄ any agent ever
  reached on the maze minus the population's mean R̄ on it now.

**Admission** (MCC's minimal criterion): a new maze joins the population
only if at least one agent reached the goal in it (in one rotation at
least) and its score is positive. A full population (``capacity``) admits it
only in place of a member of the lowest score, and only when it scores
higher (PLR's rule); among the members tied at that score, the one nearest
to the newcomer in the metric space (below) goes (*crowding*, which keeps
the population spread out). Replaced members are *retired*: ``mazes.csv``
keeps every maze that was ever a member, with its birth and retirement.

**Replay** (PLR, Jiang et al. 2021): once the population holds at least
``batch`` mazes, each slot of a batch replays a member with probability
``replay_probability`` (0.8), the members drawn without replacement from

``P = (1 - staleness) P_S + staleness P_C``, with
``P_S(i) = h(rank_i) / sum_j h(rank_j)``, ``h(r) = r ** (-1 / temperature)``

(``rank_i`` is 1 for the best score; ties keep the members' order), the
temperature a *power* (not a divisor, minimax#7), over a flat 1-D array of
scores (dcd PR #12), and ``P_C(i) = (g - g_i) / sum_j (g - g_j)``, ``g`` the
current generation and ``g_i`` the last one that played member ``i``
(uniform when every member was just played). Replay never falls back to
fresh mazes once the population is full enough (minimax#6).

**New mazes** fill the other slots: with probability ``mutation_probability``
a *mutant* (ACCEL): a member drawn from ``P``, changed by 1 to ``edits``
operators of the maze genome (:class:`~amaze.curriculum.genome.MazeGenome`,
sides within ``[min_size, max_size]``), which grows or shrinks it, adds or
removes signs...; otherwise a fresh maze of the target's *family*: the
target's fields with a new seed and a side drawn in ``[min_size,
max_size]`` (domain randomisation). Fresh seeds never are the evaluation
suite's (:func:`~amaze.curriculum.validation.reserved_seeds`) nor the
validation mazes'.

**Metric space**: each maze has a descriptor (side, intersections, lures,
traps, Surprisingness, Deceptiveness, each divided by
:data:`DESCRIPTOR_SCALES`), the Euclidean distance between descriptors
measures diversity (crowding above, :meth:`MazePopulation.diversity`).

Every draw comes from the population's own generator, seeded from the run's
seed; the whole object pickles (the buffer, its scores and the generator
state), so a run resumed from a checkpoint goes on bit-identically.
"""

from __future__ import annotations

import copy
import csv
import dataclasses
import io
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, TypeVar

import numpy as np

from amaze.curriculum.difficulty import DifficultyProfile
from amaze.curriculum.genome import SEED_RANGE, MazeGenome
from amaze.curriculum.maze_batch import BatchMaze, GenerationReport, MazeResult
from amaze.curriculum.replay import (
    CoevolutionError,
    rank_weights,
    replay_distribution,
    staleness_weights,
)
from amaze.curriculum.validation import reserved_seeds, unseen_mazes
from amaze.maze.arrow_styles import (
    DEFAULT_HEADS,
    DEFAULT_SHAFT_WIDTH,
    MAX_TRAINING_STYLES,
    TRAINING_PREFIX,
    check_heads,
    check_shaft_width,
)
from amaze.maze.maze import Maze, as_mazes, rotations
from amaze.maze.signs import Sign, SignError
from amaze.maze.spec import MAX_SIZE, MIN_SIZE, MazeSpec
from amaze.validation import check_integer, check_number, closest

__all__ = [
    "DESCRIPTOR_SCALES",
    "SCORES",
    "BatchMaze",
    "CoevolutionError",
    "GenerationReport",
    "MazePopulation",
    "MazePopulationConfig",
    "MazeRecord",
    "MazeResult",
    "mazes_csv",
    "options_from_dict",
    "rank_weights",
    "replay_distribution",
    "staleness_weights",
]

#: How a maze is scored from one generation's results (see the module docstring).
SCORES = ("learnability", "regret")
#: The descriptor's components and the scale each is divided by (about a 20x20 maze's value).
DESCRIPTOR_SCALES: dict[str, float] = {
    "side": 20.0,
    "intersections": 10.0,
    "lures": 20.0,
    "traps": 5.0,
    "surprisingness": 5.0,
    "deceptiveness": 2.0,
}
#: Draws of a new maze before settling for one already in the batch or population.
_REDRAWS = 8
#: The stream of a run's maze population, apart from its algorithm's.
_POPULATION_STREAM = 0xC0E


@dataclass(frozen=True)
class MazePopulationConfig:
    """The maze population's options (the run config's ``coevolution`` object).

    ``capacity`` mazes at most (PLR's buffer; 4000 there, where a level costs
    one episode; here every maze of a batch is played by the whole agent
    population, so a smaller buffer is replayed more often); ``batch`` mazes
    per generation, each in its 4 rotations; ``replay_probability``,
    ``staleness`` and ``temperature`` as in PLR; ``score`` one of
    :data:`SCORES`; ``mutation_probability`` the share of new mazes that are
    mutants rather than fresh family mazes; ``edits`` the most genome
    operators per mutant; ``min_size``/``max_size`` bound the sides of new
    mazes (``max_size`` default: the target's larger side). The run selects
    its champion on ``validation`` validation mazes, playing the
    ``validation_candidates`` best agents of every ``validation_every``-th
    generation there (an agent's validation costs as much wall-clock time as
    a few, so a few are played at once, and not every generation).
    ``shapes`` lists the sign shapes fresh family mazes are drawn in: each
    such maze draws one (uniformly) for all its signs, keeping their kinds and
    lightnesses, so that agents that see images (H robots) learn to read more
    than one shape; mutants keep their parent's (a sign kind a mutation adds
    comes from the genome's sign set: arrows). ``None`` (the default): the
    target's own signs. ``sign_styles`` > 0 adds that many arrow styles drawn
    from ``sign_styles_seed`` (:func:`amaze.maze.arrow_styles.training_styles`,
    the shapes ``arrowv0`` ... that ``amaze draw-signs`` writes) to those
    shapes: the run draws them into its folder and registers them itself, so
    that its config alone says what it trained on, and it resumes without
    setup (:attr:`drawn_shapes`); ``sign_styles_heads`` lists the heads they
    may have (:data:`amaze.maze.arrow_styles.HEADS`; by default filled and
    open) and ``sign_styles_shaft_width`` the ``[low, high]`` range their shafts'
    widths are drawn from (by default
    :data:`~amaze.maze.arrow_styles.DEFAULT_SHAFT_WIDTH`, thin shafts). The
    run's validation mazes take the shapes in turn
    (:attr:`~amaze.runs.coevolution.CoevolutionRun.validation_mazes`); the
    unseen mazes keep the target's. Robots that read sign values, not
    images (DD), refuse both options.
    """

    capacity: int = 64
    batch: int = 8
    replay_probability: float = 0.8
    staleness: float = 0.3
    temperature: float = 0.3
    score: str = "learnability"
    mutation_probability: float = 0.5
    edits: int = 3
    min_size: int = 5
    max_size: int | None = None
    validation: int = 16
    validation_every: int = 4
    validation_candidates: int = 4
    shapes: tuple[str, ...] | None = None
    sign_styles: int = 0
    sign_styles_seed: int = 0
    sign_styles_heads: tuple[str, ...] = DEFAULT_HEADS
    sign_styles_shaft_width: tuple[float, float] = DEFAULT_SHAFT_WIDTH

    def __post_init__(self) -> None:
        def integer(name: str, low: int, high: int) -> None:
            value = check_integer(
                name, getattr(self, name), minimum=low, maximum=high, error=CoevolutionError
            )
            object.__setattr__(self, name, value)

        def probability(name: str, strict: bool = False) -> None:
            value = check_number(
                name,
                getattr(self, name),
                minimum=0,
                maximum=1,
                strict_minimum=strict,
                error=CoevolutionError,
            )
            object.__setattr__(self, name, value)

        integer("capacity", 1, 100_000)
        integer("batch", 1, 256)
        integer("edits", 1, 32)
        integer("validation", 1, 256)
        integer("validation_every", 1, 1_000_000)
        integer("validation_candidates", 1, 256)
        integer("min_size", MIN_SIZE, MAX_SIZE)
        integer("sign_styles", 0, MAX_TRAINING_STYLES)
        integer("sign_styles_seed", 0, SEED_RANGE - 1)
        if self.max_size is not None:
            integer("max_size", self.min_size, MAX_SIZE)
        for name in ("replay_probability", "staleness", "mutation_probability"):
            probability(name)
        probability("temperature", strict=True)
        if self.score not in SCORES:
            raise CoevolutionError(f"score {self.score!r} is not one of {', '.join(SCORES)}")
        if self.shapes is not None:
            object.__setattr__(self, "shapes", _checked_shapes(self.shapes))
            clash = [s for s in self.shapes if s in self.style_names]
            if clash:
                raise CoevolutionError(
                    f"shapes {clash!r} are among the {self.sign_styles} sign_styles the run"
                    " draws itself (list them once: leave them out of shapes)"
                )
        for name, check, default in (
            ("sign_styles_heads", check_heads, DEFAULT_HEADS),
            ("sign_styles_shaft_width", check_shaft_width, DEFAULT_SHAFT_WIDTH),
        ):
            try:
                value = check(getattr(self, name))
            except SignError as error:
                raise CoevolutionError(f"{name}: {error}") from None
            object.__setattr__(self, name, value)
            if value != default and not self.sign_styles:
                raise CoevolutionError(
                    f"{name} {list(value)!r} needs sign_styles > 0: no style is drawn"
                )
        if self.capacity < self.batch:
            raise CoevolutionError(
                f"capacity {self.capacity} is smaller than batch {self.batch}: a full"
                " population could never fill a batch of replayed mazes"
            )

    @classmethod
    def from_dict(cls, data: Mapping[str, Any] | None) -> MazePopulationConfig:
        """The options of a JSON object: missing keys take their defaults, unknown ones fail."""
        return options_from_dict(cls, data, "coevolution")

    def to_dict(self) -> dict[str, Any]:
        data = dataclasses.asdict(self)
        if self.shapes is not None:
            data["shapes"] = list(self.shapes)
        data["sign_styles_heads"] = list(self.sign_styles_heads)
        data["sign_styles_shaft_width"] = list(self.sign_styles_shaft_width)
        return data

    @property
    def style_names(self) -> tuple[str, ...]:
        """The shape names of the ``sign_styles`` arrow styles (``arrowv0`` ...)."""
        return tuple(f"{TRAINING_PREFIX}{i}" for i in range(self.sign_styles))

    @property
    def drawn_shapes(self) -> tuple[str, ...] | None:
        """The shapes fresh family mazes are drawn in: ``shapes``, then the drawn
        styles' names; ``None`` when neither is given (the target's own signs)."""
        if self.shapes is None and not self.sign_styles:
            return None
        return (*(self.shapes or ()), *self.style_names)


_Options = TypeVar("_Options")


def options_from_dict(cls: type[_Options], data: Mapping[str, Any] | None, what: str) -> _Options:
    """The dataclass ``cls`` of a JSON object's options; unknown keys raise, naming ``what``.

    Missing keys take their defaults; the values are checked by ``cls``.
    """
    data = dict(data or {})
    known = {f.name for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    unknown = sorted(set(data) - known)
    if unknown:
        named = ", ".join(f"{key!r}{closest(key, known)}" for key in unknown)
        raise CoevolutionError(
            f"unknown {what} option(s) {named} (known: {', '.join(sorted(known))})"
        )
    return cls(**data)


def _checked_shapes(shapes: object) -> tuple[str, ...]:
    """``shapes`` as a tuple of known sign shape names (at least one, no repeats)."""
    if isinstance(shapes, str) or not isinstance(shapes, Sequence) or not shapes:
        raise CoevolutionError(f"shapes {shapes!r} must be a non-empty list of sign shapes")
    checked = []
    for shape in shapes:
        try:
            checked.append(Sign(shape).shape)
        except SignError as error:
            raise CoevolutionError(f"shapes: {error}") from None
    if len(set(checked)) != len(checked):
        raise CoevolutionError(f"shapes {list(shapes)!r} names a shape twice")
    return tuple(checked)


# -- the population -------------------------------------------------------------------


@dataclass
class MazeRecord:
    """One maze that was ever a member (a row of ``mazes.csv``).

    ``origin`` is ``family`` (a fresh maze of the target's family) or
    ``mutant`` (of ``parent``, a record id); ``birth`` the generation it was
    first played and admitted at, ``retired`` the one it was replaced at
    (None while a member). ``score``, ``success_rate`` and ``normalized_reward``
    are those of the last generation that played it (the agent population's
    means over its 4 rotations), ``best_normalized_reward`` the best R̄ an
    agent ever had on it; ``plays`` counts the generations that played it.
    """

    id: int
    maze: str
    origin: str
    parent: int | None
    birth: int
    profile: DifficultyProfile
    difficulty: float
    score: float = 0.0
    success_rate: float = math.nan
    normalized_reward: float = math.nan
    best_normalized_reward: float = -math.inf
    plays: int = 0
    last_played: int = 0
    retired: int | None = None
    point: np.ndarray | None = field(default=None, repr=False, compare=False)

    def descriptor(self) -> np.ndarray:
        """The maze's point in the metric space (see the module docstring)."""
        if self.point is None:
            self.point = descriptor(self.maze, self.profile)
        return self.point

    def to_row(self) -> dict[str, Any]:
        """The record as a ``mazes.csv`` row."""
        return {
            "id": self.id,
            "maze": self.maze,
            "origin": self.origin,
            "parent": "" if self.parent is None else self.parent,
            "birth": self.birth,
            "retired": "" if self.retired is None else self.retired,
            "plays": self.plays,
            "last_played": self.last_played,
            "score": round(self.score, 6),
            "success_rate": round(self.success_rate, 6),
            "normalized_reward": round(self.normalized_reward, 6),
            "best_normalized_reward": round(self.best_normalized_reward, 6),
            "difficulty": round(self.difficulty, 4),
            **{k: round(float(v), 4) for k, v in self.profile.components().items()},
        }


#: The columns of ``mazes.csv``, in order.
MAZES_CSV_FIELDS = (
    "id maze origin parent birth retired plays last_played score success_rate normalized_reward"
    " best_normalized_reward"
    " difficulty path_length intersections lures traps surprisingness deceptiveness"
).split()


def descriptor(maze: str | MazeSpec, profile: DifficultyProfile) -> np.ndarray:
    """``(side, intersections, lures, traps, S, D)`` divided by :data:`DESCRIPTOR_SCALES`."""
    spec = maze if isinstance(maze, MazeSpec) else MazeSpec.from_string(maze)
    values = {"side": max(spec.width, spec.height), **profile.components()}
    return np.array([values[name] / scale for name, scale in DESCRIPTOR_SCALES.items()])


@dataclass
class MazePopulation:
    """The level buffer of the ``coevolution`` regime (see the module docstring).

    ``propose()`` gives the next generation's batch; ``update(batch,
    results)`` scores it, admits new mazes and advances the generation.
    """

    target: str
    config: MazePopulationConfig
    seed: int
    reserved: frozenset[int] = frozenset()
    records: list[MazeRecord] = field(default_factory=list)
    members: list[int] = field(default_factory=list)
    generation: int = 0
    rng: np.random.Generator = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.target = MazeSpec.from_string(self.target).to_string()
        self._steer(self.config)
        self.rng = np.random.default_rng(check_integer("seed", self.seed, minimum=0))
        self._generated: dict[str, list[Maze]] = {}

    def _steer(self, config: MazePopulationConfig) -> None:
        """Take ``config`` as the population's options, and the genome its sides give."""
        spec = MazeSpec.from_string(self.target)
        self.config = config
        self.max_size = config.max_size or max(spec.width, spec.height, config.min_size)
        self.genome = MazeGenome(min_size=config.min_size, max_size=self.max_size)

    def branch(
        self, config: MazePopulationConfig | None = None, seed: int | None = None
    ) -> MazePopulation:
        """A copy that goes on apart from this one, with ``config`` as its options if given.

        The copy has its own records, members and generator (``seed``'s, or a
        copy of this one's state); the generated mazes are shared (a maze's
        4 rotations are the same in every copy), so a branch compiles nothing
        again. EDEnS's alternatives are branches
        (:mod:`amaze.curriculum.population_selector`).
        """
        twin = copy.copy(self)  # through __getstate__, which leaves the cache out
        twin._generated = self._generated
        twin.records = copy.deepcopy(self.records)
        twin.members = list(self.members)
        twin.rng = copy.deepcopy(self.rng) if seed is None else np.random.default_rng(seed)
        if config is not None:
            twin._steer(config)
        return twin

    @classmethod
    def for_run(
        cls, target: str, config: MazePopulationConfig, run_seed: int, validation: Iterable[str]
    ) -> MazePopulation:
        """The population of a run: its own random stream, seeds apart from every held-out maze.

        The generator is seeded from ``run_seed`` on a stream of its own (the
        run's algorithm draws from others); fresh seeds avoid the evaluation
        suite's, the ``validation`` mazes' and the run's unseen mazes'
        (:func:`~amaze.curriculum.validation.unseen_mazes`).
        """
        held_out = [*validation, *unseen_mazes(target, run_seed)]
        seeds = {MazeSpec.from_string(maze).seed for maze in held_out}
        stream = np.random.SeedSequence([run_seed, _POPULATION_STREAM]).generate_state(1)[0]
        return cls(target, config, seed=int(stream), reserved=reserved_seeds() | seeds)

    # -- reading --------------------------------------------------------------------

    def member_records(self) -> list[MazeRecord]:
        """The current members, in the population's order."""
        return [self.records[i] for i in self.members]

    def replay_distribution(self) -> np.ndarray:
        """The probability of replaying each member now (in :attr:`members` order)."""
        members = self.member_records()
        return replay_distribution(
            [r.score for r in members],
            [r.last_played for r in members],
            self.generation,
            temperature=self.config.temperature,
            staleness=self.config.staleness,
        )

    def mean_difficulty(self) -> float:
        """Mean difficulty of the members (0 without members)."""
        members = self.member_records()
        return float(np.mean([r.difficulty for r in members])) if members else 0.0

    def diversity(self) -> float:
        """Mean distance between two members' descriptors (0 with fewer than two)."""
        points = np.array([r.descriptor() for r in self.member_records()])
        if len(points) < 2:
            return 0.0
        gaps = np.sqrt(((points[:, None, :] - points[None, :, :]) ** 2).sum(axis=-1))
        return float(gaps.sum() / (len(points) * (len(points) - 1)))

    # -- one generation ---------------------------------------------------------------

    def propose(self) -> list[BatchMaze]:
        """The mazes of the next generation: replayed members first, then new mazes."""
        c, rng = self.config, self.rng
        n_replay = 0
        if len(self.members) >= c.batch:
            n_replay = int(rng.binomial(c.batch, c.replay_probability))
        batch: list[BatchMaze] = []
        if n_replay:
            weights = self.replay_distribution()
            # a weight may underflow to 0 (huge populations, tiny temperatures)
            n_replay = min(n_replay, int(np.count_nonzero(weights)))
            chosen = rng.choice(len(self.members), size=n_replay, replace=False, p=weights)
            for index in chosen:
                record = self.records[self.members[int(index)]]
                batch.append(BatchMaze(record.maze, member=record.id))
        taken = {r.maze for r in self.member_records()} | {b.maze for b in batch}
        while len(batch) < c.batch:
            new = self._new_maze(taken)
            taken.add(new.maze)
            batch.append(new)
        return batch

    def update(self, batch: Sequence[BatchMaze], results: Sequence[MazeResult]) -> GenerationReport:
        """Score ``batch`` by ``results`` (one per maze), admit new mazes, advance a generation."""
        if len(batch) != len(results):
            raise CoevolutionError(f"{len(results)} results for a batch of {len(batch)} mazes")
        self.generation += 1
        now = self.generation
        report = GenerationReport()
        difficulties, scores = [], []
        for item, result in zip(batch, results, strict=True):
            if item.member is not None:
                record = self.records[item.member]
                self._score(record, result, now)
                report.replayed += 1
            else:
                report.new += 1
                profile = self.profile(item.maze)
                record = MazeRecord(
                    id=len(self.records),
                    maze=item.maze,
                    origin=item.origin,
                    parent=item.parent,
                    birth=now,
                    profile=profile,
                    difficulty=profile.score(),
                )
                self._score(record, result, now)
                full = len(self.members) >= self.config.capacity
                if result.solved and record.score > 0 and self._admit(record):
                    report.admitted += 1
                    report.retired += full
            difficulties.append(record.difficulty)
            scores.append(record.score)
        report.batch_difficulty = float(np.mean(difficulties)) if difficulties else 0.0
        report.batch_score = float(np.mean(scores)) if scores else 0.0
        return report

    def profile(self, maze: str) -> DifficultyProfile:
        """The difficulty profile of a maze (the same for its 4 rotations)."""
        return DifficultyProfile.of(self.generated(maze)[0])

    def generated(self, maze: str) -> list[Maze]:
        """The maze in its 4 rotations, generated once while it is a member or in a batch."""
        cache = self._generated
        if maze not in cache:
            if len(cache) > 2 * self.config.capacity + 2 * self.config.batch:
                # the oldest non-members go; the newest (this batch's new mazes) stay
                members = {r.maze for r in self.member_records()}
                stale = [m for m in cache if m not in members]
                for old in stale[: len(stale) - self.config.batch]:
                    del cache[old]
            cache[maze] = as_mazes(rotations(maze))
        return cache[maze]

    # -- inner workings ----------------------------------------------------------------

    def _score(self, record: MazeRecord, result: MazeResult, now: int) -> None:
        record.success_rate = result.success_rate
        record.normalized_reward = result.normalized_reward
        record.best_normalized_reward = max(
            record.best_normalized_reward, result.best_normalized_reward
        )
        if self.config.score == "learnability":
            record.score = result.success_rate * (1.0 - result.success_rate)
        else:
            record.score = record.best_normalized_reward - result.normalized_reward
        record.plays += 1
        record.last_played = now

    def _admit(self, record: MazeRecord) -> bool:
        """Add ``record`` (a new maze that met the minimal criterion) if there is room for it."""
        if len(self.members) < self.config.capacity:
            self.records.append(record)
            self.members.append(record.id)
            return True
        members = self.member_records()
        lowest = min(r.score for r in members)
        if record.score <= lowest:
            return False
        tied = [r for r in members if r.score == lowest]
        point = record.descriptor()
        victim = min(tied, key=lambda r: (float(np.linalg.norm(r.descriptor() - point)), r.id))
        victim.retired = record.birth
        self.records.append(record)
        self.members[self.members.index(victim.id)] = record.id
        return True

    def _new_maze(self, taken: set[str]) -> BatchMaze:
        """A mutant of a member (ACCEL) or a fresh family maze, not one of ``taken``.

        A mutant that is already taken, or whose seed is reserved, is drawn
        again (a few times, then a family maze is drawn until one is new).
        """
        c, rng = self.config, self.rng
        for _ in range(_REDRAWS):
            if self.members and rng.random() < c.mutation_probability:
                index = int(rng.choice(len(self.members), p=self.replay_distribution()))
                parent = self.records[self.members[index]]
                edits = int(rng.integers(1, c.edits + 1))
                spec = self.genome.mutate(MazeSpec.from_string(parent.maze), rng, n=edits)
                if spec.seed in self.reserved:
                    continue
                new = BatchMaze(spec.to_string(), parent=parent.id, origin="mutant")
            else:
                new = BatchMaze(self._family_maze(), origin="family")
            if new.maze not in taken:
                return new
        while True:
            new = BatchMaze(self._family_maze(), origin="family")
            if new.maze not in taken:
                return new

    def _family_maze(self) -> str:
        """The target's fields with a fresh seed and a side in ``[min_size, max_size]``."""
        spec = MazeSpec.from_string(self.target)
        side = int(self.rng.integers(self.config.min_size, self.max_size + 1))
        longest = max(spec.width, spec.height)
        width = max(MIN_SIZE, round(spec.width * side / longest))
        height = max(MIN_SIZE, round(spec.height * side / longest))
        while True:
            seed = int(self.rng.integers(SEED_RANGE))
            if seed not in self.reserved:
                break
        spec = dataclasses.replace(spec, width=width, height=height, seed=seed)
        shapes = self.config.drawn_shapes
        if shapes is not None:
            spec = spec.in_shape(shapes[int(self.rng.integers(len(shapes)))])
        return spec.to_string()

    def __getstate__(self) -> dict[str, Any]:
        state = dict(self.__dict__)
        state["_generated"] = {}  # a cache, rebuilt on demand
        return state


def mazes_csv(records: Iterable[MazeRecord]) -> str:
    """The text of ``mazes.csv``: a header of :data:`MAZES_CSV_FIELDS`, a row per record."""
    text = io.StringIO(newline="")
    writer = csv.DictWriter(text, fieldnames=MAZES_CSV_FIELDS)
    writer.writeheader()
    writer.writerows(record.to_row() for record in records)
    return text.getvalue()
