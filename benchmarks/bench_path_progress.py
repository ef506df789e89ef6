"""How far along the paper suite's solutions do agents get? Path progress beside success and R̄.

    python benchmarks/bench_path_progress.py AGENT.npz [AGENT.npz ...] [--csv FILE]

plays each evolved agent (any robot) once on each of the 72 episodes of the
paper's suite (the 18 mazes of its Table 3 x 4 rotations, what run summaries
call ``paper_suite``) and prints, per agent, the mean path progress
(how far along its maze's solution each episode got: the furthest solution cell
the robot stood in, as a share of the path, 1 at the goal;
:func:`amaze.evaluation.policy.run_episodes` with ``path_progress=True``), the
success rate and the mean R̄. On mazes an agent does not solve, success and R̄
do not tell a robot that stands still (R̄ about -4, progress 0) from one that
drives a third of the way and collides on the way (R̄ far lower, progress about
0.3): progress does. ``--csv FILE`` also writes one row per agent.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from amaze.evaluation.suite import paper_suite
from amaze.runs.folder import write_rows
from evolution.agent_file import AgentFileError, load_agent
from evolution.population import PopulationEvaluator


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("agents", type=Path, nargs="+", metavar="AGENT", help="agent files (.npz)")
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
    mazes = paper_suite().maze_strings()
    evaluators: dict[str, PopulationEvaluator] = {}  # one per robot: the mazes compile once
    rows = []
    print(f"{'agent':<60} {'robot':>6} {'progress':>9} {'success':>8} {'mean R̄':>9}")
    for path, agent in agents:
        robot = agent.robot.to_string()
        if robot not in evaluators:
            evaluators[robot] = PopulationEvaluator(mazes, robot, fitness="path_progress")
        result = evaluators[robot].evaluate(agent)
        row = {
            "agent": str(path),
            "robot": robot,
            "episodes": evaluators[robot].n_episodes,
            "path_progress": float(result.fitness[0]),
            "success_rate": float(result.success_rate[0]),
            "normalized_reward": float(result.normalized_reward[0]),
        }
        rows.append(row)
        print(f"{path!s:<60} {robot:>6} {row['path_progress']:>9.3f}"
              f" {row['success_rate']:>8.3f} {row['normalized_reward']:>+9.3f}")  # fmt: skip
    if args.csv is not None:
        write_rows(args.csv, rows)
        print(f"rows written to {args.csv}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
