"""Can an agent read signs of a shape it never saw? The standard suite with each sign shape.

    python benchmarks/bench_sign_transfer.py AGENT.npz [AGENT.npz ...]
        [--shapes arrow star point ...] [--training-styles DIR] [--csv FILE]
        [--episodes FILE] [--outline-parts] [--bold]

plays each agent of a hybrid robot (``H15``...), trained on mazes whose signs are
arrows, on the standard suite (18 mazes x 4 rotations) with its signs redrawn
in each shape (same kinds, lightnesses and directions: ``C1`` becomes
``Cstar-1``, ``L.25`` becomes ``Lstar-.25``...), and runs the input-recognition
test with those signs (the paper's training maze's, as the protocol does).
Besides the built-in shapes, it draws the held-out arrow styles of
:mod:`amaze.maze.arrow_styles` (``chevron``: an open ">" of two strokes;
``harpoon``: a shaft with one barb; ``outline``: the hollow contour of a block
arrow), PNG images registered with :func:`amaze.register_custom_signs`.
``--training-styles DIR`` also registers a folder of training styles (``amaze
draw-signs OUT`` writes ``OUT/training``) and adds its first shapes to the default list.
It prints one row per shape: whether the shape can carry a direction at all
(:func:`~amaze.maze.arrow_styles.directional`), suite success, mean R̄ and input
recognition with its four classes; then the shapes that cannot carry a direction.
``--csv FILE`` also writes every agent's rows to one CSV file (a study's agents
side by side); ``--episodes FILE`` every suite episode (agent, shape, maze
played, its suite column, success, R̄): which mazes a shape is lost on.
``--outline-parts`` also draws the held-out ``outline`` taken apart
(:func:`~amaze.maze.arrow_styles.draw_outline`), never trained on either, and
adds them to the shapes: ``outlinefilled`` (the same polygon filled),
``outlinehead`` (its hollow head on a filled shaft), ``outlineshaft`` (its hollow
shaft under a filled head), ``outlinesmall`` (the outline at 0.7 of its
size) and ``outline95`` (at 0.95: its tail and tip all but off the sign's
outermost pixels, which even blocks of a pooled retina mix with the cell's
walls and arrival marker): which part of the drawing an agent cannot read. ``--bold`` adds
``harpoonbold`` and ``outlinebold``, the two drawn with strokes twice as wide
(``stroke``), never trained on: whether strokes narrower than a pixel of the
robot's sign, whose pixels are then dimmer than the drawing's lightness, are
what an agent misreads.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from collections.abc import Callable
from functools import partial
from pathlib import Path

from PIL import Image

from amaze.errors import AmazeError
from amaze.evaluation.inputs import enumerate_inputs, evaluate_inputs
from amaze.evaluation.protocol import INPUT_SIGNS_MAZE, Evaluator
from amaze.evaluation.suite import standard_suite
from amaze.maze.arrow_styles import (
    HELD_OUT_FOLDER,
    HELD_OUT_STYLES,
    directional,
    draw_harpoon,
    draw_outline,
    write_sign_styles,
)
from amaze.maze.signs import register_custom_signs
from amaze.maze.spec import MazeSpec
from amaze.runs.folder import write_rows
from evolution.agent_file import AgentFileError, load_agent

SHAPES = ("arrow", "rarrow", "star", "point", "warning", *HELD_OUT_STYLES)
#: How many shapes of a ``--training-styles`` folder join the default list.
TRAINING_SHAPES_LISTED = 3
#: ``--outline-parts``: the held-out outline taken apart, by shape name.
OUTLINE_PARTS: dict[str, Callable[[], Image.Image]] = {
    "outlinefilled": partial(draw_outline, hollow_head=False, hollow_shaft=False),
    "outlinehead": partial(draw_outline, hollow_shaft=False),
    "outlineshaft": partial(draw_outline, hollow_head=False),
    "outlinesmall": partial(draw_outline, scale=0.7),
    "outline95": partial(draw_outline, scale=0.95),
}
#: ``--bold``: the harpoon and the outline with strokes twice as wide, by shape name.
BOLD: dict[str, Callable[[], Image.Image]] = {
    "harpoonbold": partial(draw_harpoon, stroke=0.2),
    "outlinebold": partial(draw_outline, stroke=0.14),
}


def draw_held_out(folder: Path) -> list[str]:
    """Write the held-out arrow styles in ``folder`` (:func:`write_sign_styles`'s held-out
    group; its one training style is not registered) and register them."""
    write_sign_styles(folder, 1, 0)
    return register_custom_signs(folder / HELD_OUT_FOLDER)


def draw_variants(folder: Path, drawings: dict[str, Callable[[], Image.Image]]) -> list[str]:
    """Write ``drawings`` (:data:`OUTLINE_PARTS`, :data:`BOLD`) as PNG files in ``folder``
    and register them."""
    folder.mkdir()
    for name, draw in drawings.items():
        draw().save(folder / f"{name}.png")
    return register_custom_signs(folder)


def reshaped(maze: str, shape: str) -> str:
    """``maze`` with every sign type drawn in ``shape`` (same kind and lightness)."""
    return MazeSpec.from_string(maze).in_shape(shape).to_string()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "agents", type=Path, nargs="+", metavar="AGENT", help="agent files of a hybrid robot (.npz)"
    )
    parser.add_argument("--shapes", nargs="+", metavar="SHAPE", help=f"({' '.join(SHAPES)})")
    parser.add_argument(
        "--training-styles",
        type=Path,
        metavar="DIR",
        help="also register this folder of sign PNGs (amaze draw-signs OUT writes OUT/training)",
    )
    parser.add_argument("--csv", type=Path, metavar="FILE", help="also write the rows to FILE")
    parser.add_argument(
        "--episodes", type=Path, metavar="FILE", help="also write every suite episode to FILE"
    )
    parser.add_argument(
        "--outline-parts",
        action="store_true",
        help="also play the outline taken apart: filled, hollow head only, hollow shaft only,"
        " smaller",
    )
    parser.add_argument(
        "--bold",
        action="store_true",
        help="also play the harpoon and the outline drawn with strokes twice as wide",
    )
    args = parser.parse_args(argv)
    agents = []
    for path in args.agents:
        try:
            agent = load_agent(path)
        except (AgentFileError, OSError) as error:
            print(f"error: {error}", file=sys.stderr)
            return 2
        if agent.robot.discrete_inputs:
            robot = agent.robot.to_string()
            print(f"error: {path}: its robot {robot} sees no images: give an H robot",
                  file=sys.stderr)  # fmt: skip
            return 2
        agents.append((path, agent))
    for option, path in (("--csv", args.csv), ("--episodes", args.episodes)):
        if path is not None and not path.parent.is_dir():
            print(f"error: {option} {path}: folder {path.parent} does not exist", file=sys.stderr)
            return 2
    with tempfile.TemporaryDirectory() as folder:
        draw_held_out(Path(folder))
        shapes = list(SHAPES) if args.shapes is None else args.shapes
        for wanted, drawings, subfolder in (
            (args.outline_parts, OUTLINE_PARTS, "parts"),
            (args.bold, BOLD, "bold"),
        ):
            if wanted:
                drawn = draw_variants(Path(folder) / subfolder, drawings)
                shapes += [s for s in drawn if s not in shapes]
        try:
            if args.training_styles is not None:
                trained = register_custom_signs(args.training_styles)
                listed = ", ".join(trained[:TRAINING_SHAPES_LISTED])
                more = len(trained) - TRAINING_SHAPES_LISTED
                print(f"training styles of {args.training_styles}: {len(trained)} shapes ({listed}"
                      + (f" and {more} more)" if more > 0 else ")"))  # fmt: skip
                if args.shapes is None:
                    shapes[1:1] = trained[:TRAINING_SHAPES_LISTED]
            directions = {shape: directional(shape) for shape in shapes}
        except AmazeError as error:
            print(f"error: {error}", file=sys.stderr)
            return 2
        rows, episodes = [], []
        for path, agent in agents:
            rows += _rows(path, agent, shapes, directions, episodes)
        if args.csv is not None:
            write_rows(args.csv, rows)
            print(f"rows written to {args.csv}")
        if args.episodes is not None:
            write_rows(args.episodes, episodes)
            print(f"episodes written to {args.episodes}")
        blind = [shape for shape in shapes if not directions[shape]]
        if blind:
            print(
                f"cannot carry a direction (its four orientations look alike; leave it out of"
                f" any training target): {', '.join(blind)}"
            )
    return 0


CLASSES = ("clue", "trap", "lure", "empty")


def _rows(
    path: Path, agent, shapes: list[str], directions: dict[str, bool], episodes: list[dict]
) -> list[dict]:
    """Print and return the rows of one agent: the suite and the input test in each shape.

    Its suite episodes are appended to ``episodes``, one row each."""
    robot = agent.robot.to_string()
    suite = standard_suite().maze_strings(rotations=True)
    print(f"agent {path} ({robot}), standard suite (18 mazes x 4 rotations) per shape")
    print("shape      directional  success   mean R̄   inputs  (clue  trap  lure  empty)")
    rows = []
    for shape in shapes:
        mazes = [reshaped(maze, shape) for maze in suite]
        report = Evaluator(robot, mazes, inputs=False).evaluate(agent)
        episodes += [
            {"agent": str(path), "shape": shape, "maze": e.maze, "column": e.column,
             "success": e.success, "normalized_reward": e.normalized_reward}
            for e in report.episodes
        ]  # fmt: skip
        spec = MazeSpec.from_string(reshaped(INPUT_SIGNS_MAZE, shape))
        inputs = enumerate_inputs(robot, spec.clue, spec.lure, spec.trap)
        recognition = evaluate_inputs(agent, inputs)
        rates = {name: recognition.rates.get(name, float("nan")) for name in CLASSES}
        classes = "  ".join(f"{rate:.2f}" for rate in rates.values())
        print(
            f"{shape:<10} {'yes' if directions[shape] else 'no':<11}"
            f" {report.success_rate:7.3f}  {report.normalized_reward:+7.3f}"
            f"  {recognition.overall:6.3f}  ({classes})"
        )
        rows.append({
            "agent": str(path), "shape": shape, "directional": directions[shape],
            "success_rate": report.success_rate, "normalized_reward": report.normalized_reward,
            "input_recognition": recognition.overall,
            **{f"input_recognition_{name}": rate for name, rate in rates.items()},
        })  # fmt: skip
    return rows


if __name__ == "__main__":
    sys.exit(main())
