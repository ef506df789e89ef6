"""The paper's evaluation suite, built as the paper's evaluation script built it.

The AMaze paper's RL results (its Table 3) were scored on 18 mazes chosen by
its evaluation script, ``src/amaze/bin/sb3/eval.py`` of the reference
repository (kgd-al/amaze), function ``_generate_mazes``, at commit c4feded.
The script:

1. generates, for each of four families (``U``, ``C1``, ``C1_l.25_L.25``,
   ``C1_l.25_L.25_t.5_T.5``), the 20x20 mazes of seeds ``1,000,000 + j`` for
   ``j < 10,000``, and scores each by the entropy of the inputs along its
   solution path, in nats (:func:`script_entropy`);
2. for the first three families (columns trivial, simple, lures), keeps the
   mazes nearest the quantiles 0, 0.5 and 1 of the scores
   (:func:`nearest_quantiles`);
3. for the trap family, rounds the quantiles 0, 0.5 and 1 of the pooled
   (trap count, score) table of the counts that at least 3 mazes have to trap
   counts ``t``, one column each, whose rows are the mazes of ``t`` traps
   nearest the quantiles of their scores (:func:`trap_columns`): 1, 3 and 16
   traps, the paper's "1 Trap", "3 Traps" and "16 Traps".

Quantiles are numpy's default (linear interpolation) and the nearest maze is
the first in seed order among equally near ones, as the script's ``argmin``.
The scores are summed term by term as the script sums them, with the
commit's trap directions at four-way crossings (:func:`script_trap_direction`):
several picks are ties that rounding or the unit would change
(``docs/evaluation.md``, "The paper's evaluation suite").

Scoring the 40,000 mazes takes about 12 s on one core, so the result ships
with the package (``amaze/data/paper_suite.json``, loaded by
:func:`amaze.evaluation.suite.paper_suite`), written by
``python tools/make_paper_suite.py``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from typing import Any

import numpy as np

from amaze.errors import AmazeError
from amaze.evaluation.suite import ROWS, PaperSuite, PaperSuiteMaze
from amaze.maze.directions import Direction, direction_between
from amaze.maze.maze import Maze
from amaze.maze.metrics import surprisingness
from amaze.maze.signs import PlacedSign

__all__ = [
    "PAPER_FAMILIES",
    "PAPER_SAMPLE_SIZE",
    "PAPER_SEED_OFFSET",
    "build_paper_suite",
    "family_maze",
    "nearest_quantiles",
    "sample_family",
    "score_mazes",
    "script_entropy",
    "script_trap_direction",
    "trap_columns",
]

#: The script's seeds are ``PAPER_SEED_OFFSET + j``, ``j < PAPER_SAMPLE_SIZE``.
PAPER_SEED_OFFSET = 1_000_000
PAPER_SAMPLE_SIZE = 10_000
#: The script's families, in its order: (column name, maze string without its seed).
#: The last one gives the three trap columns.
PAPER_FAMILIES: tuple[tuple[str, str], ...] = (
    ("trivial", "20x20_U"),
    ("simple", "20x20_C1"),
    ("lures", "20x20_C1_l.25_L.25"),
    ("traps", "20x20_C1_l.25_L.25_t.5_T.5"),
)
#: The script keeps a trap count only if at least this many mazes have it.
MIN_MAZES_PER_TRAP_COUNT = 3
_QUANTILES = (0.0, 0.5, 1.0)
_CHUNK = 500

Mapper = Callable[[Callable[..., Any], Iterable[Any]], Iterable[Any]]


def family_maze(family: str, j: int) -> str:
    """The script's maze string of sample ``j`` of ``family`` (its ``make_maze``)."""
    return f"M{j + PAPER_SEED_OFFSET}_{family}"


# -- the script's score ---------------------------------------------------------------------------


def script_trap_direction(maze: Maze, trap: PlacedSign) -> Direction:
    """Where the trap points at c4feded: the first open side (E, N, W, S) not correct nor back."""
    cell = trap.cell
    back = direction_between(cell, maze.solution[trap.solution_index - 1])
    for direction in Direction:
        if direction not in (trap.truth, back) and not maze.walls[cell][direction]:
            return direction
    raise AmazeError(f"{maze.to_string()}: no side for the trap at {cell}")


def script_entropy(maze: Maze) -> float:
    """The script's score of a maze: entropy (nats) of the inputs along its solution path.

    The inputs are the discrete ones (walls; the side the agent came from, not
    at the start; the sign's lightness in the slot it points to), with the
    traps pointing as at c4feded (:func:`script_trap_direction`). The sum runs
    over the distinct inputs in the order of their first appearance, as the
    script's ``__entropy_bits`` does.
    """
    path = np.array(maze.solution, dtype=np.int64)
    cols, rows = path[:, 0], path[:, 1]
    keys = maze.walls[cols, rows].astype(np.int64) @ np.array([2, 6, 18, 54], dtype=np.int64)
    steps = path[:-1] - path[1:]  # from each cell back to the one before it
    back = np.where(steps[:, 0] != 0, 1 - steps[:, 0], 2 - steps[:, 1])  # E=0, N=1, W=2, S=3
    keys[1:] += 3**back
    direction = maze.cell_signs.direction[cols, rows].astype(np.int64)
    for trap in maze.traps:
        direction[trap.solution_index] = int(script_trap_direction(maze, trap))
    value = maze.cell_signs.value[cols, rows]
    signed = direction >= 0
    values = np.unique(value[signed])
    sign = np.zeros(len(path), dtype=np.int64)
    sign[signed] = 1 + direction[signed] * len(values) + np.searchsorted(values, value[signed])
    keys = keys * (4 * len(values) + 1) + sign
    _, first, counts = np.unique(keys, return_index=True, return_counts=True)
    total = len(keys)
    entropy = 0.0
    for n in counts[np.argsort(first)].tolist():
        p = n / total
        entropy += -p * math.log(p)
    return entropy


def score_mazes(family: str, samples: Sequence[int]) -> tuple[list[float], list[int]]:
    """The script's score and the trap count of samples ``j`` of ``family``."""
    scores, traps = [], []
    for j in samples:
        maze = Maze.from_string(family_maze(family, j))
        scores.append(script_entropy(maze))
        traps.append(len(maze.traps))
    return scores, traps


def sample_family(
    family: str, sample_size: int = PAPER_SAMPLE_SIZE, map_fn: Mapper | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Scores (float64) and trap counts (int64) of samples ``0 .. sample_size - 1`` of ``family``.

    ``map_fn`` (a process pool's ``map``, say) may score chunks in parallel; the
    result does not depend on it.
    """
    if not isinstance(sample_size, int) or sample_size < 1:
        raise AmazeError(f"sample_size must be a positive integer, got {sample_size!r}")
    chunks = [range(k, min(k + _CHUNK, sample_size)) for k in range(0, sample_size, _CHUNK)]
    scores: list[float] = []
    traps: list[int] = []
    for chunk_scores, chunk_traps in (map_fn or map)(score_mazes, [family] * len(chunks), chunks):
        scores.extend(chunk_scores)
        traps.extend(chunk_traps)
    return np.array(scores, dtype=np.float64), np.array(traps, dtype=np.int64)


# -- the script's choice --------------------------------------------------------------------------


def nearest_quantiles(scores: Sequence[float]) -> list[int]:
    """The script's ``arg_quantiles``: for the quantiles 0, 0.5, 1, the index of the nearest score.

    ``np.quantile`` with linear interpolation; among equally near scores, the first.
    """
    data = np.asarray(scores, dtype=np.float64)
    if not data.size:
        raise AmazeError("no score to take quantiles of")
    return [int(np.abs(data - q).argmin()) for q in np.quantile(data, _QUANTILES)]


def trap_columns(scores: Sequence[float], traps: Sequence[int]) -> list[tuple[int, list[int]]]:
    """The script's trap columns: ``(t, [min, median, max sample])`` for each of its 3 counts.

    The counts kept are those of at least :data:`MIN_MAZES_PER_TRAP_COUNT`
    samples (and above 0); ``t`` is the rounded quantile (0, 0.5, 1) of their
    (count, score) table flattened; the rows are :func:`nearest_quantiles` of
    the scores of the samples with ``t`` traps, in sample order.
    """
    by_count: dict[int, list[int]] = {}
    for j, count in enumerate(traps):
        by_count.setdefault(int(count), []).append(j)
    table = [
        (count, j)
        for count, samples in by_count.items()
        if len(samples) >= MIN_MAZES_PER_TRAP_COUNT and count > 0
        for j in samples
    ]
    if not table:
        raise AmazeError("no trap count is common enough for the trap columns")
    pooled = np.array([[count, scores[j]] for count, j in table], dtype=np.float64).ravel()
    columns = []
    for quantile in np.quantile(pooled, _QUANTILES):
        t = round(float(quantile))
        samples = [j for count, j in table if count == t]
        if not samples:
            raise AmazeError(f"the trap quantile {quantile} rounds to {t} traps, which no maze has")
        picks = nearest_quantiles([scores[j] for j in samples])
        columns.append((t, [samples[k] for k in picks]))
    return columns


def _trap_column_name(t: int) -> str:
    return f"{t} trap" if t == 1 else f"{t} traps"


def build_paper_suite(
    sample_size: int = PAPER_SAMPLE_SIZE, map_fn: Mapper | None = None
) -> PaperSuite:
    """The paper's suite from the first ``sample_size`` samples of each family (see the module)."""
    picked: list[tuple[str, str, int, float, int]] = []  # column, family, j, score, traps
    *plain, (_, trap_family) = PAPER_FAMILIES
    for name, family in plain:
        scores, traps = sample_family(family, sample_size, map_fn)
        picked += [(name, family, j, scores[j], traps[j]) for j in nearest_quantiles(scores)]
    scores, traps = sample_family(trap_family, sample_size, map_fn)
    for t, samples in trap_columns(scores, traps):
        picked += [(_trap_column_name(t), trap_family, j, scores[j], t) for j in samples]
    mazes = []
    for index, (column, family, j, score, count) in enumerate(picked):
        string = family_maze(family, j)
        exact = surprisingness(Maze.from_string(string))
        row = ROWS[index % len(ROWS)]
        mazes.append(PaperSuiteMaze(column, row, string, exact, float(score), int(count)))
    return PaperSuite(
        mazes=tuple(mazes),
        sample_size=sample_size,
        seed_offset=PAPER_SEED_OFFSET,
        families=PAPER_FAMILIES,
    )
