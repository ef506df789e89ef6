"""Machine- and human-readable descriptions of a maze.

:func:`describe` returns the record printed by ``amaze inspect --json`` (one
JSON object per maze, a contract other tools rely on: exactly these keys);
:func:`summary` is the readable form printed without ``--json``.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from typing import Any

from amaze.maze.maze import Maze
from amaze.maze.metrics import compute_metrics

#: The keys of an ``amaze inspect --json`` record, in order.
INSPECT_KEYS = (
    "string",
    "width",
    "height",
    "start",
    "end",
    "solution",
    "walls",
    "intersections",
    "signs",
    "class",
    "metrics",
)


def describe(maze: Maze) -> dict[str, Any]:
    """The ``amaze inspect --json`` record of ``maze`` (plain JSON types)."""
    metrics = compute_metrics(maze)
    return {
        "string": maze.to_string(),
        "width": maze.width,
        "height": maze.height,
        "start": list(maze.start),
        "end": list(maze.end),
        "solution": [list(cell) for cell in maze.solution],
        "walls": maze.walls.astype(int).tolist(),
        "intersections": maze.n_intersections,
        "signs": [placed.to_dict() for placed in maze.signs],
        "class": maze.maze_class.label,
        "metrics": {
            "surprisingness": metrics.surprisingness,
            "surprisingness_all": metrics.surprisingness_all,
            "deceptiveness": metrics.deceptiveness,
        },
    }


def summary(maze: Maze) -> str:
    """A few readable lines: size, path, signs, class and metrics."""
    metrics = compute_metrics(maze)
    stats = maze.stats()
    lines = [
        maze.to_string(),
        f"  size {maze.width}x{maze.height}, start {maze.start}, goal {maze.end}",
        f"  path {stats['path']} cells, {stats['intersections']} intersections",
        f"  signs: {stats['clues']} clues, {stats['lures']} lures, {stats['traps']} traps",
        f"  class: {maze.maze_class.label}",
        f"  surprisingness {metrics.surprisingness:.4f}"
        f" (all cells {metrics.surprisingness_all:.4f})",
        f"  deceptiveness {metrics.deceptiveness:.4f}"
        f" (rotation-invariant, paper definition: {metrics.invariant_deceptiveness:.4f})",
    ]
    return "\n".join(lines)


STATS_COLUMNS = (
    "string",
    "width",
    "height",
    "path",
    "intersections",
    "clues",
    "lures",
    "traps",
    "class",
    "surprisingness",
    "surprisingness_all",
    "deceptiveness",
    "invariant_deceptiveness",
    "inseparability",
)


def stats_rows(mazes: Iterable) -> Iterator[dict[str, object]]:
    """One row of statistics and metrics per maze (the columns of ``amaze stats``)."""
    for maze in mazes:
        stats = maze.stats()
        metrics = compute_metrics(maze)
        yield {
            "string": maze.to_string(),
            "width": maze.width,
            "height": maze.height,
            "path": stats["path"],
            "intersections": stats["intersections"],
            "clues": stats["clues"],
            "lures": stats["lures"],
            "traps": stats["traps"],
            "class": maze.maze_class.label,
            "surprisingness": metrics.surprisingness,
            "surprisingness_all": metrics.surprisingness_all,
            "deceptiveness": metrics.deceptiveness,
            "invariant_deceptiveness": metrics.invariant_deceptiveness,
            "inseparability": metrics.inseparability,
        }


def format_table(rows: list[dict[str, object]]) -> str:
    """The rows of :func:`stats_rows` as an aligned text table."""

    def cell(value: object) -> str:
        return f"{value:.4f}" if isinstance(value, float) else str(value)

    headers = {
        "surprisingness": "S",
        "surprisingness_all": "S_all",
        "deceptiveness": "D",
        "invariant_deceptiveness": "D_inv",
        "inseparability": "I",
        "intersections": "inter",
    }
    table = [[headers.get(c, c) for c in STATS_COLUMNS]]
    table += [[cell(row[c]) for c in STATS_COLUMNS] for row in rows]
    widths = [max(len(line[k]) for line in table) for k in range(len(STATS_COLUMNS))]
    lines = []
    for line in table:
        parts = [
            text.ljust(width) if k == 0 or text.isalpha() else text.rjust(width)
            for k, (text, width) in enumerate(zip(line, widths, strict=True))
        ]
        lines.append("  ".join(parts).rstrip())
    return "\n".join(lines)
