"""The main job on built-in defaults (``make demo``).

For now it shows the maze core: it generates a few mazes of each class (trivial,
simple, lures, traps, complex) and the paper's direct-training and evaluation
mazes, renders them to PNG, prints their statistics and metrics, and writes the
table as CSV. Outputs go to ``demo_output/`` (or ``--out DIR``).
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from pathlib import Path

from amaze.description import STATS_COLUMNS, format_table, stats_rows
from amaze.maze import Maze
from amaze.render import render_mazes_grid, save_maze_png

#: Maze strings per class; seeds are fixed so the demo is reproducible.
CLASS_EXAMPLES: dict[str, list[str]] = {
    "trivial": [f"M{seed}_10x10_U" for seed in (1, 2, 3)],
    "simple": [f"M{seed}_10x10_C1" for seed in (1, 2, 3)],
    "lures": [f"M{seed}_10x10_C1_l.25_L.25" for seed in (1, 2, 3)],
    "traps": [f"M{seed}_10x10_C1_t.5_T.5" for seed in (1, 2, 3)],
    "complex": [f"M{seed}_10x10_C1_l.25_L.25_t.5_T.5" for seed in (1, 2, 3)],
    "paper": [
        "M2000007_20x20_C1_l.25_L.25_t.5_T.5",  # the paper's direct-training maze
        "M2000018_20x20_C1_l.25_L.25_t.5_T.5",  # and its evaluation maze
    ],
}


def run(out: Path) -> Path:
    """Render and measure the example mazes into ``out``; returns the CSV path."""
    started = time.perf_counter()
    maze_dir = out / "mazes"
    maze_dir.mkdir(parents=True, exist_ok=True)
    mazes: list[Maze] = []
    for group, strings in CLASS_EXAMPLES.items():
        for text in strings:
            maze = Maze.from_string(text)
            if group != "paper" and maze.maze_class.label != group:
                raise RuntimeError(f"{text} is {maze.maze_class.label}, expected {group}")
            mazes.append(maze)
            save_maze_png(maze, maze_dir / f"{group}_{maze.to_string()}.png")
            save_maze_png(maze, maze_dir / f"{group}_{maze.to_string()}_dark.png", theme="dark")
    render_mazes_grid(mazes[:-2], columns=3).save(out / "classes.png")

    rows = list(stats_rows(mazes))
    print(format_table(rows))
    table = out / "mazes.csv"
    with table.open("w", newline="") as stream:
        writer = csv.DictWriter(stream, fieldnames=STATS_COLUMNS)
        writer.writeheader()
        writer.writerows(rows)

    print(f"\n{len(mazes)} mazes in {time.perf_counter() - started:.1f} s")
    print(f"outputs in {out.resolve()}/:")
    print("  classes.png          overview: three mazes of each class (rows)")
    print("  mazes/*.png          every maze, light and dark themes")
    print("  mazes.csv            the table above")
    return table


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default="demo_output", help="output folder (default demo_output)")
    args = parser.parse_args(argv)
    run(Path(args.out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
