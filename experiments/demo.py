"""The main job on built-in defaults (``make demo``).

1. Mazes: it generates a few mazes of each class (trivial, simple, lures,
   traps, complex) and the paper's direct-training and evaluation mazes,
   renders them to PNG, prints their statistics and metrics, and writes the
   table as CSV.
2. Agents: it evaluates the built-in oracle and (seeded) random controllers
   on the standard evaluation suite (18 mazes x 4 rotations) with the
   evaluation protocol every agent of the project goes through, runs the
   input-recognition test of the random controller, and records one episode
   of each controller in the paper's evaluation maze as a trajectory PNG and
   an animated GIF.
3. Evolution: a short CMA-ES run (about a minute) of a DD agent on the
   suite's trivial and simple mazes (each in its 4 rotations); it prints the
   champion's scores on the whole suite, column by column, and leaves a full
   run folder (champion, progress, fitness plot, checkpoints).

Outputs go to ``demo_output/`` (or ``--out DIR``).
"""

from __future__ import annotations

import argparse
import csv
import json
import shutil
import sys
import time
from pathlib import Path

from amaze.maze.description import STATS_COLUMNS, format_table, stats_rows
from amaze.maze.maze import Maze
from amaze.maze.render import render_mazes_grid, save_maze_png

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


def run_agents(out: Path, robot: str = "DD") -> None:
    """Evaluate the oracle and random controllers; save trajectories and the inputs test."""
    from amaze.agents.trajectories import save_episode_gif, save_trajectory_png
    from amaze.evaluation.controllers import OracleController, RandomController
    from amaze.evaluation.inputs import evaluate_inputs, inputs_for_maze
    from amaze.evaluation.inputs_picture import save_summary_png
    from amaze.evaluation.policy import record_episode
    from amaze.evaluation.protocol import Evaluator
    from amaze.evaluation.suite import PAPER_EVALUATION_MAZE, standard_suite

    agents_dir = out / "agents"
    agents_dir.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    evaluator = Evaluator(robot)
    print(
        f"\nstandard evaluation suite: {len(standard_suite())} mazes x 4 rotations,"
        f" prepared in {time.perf_counter() - started:.2f} s"
    )
    controllers = {"oracle": OracleController(robot), "random": RandomController(robot, seed=0)}
    summaries = {}
    for name, controller in controllers.items():
        started = time.perf_counter()
        report = evaluator.evaluate(controller)
        elapsed = time.perf_counter() - started
        print(f"\n{name} controller (evaluated in {elapsed:.3f} s):")
        print(report.format())
        report.write_csv(agents_dir / f"suite_{name}.csv")
        summaries[name] = report.summary()

    recognition = evaluate_inputs(RandomController(robot, seed=0), inputs_for_maze(
        PAPER_EVALUATION_MAZE, robot
    ))  # fmt: skip
    recognition.write_csv(agents_dir / "inputs_random.csv")
    save_summary_png(recognition, agents_dir / "inputs_random.png")
    print(
        f"\ninput-recognition picture of the random controller: {agents_dir / 'inputs_random.png'}"
    )

    for name, controller in controllers.items():
        result, trajectory = record_episode(PAPER_EVALUATION_MAZE, robot, controller)
        caption = (
            f"{name} controller · paper reward {float(result.paper_reward[0]):+.3f}"
            f" · pretty reward {float(result.pretty_reward[0]):+.3f}"
        )
        save_trajectory_png(
            PAPER_EVALUATION_MAZE, trajectory, agents_dir / f"trajectory_{name}.png",
            caption=caption,
        )  # fmt: skip
        save_episode_gif(PAPER_EVALUATION_MAZE, trajectory, agents_dir / f"episode_{name}.gif")
    (agents_dir / "summary.json").write_text(json.dumps(summaries, indent=1) + "\n")


#: Wall-clock budget of the demo's evolution run.
EVOLUTION_SECONDS = 45.0


def run_evolution(out: Path, seconds: float = EVOLUTION_SECONDS) -> None:
    """Evolve a DD agent with CMA-ES on the suite's trivial and simple mazes."""
    from amaze.evaluation.protocol import Evaluator
    from amaze.evaluation.suite import standard_suite
    from evolution.run import evolve

    mazes = [m.string for m in standard_suite().mazes if m.column in ("trivial", "simple")]
    run_dir = out / "evolution"
    if run_dir.exists():
        shutil.rmtree(run_dir)
    print(f"\nCMA-ES on the {len(mazes)} trivial and simple suite mazes x 4 rotations,"
          f" {seconds:.0f} s budget:")  # fmt: skip
    config = {"algo": "cmaes", "mazes": mazes, "budget_steps": None, "budget_seconds": seconds}
    result = evolve(config, run_dir, progress_bar=sys.stderr.isatty())
    s = result.summary
    print(
        f"{s['generations']} generations, {result.env_steps:,} env steps in"
        f" {result.seconds:.1f} s ({s['policy_steps_per_second'] / 1e6:.1f} M"
        f" policy-steps/s while evaluating); champion fitness (mean R̄) {s['champion_fitness']:.3f}"
    )
    print("the champion on the standard evaluation suite:")
    print(Evaluator("DD").evaluate(result.agent).format())


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
    return table


def print_outputs(out: Path) -> None:
    print(f"\noutputs in {out.resolve()}/:")
    print("  classes.png                  overview: three mazes of each class (rows)")
    print("  mazes/*.png                  every maze, light and dark themes")
    print("  mazes.csv                    the maze table above")
    print("  agents/summary.json          oracle and random scores on the evaluation suite")
    print("  agents/suite_*.csv           their 72 episodes each")
    print("  agents/trajectory_*.png      one episode of each in the paper's evaluation maze")
    print("  agents/episode_*.gif         the same episodes, animated")
    print("  agents/inputs_random.*       the input-recognition test of the random controller")
    print("  evolution/                   the CMA-ES run folder: champion.npz, summary.json,")
    print("                               progress.csv, fitness.png, trajectories/")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default="demo_output", help="output folder (default demo_output)")
    args = parser.parse_args(argv)
    out = Path(args.out)
    run(out)
    run_agents(out)
    run_evolution(out)
    print_outputs(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
