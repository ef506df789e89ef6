"""Can an agent read signs of a shape it never saw? The standard suite with each sign shape.

    python benchmarks/bench_sign_transfer.py AGENT.npz [--shapes arrow star point ...]

plays an agent of a hybrid robot (``H15``...), trained on mazes whose signs are
arrows, on the standard suite (18 mazes x 4 rotations) with its signs redrawn
in each shape (same kinds, lightnesses and directions: ``C1`` becomes
``Cstar-1``, ``L.25`` becomes ``Lstar-.25``...), and runs the input-recognition
test with those signs (the paper's training maze's, as the protocol does).
Besides the built-in shapes, it draws one of its own (``chevron``: an open
">" of two strokes, a PNG registered with :func:`amaze.register_custom_signs`).
It prints one row per shape: suite success, mean R̄ and input recognition with its
four classes.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

from PIL import Image, ImageDraw

from amaze.evaluation.inputs import enumerate_inputs, evaluate_inputs
from amaze.evaluation.protocol import INPUT_SIGNS_MAZE, Evaluator
from amaze.evaluation.suite import standard_suite
from amaze.maze.signs import register_custom_signs
from amaze.maze.spec import MazeSpec
from evolution.agent_file import AgentFileError, load_agent

SHAPES = ("arrow", "rarrow", "star", "point", "warning", "chevron")


def draw_chevron(folder: Path, size: int = 64) -> Path:
    """A custom sign: an open chevron pointing east, white on transparent, as a PNG file."""
    image = Image.new("LA", (size, size), (0, 0))
    draw = ImageDraw.Draw(image)
    width = max(1, size // 8)
    draw.line([(size * 0.25, size * 0.1), (size * 0.8, size * 0.5)], fill=(255, 255), width=width)
    draw.line([(size * 0.8, size * 0.5), (size * 0.25, size * 0.9)], fill=(255, 255), width=width)
    path = folder / "chevron.png"
    image.save(path)
    return path


def reshaped(maze: str, shape: str) -> str:
    """``maze`` with every sign type drawn in ``shape`` (same kind and lightness)."""
    return MazeSpec.from_string(maze).in_shape(shape).to_string()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("agent", type=Path, help="an agent file of a hybrid robot (.npz)")
    parser.add_argument("--shapes", nargs="+", default=list(SHAPES), metavar="SHAPE")
    args = parser.parse_args(argv)
    try:
        agent = load_agent(args.agent)
    except (AgentFileError, OSError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    robot = agent.robot.to_string()
    if agent.robot.discrete_inputs:
        print(f"error: the agent's robot {robot} sees no images: give an H robot", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory() as folder:
        register_custom_signs(draw_chevron(Path(folder)))
        suite = standard_suite().maze_strings(rotations=True)
        print(f"agent {args.agent} ({robot}), standard suite (18 mazes x 4 rotations) per shape")
        header = "shape      success   mean R̄   inputs  (clue  trap  lure  empty)"
        print(header)
        for shape in args.shapes:
            mazes = [reshaped(maze, shape) for maze in suite]
            report = Evaluator(robot, mazes, inputs=False).evaluate(agent)
            spec = MazeSpec.from_string(reshaped(INPUT_SIGNS_MAZE, shape))
            inputs = enumerate_inputs(robot, spec.clue, spec.lure, spec.trap)
            recognition = evaluate_inputs(agent, inputs)
            rates = recognition.rates
            classes = "  ".join(f"{rates.get(name, float('nan')):.2f}" for name in
                                ("clue", "trap", "lure", "empty"))  # fmt: skip
            print(
                f"{shape:<10} {report.success_rate:7.3f}  {report.normalized_reward:+7.3f}"
                f"  {recognition.overall:6.3f}  ({classes})"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
