"""How far along the paper suite's solutions do agents get? Path progress beside success and R̄.

    python benchmarks/bench_path_progress.py AGENT.npz [AGENT.npz ...] [--by-class] [--csv FILE]

plays each evolved agent (any robot) once on each of the 72 episodes of the
paper's suite (the 18 mazes of its Table 3 x 4 rotations, what run summaries
call ``paper_suite``) and prints, per agent, the mean path progress
(how far along its maze's solution each episode got: the furthest solution cell
the robot stood in, as a share of the path, 1 at the goal;
:func:`amaze.evaluation.policy.run_episodes` with ``path_progress=True``), the
success rate and the mean R̄. On mazes an agent does not solve, success and R̄
do not tell a robot that stands still (R̄ about -4, progress 0) from one that
drives a third of the way and collides on the way (R̄ far lower, progress about
0.3): progress does. ``--by-class`` also prints each agent on the suite's
episodes of each maze class (trivial: unicursive, no signs; simple: clues;
lures; complex: clues, lures and traps), where it is lost. ``--csv FILE``
also writes the rows (one per agent, and per class with ``--by-class``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from amaze.evaluation.suite import paper_suite
from amaze.maze.maze import Maze
from amaze.runs.folder import write_rows
from evolution.agent_file import AgentFileError, load_agent
from evolution.population import PopulationEvaluator


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("agents", type=Path, nargs="+", metavar="AGENT", help="agent files (.npz)")
    parser.add_argument(
        "--by-class", action="store_true", help="also score each maze class of the suite apart"
    )
    parser.add_argument("--csv", type=Path, metavar="FILE", help="also write the rows to FILE")
    args = parser.parse_args(argv)
    if args.csv is not None and not args.csv.parent.is_dir():
        print(f"error: --csv {args.csv}: folder {args.csv.parent} does not exist", file=sys.stderr)
        return 2
    agents = []
    for path in args.agents:
        try:
            agents.append((path, load_agent(path)))
        except (AgentFileError, OSError) as error:
            print(f"error: {error}", file=sys.stderr)
            return 2
    suite = paper_suite().maze_strings()
    groups = {"suite": suite}
    if args.by_class:
        for maze in suite:
            name = Maze.from_string(maze).maze_class.name.lower()
            groups.setdefault(name, []).append(maze)
    evaluators: dict[tuple[str, str], PopulationEvaluator] = {}  # mazes compile once per robot
    rows = []
    print(f"{'agent':<60} {'robot':>6} {'mazes':>8} {'episodes':>8} {'progress':>9}"
          f" {'success':>8} {'mean R̄':>9}")  # fmt: skip
    for path, agent in agents:
        robot = agent.robot.to_string()
        for group, mazes in groups.items():
            if (robot, group) not in evaluators:
                evaluators[robot, group] = PopulationEvaluator(
                    mazes, robot, fitness="path_progress"
                )
            evaluator = evaluators[robot, group]
            result = evaluator.evaluate(agent)
            row = {
                "agent": str(path),
                "robot": robot,
                "mazes": group,
                "episodes": evaluator.n_episodes,
                "path_progress": float(result.fitness[0]),
                "success_rate": float(result.success_rate[0]),
                "normalized_reward": float(result.normalized_reward[0]),
            }
            rows.append(row)
            print(f"{path!s:<60} {robot:>6} {group:>8} {row['episodes']:>8}"
                  f" {row['path_progress']:>9.3f} {row['success_rate']:>8.3f}"
                  f" {row['normalized_reward']:>+9.3f}")  # fmt: skip
    if args.csv is not None:
        write_rows(args.csv, rows)
        print(f"rows written to {args.csv}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
