"""The standard evaluation suite: 18 mazes in 6 columns x 3 rows, each in its 4 rotations.

In the spirit of the paper's generalisation mazes (its Figure "Mazes used for
generalization evaluation"), every agent of this project is scored on the same
fixed set of 20x20 mazes:

=========  =====================================  =====================
column     maze family (seeds vary)               kept when
=========  =====================================  =====================
trivial    ``20x20_U``                            always
simple     ``20x20_C1``                           always
lures      ``20x20_C1_l.25_L.25``                 always
1 trap     ``20x20_C1_l.25_L.25_t.1_T.5``         exactly 1 trap
3 traps    ``20x20_C1_l.25_L.25_t.25_T.5``        exactly 3 traps
16 traps   ``20x20_C1_l.25_L.25_t.75_T.5``        exactly 16 traps
=========  =====================================  =====================

The paper's last three columns ("1 Trap", "3 Traps", "16 Traps") are read as
trap counts: a maze string cannot fix that number (it is ``round(t *
intersections)``), so a trap column keeps the mazes of its family with
exactly that many traps, ``t`` chosen so that they are common. For each
column, a seeded sample of 10000 distinct mazes is drawn (seeds from a
``numpy`` generator with the column's own seed), and the three rows are the
mazes of minimal, median and maximal Surprisingness ``S`` (ties broken by the
smaller seed; the median is the element of rank 5000 of the sorted sample).
Every maze is played in its four rotations: 72 episodes.

The suite ships with the package (``amaze/data/evaluation_suite.json``),
written by ``python tools/make_evaluation_suite.py``; the tests check it
against this definition. The paper's direct-training pair is kept alongside:
:data:`PAPER_TRAINING_MAZE` and :data:`PAPER_EVALUATION_MAZE`. The paper's own
suite (:mod:`amaze.evaluation.paper_suite`) is :func:`paper_suite`, a
:class:`PaperSuite` the protocol plays as it plays this one; run summaries
and reports use the standard suite (``docs/evaluation.md``).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from typing import Any

import numpy as np

from amaze.errors import AmazeError
from amaze.maze import rotations
from amaze.maze.maze import Maze
from amaze.maze.metrics import surprisingness
from amaze.maze.signs import SignKind

__all__ = [
    "COLUMNS",
    "PAPER_EVALUATION_MAZE",
    "PAPER_TRAINING_MAZE",
    "ROWS",
    "SAMPLE_SIZE",
    "EvaluationSuite",
    "PaperSuite",
    "PaperSuiteMaze",
    "SuiteColumn",
    "SuiteMaze",
    "build_suite",
    "paper_suite",
    "standard_suite",
]

#: The paper's direct-training maze and its evaluation counterpart (same family, other seed).
PAPER_TRAINING_MAZE = "M2000007_20x20_C1_l.25_L.25_t.5_T.5"
PAPER_EVALUATION_MAZE = "M2000018_20x20_C1_l.25_L.25_t.5_T.5"

#: Mazes sampled per column.
SAMPLE_SIZE = 10000
#: The rows of the suite: minimal, median and maximal Surprisingness of the sample.
ROWS: tuple[str, ...] = ("min", "median", "max")
#: Seeds are drawn in [0, SEED_RANGE).
SEED_RANGE = 2**31
#: Candidate seeds drawn at a time while filling a column.
_BATCH = 2048

_DATA_FILE = "evaluation_suite.json"
_PAPER_DATA_FILE = "paper_suite.json"


@dataclass(frozen=True)
class SuiteColumn:
    """One column: a maze family, an optional exact trap count, and its sampling seed."""

    name: str
    family: str
    traps: int | None
    sample_seed: int

    def maze_string(self, seed: int) -> str:
        return f"M{seed}_{self.family}"

    def accepts(self, maze: Maze) -> bool:
        """Whether a maze of the family belongs to the column (its trap count, if fixed)."""
        if self.traps is None:
            return True
        return sum(1 for placed in maze.signs if placed.kind is SignKind.TRAP) == self.traps


COLUMNS: tuple[SuiteColumn, ...] = (
    SuiteColumn("trivial", "20x20_U", None, 1),
    SuiteColumn("simple", "20x20_C1", None, 2),
    SuiteColumn("lures", "20x20_C1_l.25_L.25", None, 3),
    SuiteColumn("1 trap", "20x20_C1_l.25_L.25_t.1_T.5", 1, 4),
    SuiteColumn("3 traps", "20x20_C1_l.25_L.25_t.25_T.5", 3, 5),
    SuiteColumn("16 traps", "20x20_C1_l.25_L.25_t.75_T.5", 16, 6),
)


@dataclass(frozen=True)
class SuiteMaze:
    """One maze of the suite (in its base orientation, start in the south-west corner)."""

    column: str
    row: str
    string: str
    surprisingness: float

    def rotations(self) -> list[str]:
        """The maze string started from each corner (NW, NE, SW, SE), by :func:`rotations`."""
        return rotations(self.string)


@dataclass(frozen=True)
class EvaluationSuite:
    """The suite's mazes, in column-major order (column by column, rows min, median, max)."""

    mazes: tuple[SuiteMaze, ...]
    sample_size: int

    def __len__(self) -> int:
        return len(self.mazes)

    def episodes(self) -> list[tuple[SuiteMaze, str]]:
        """Every (suite maze, rotated maze string) pair evaluated: 4 per maze."""
        return [(maze, rotated) for maze in self.mazes for rotated in maze.rotations()]

    def maze_strings(self, rotations: bool = True) -> list[str]:
        """The strings of all mazes (with their rotations by default: 72 strings)."""
        if rotations:
            return [rotated for _, rotated in self.episodes()]
        return [maze.string for maze in self.mazes]

    def to_dict(self) -> dict[str, Any]:
        return {
            "sample_size": self.sample_size,
            "columns": [
                {"name": c.name, "family": c.family, "traps": c.traps, "sample_seed": c.sample_seed}
                for c in COLUMNS
            ],
            "mazes": [
                {
                    "column": m.column,
                    "row": m.row,
                    "string": m.string,
                    "surprisingness": m.surprisingness,
                }
                for m in self.mazes
            ],
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> EvaluationSuite:
        try:
            mazes = tuple(
                SuiteMaze(m["column"], m["row"], m["string"], float(m["surprisingness"]))
                for m in data["mazes"]
            )
            return cls(mazes=mazes, sample_size=int(data["sample_size"]))
        except (KeyError, TypeError, ValueError) as error:
            raise AmazeError(f"not an evaluation suite description: {error!r}") from None


def _candidate_seeds(column: SuiteColumn) -> Iterable[int]:
    """The column's stream of distinct candidate seeds."""
    rng = np.random.default_rng(column.sample_seed)
    seen: set[int] = set()
    while True:
        for seed in rng.integers(0, SEED_RANGE, size=_BATCH).tolist():
            if seed not in seen:
                seen.add(seed)
                yield seed


def _score(column: SuiteColumn, seeds: Sequence[int]) -> list[float | None]:
    """Surprisingness of each candidate maze, None where the column rejects it."""
    scores: list[float | None] = []
    for seed in seeds:
        maze = Maze.from_string(column.maze_string(seed))
        scores.append(surprisingness(maze) if column.accepts(maze) else None)
    return scores


Mapper = Callable[[Callable[..., Any], Iterable[Any]], Iterable[Any]]


def sample_column(
    column: SuiteColumn, sample_size: int = SAMPLE_SIZE, map_fn: Mapper | None = None
) -> list[tuple[int, float]]:
    """The column's sample: ``(seed, S)`` of the first ``sample_size`` accepted mazes.

    ``map_fn`` (for example a process pool's ``map``) may score batches of
    candidates in parallel; the result does not depend on it.
    """
    if sample_size < 1:
        raise AmazeError(f"sample_size must be positive, got {sample_size}")
    mapper = map_fn or map
    stream = iter(_candidate_seeds(column))
    sample: list[tuple[int, float]] = []
    chunk = 256
    while len(sample) < sample_size:
        missing = sample_size - len(sample)
        n_chunks = max(1, min(8, missing // chunk + 1))
        chunks = [[next(stream) for _ in range(chunk)] for _ in range(n_chunks)]
        for seeds, scores in zip(
            chunks, mapper(_score, [column] * len(chunks), chunks), strict=True
        ):
            for seed, score in zip(seeds, scores, strict=True):
                if score is not None and len(sample) < sample_size:
                    sample.append((seed, score))
    return sample


def select_rows(column: SuiteColumn, sample: Sequence[tuple[int, float]]) -> list[SuiteMaze]:
    """The mazes of minimal, median and maximal S in a sample (ties: smaller seed first)."""
    ranked = sorted(sample, key=lambda item: (item[1], item[0]))
    picks = (ranked[0], ranked[len(ranked) // 2], ranked[-1])
    return [
        SuiteMaze(column.name, row, column.maze_string(seed), score)
        for row, (seed, score) in zip(ROWS, picks, strict=True)
    ]


def build_suite(sample_size: int = SAMPLE_SIZE, map_fn: Mapper | None = None) -> EvaluationSuite:
    """Build the suite from its definition (about a minute on 2 cores at the full sample size)."""
    mazes: list[SuiteMaze] = []
    for column in COLUMNS:
        mazes.extend(select_rows(column, sample_column(column, sample_size, map_fn)))
    return EvaluationSuite(mazes=tuple(mazes), sample_size=sample_size)


@lru_cache(maxsize=1)
def standard_suite() -> EvaluationSuite:
    """The shipped standard evaluation suite (built by ``tools/make_evaluation_suite.py``)."""
    text = resources.files("amaze").joinpath("data", _DATA_FILE).read_text(encoding="utf-8")
    return EvaluationSuite.from_dict(json.loads(text))


@dataclass(frozen=True)
class PaperSuiteMaze(SuiteMaze):
    """A maze of the paper's suite: ``surprisingness`` is S in bits, as in the standard suite.

    ``script_entropy`` is the score the paper's script ranked it by (its solution-path
    entropy, in nats: :func:`amaze.evaluation.paper_suite.script_entropy`); ``traps``
    its number of traps.
    """

    script_entropy: float
    traps: int


@dataclass(frozen=True)
class PaperSuite(EvaluationSuite):
    """The paper's evaluation suite: 18 mazes in the paper's 6 columns x 3 rows.

    ``seed_offset`` and ``sample_size``: the script scored the mazes of seeds
    ``seed_offset + j`` for ``j < sample_size`` of each family in ``families``
    (``(name, family)`` pairs, the family without its seed).
    """

    seed_offset: int = 0
    families: tuple[tuple[str, str], ...] = ()

    def to_dict(self) -> dict[str, Any]:
        return {
            "seed_offset": self.seed_offset,
            "sample_size": self.sample_size,
            "families": [{"name": name, "family": family} for name, family in self.families],
            "mazes": [
                {
                    "column": m.column,
                    "row": m.row,
                    "string": m.string,
                    "surprisingness": m.surprisingness,
                    "script_entropy": m.script_entropy,
                    "traps": m.traps,
                }
                for m in self.mazes
            ],
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> PaperSuite:
        try:
            mazes = tuple(
                PaperSuiteMaze(
                    m["column"],
                    m["row"],
                    m["string"],
                    float(m["surprisingness"]),
                    float(m["script_entropy"]),
                    int(m["traps"]),
                )
                for m in data["mazes"]
            )
            families = tuple((str(f["name"]), str(f["family"])) for f in data["families"])
            return cls(
                mazes=mazes,
                sample_size=int(data["sample_size"]),
                seed_offset=int(data["seed_offset"]),
                families=families,
            )
        except (KeyError, TypeError, ValueError) as error:
            raise AmazeError(f"not a paper suite description: {error!r}") from None


@lru_cache(maxsize=1)
def paper_suite() -> PaperSuite:
    """The shipped paper's evaluation suite (built by ``tools/make_paper_suite.py``)."""
    text = resources.files("amaze").joinpath("data", _PAPER_DATA_FILE).read_text(encoding="utf-8")
    return PaperSuite.from_dict(json.loads(text))
