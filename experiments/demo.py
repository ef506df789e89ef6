"""The main job on built-in defaults (``make demo``): what the framework is for, in a minute.

1. Mazes: two mazes of each class (trivial, simple, lures, traps, complex)
   and the paper's direct-training and evaluation mazes, rendered to PNG,
   with their statistics and metrics (printed, and written as CSV).
2. Controllers: the built-in oracle and (seeded) random controllers on the
   standard evaluation suite (18 mazes x 4 rotations) through the evaluation
   protocol every agent of the project goes through, the random controller's
   input-recognition test, and one episode of each in the paper's
   evaluation maze as a trajectory PNG and an animated GIF.
3. The headline: CMA-ES in the coevolution regime (agents and a population
   of mazes evolving together toward the target's family) beside CMA-ES in
   the direct regime (on the target maze itself, the paper's training maze),
   with the same algorithm options, seed and environment-step budget. One
   table shows both champions on the standard suite, on unseen mazes of the
   target's family (:func:`~amaze.curriculum.validation.unseen_mazes`, each
   in its 4 rotations) and what each run spent; pictures show both
   champions in the 4 rotations of the paper's evaluation maze.

**Why an equal step budget.** Both runs get the same number of environment
steps (validation episodes included), so neither sees more episodes than
the other, and the result does not depend on the machine's speed or load:
the demo prints the same figures run after run, busy machine or not (a
seconds budget would stop a run on a busy machine earlier, at other
figures). Each run's seconds are printed beside its steps (on an idle
2-core machine, about 20 s and 15 s). The project's headline claims
(``docs/regimes/coevolution.md``) use equal wall-clock seconds instead; at 20 s
each, this seed's two runs come out the same way.

**Why the target maze for the direct run.** It is the direct regime's
default training maze and the coevolution regime's default target, so both
runs aim at the same family with nothing else changed, and the unseen
mazes (the same 32 for both, drawn from the seed) are new to both: the
unseen columns measure generalisation within the family, while the direct
run may have memorised its one maze (its ``trajectories/`` show it there).

Outputs go to ``demo_output/`` (or ``--out DIR``); the printed summary ends
with the path of every output and three commands to go further.
"""

from __future__ import annotations

import argparse
import csv
import json
import shutil
import sys
import time
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from amaze.evaluation.suite import PAPER_EVALUATION_MAZE, PAPER_TRAINING_MAZE
from amaze.maze.description import STATS_COLUMNS, format_table, stats_rows
from amaze.maze.maze import Maze
from amaze.maze.render import render_mazes_grid, save_maze_png

if TYPE_CHECKING:
    from amaze.evaluation.protocol import Evaluator
    from amaze.runs.lifecycle import RunResult

#: Maze strings per class; seeds are fixed so the demo is reproducible.
CLASS_EXAMPLES: dict[str, list[str]] = {
    "trivial": [f"M{seed}_10x10_U" for seed in (1, 2)],
    "simple": [f"M{seed}_10x10_C1" for seed in (1, 2)],
    "lures": [f"M{seed}_10x10_C1_l.25_L.25" for seed in (1, 2)],
    "traps": [f"M{seed}_10x10_C1_t.5_T.5" for seed in (1, 2)],
    "complex": [f"M{seed}_10x10_C1_l.25_L.25_t.5_T.5" for seed in (1, 2)],
    "paper": [PAPER_TRAINING_MAZE, PAPER_EVALUATION_MAZE],
}
#: The robot of every agent of the demo (discrete moves, 5x5 cell images... see ``Robot``).
ROBOT = "DD"
#: Seed of both evolution runs (the README's example seed) and of their unseen mazes.
SEED = 7
#: The family both runs aim at: the coevolution regime's default target, the
#: direct regime's default training maze.
TARGET = PAPER_TRAINING_MAZE
#: Environment steps of each evolution run (about 20 s on 2 cores).
BUDGET_STEPS = 60_000_000
#: The two runs: what each trains on (a table cell, a sentence) and its config
#: beyond the shared one.
RUNS: dict[str, tuple[str, str, dict[str, Any]]] = {
    "coevolution": (
        "co-evolved mazes",
        "agents and a population of mazes evolve together toward the target's family",
        {"regime": "coevolution", "target": TARGET},
    ),
    "direct": (
        "the target maze",
        "agents evolve on the target maze itself, in its 4 rotations",
        {"regime": "direct", "mazes": [TARGET]},
    ),
}


# -- 1. mazes ------------------------------------------------------------------------


def run_mazes(out: Path) -> Path:
    """Render and measure the example mazes into ``out``; returns the CSV path."""
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
    examples = len(CLASS_EXAMPLES["trivial"])
    render_mazes_grid(mazes[: -len(CLASS_EXAMPLES["paper"])], columns=examples).save(
        out / "classes.png"
    )
    rows = list(stats_rows(mazes))
    print(format_table(rows))
    table = out / "mazes.csv"
    with table.open("w", newline="") as stream:
        writer = csv.DictWriter(stream, fieldnames=STATS_COLUMNS)
        writer.writeheader()
        writer.writerows(rows)
    return table


# -- 2. controllers ------------------------------------------------------------------


def run_controllers(out: Path) -> None:
    """Score the oracle and random controllers; save the inputs test, trajectories and GIFs."""
    from amaze.agents.trajectories import save_episode_gif
    from amaze.evaluation.controllers import OracleController, RandomController
    from amaze.evaluation.inputs import evaluate_inputs, inputs_for_maze
    from amaze.evaluation.inputs_picture import save_summary_png
    from amaze.evaluation.policy import record_episode
    from amaze.evaluation.protocol import evaluate

    agents_dir = out / "agents"
    agents_dir.mkdir(parents=True, exist_ok=True)
    controllers = {"oracle": OracleController(ROBOT), "random": RandomController(ROBOT, seed=0)}
    print("\nbuilt-in controllers on the standard evaluation suite (18 mazes x 4 rotations):")
    summaries = {}
    for name, controller in controllers.items():
        report = evaluate(controller, ROBOT)
        report.write_csv(agents_dir / f"suite_{name}.csv")
        summaries[name] = report.summary()
        print(f"  {name:<7} {figures_line(report.summary())}")
    (agents_dir / "summary.json").write_text(json.dumps(summaries, indent=1) + "\n")

    inputs = inputs_for_maze(PAPER_EVALUATION_MAZE, ROBOT)
    recognition = evaluate_inputs(RandomController(ROBOT, seed=0), inputs)
    recognition.write_csv(agents_dir / "inputs_random.csv")
    save_summary_png(recognition, agents_dir / "inputs_random.png")
    for name, controller in controllers.items():
        result, trajectory = record_episode(PAPER_EVALUATION_MAZE, ROBOT, controller)
        save_episode_trajectory(
            trajectory, agents_dir / f"trajectory_{name}.png", f"{name} controller", result
        )
        save_episode_gif(PAPER_EVALUATION_MAZE, trajectory, agents_dir / f"episode_{name}.gif")


def figures_line(summary: Mapping[str, Any]) -> str:
    """Success, mean R̄ and input recognition of an evaluation summary, on one line."""
    recognition = summary["input_recognition"]
    inputs = "n/a (reads the maze)" if recognition is None else f"{100 * recognition:.1f}%"
    return (
        f"success {100 * summary['success_rate']:5.1f}%,"
        f" mean R̄ {summary['normalized_reward']:+7.3f}, input recognition {inputs}"
    )


def save_episode_trajectory(trajectory: Any, path: Path, who: str, result: Any) -> None:
    """One episode in the paper's evaluation maze as a PNG, captioned with its rewards."""
    from amaze.agents.trajectories import save_trajectory_png

    caption = (
        f"{who} · R̄ {float(result.normalized_reward[0]):+.3f}"
        f" · pretty reward {float(result.pretty_reward[0]):+.3f}"
    )
    save_trajectory_png(PAPER_EVALUATION_MAZE, trajectory, path, robot=ROBOT, caption=caption)


# -- 3. the headline: coevolution against direct ------------------------------------


def evolve_run(regime: str, out: Path, steps: int) -> RunResult:
    """One CMA-ES run of the comparison in ``out/regime`` (a fresh folder).

    Both runs use the coevolution regime's CMA-ES options (one 16-unit hidden
    layer shared by the four directions, 16 IPOP restarts), so that only the
    regime differs.
    """
    from evolution.config import coevolution_cmaes
    from evolution.run import evolve

    _, what, options = RUNS[regime]
    run_dir = out / regime
    if run_dir.exists():
        shutil.rmtree(run_dir)
    config = {
        "algo": "cmaes", "algorithm": coevolution_cmaes(ROBOT), "robot": ROBOT,
        "seed": SEED, "budget_steps": steps, "budget_seconds": None, **options,
    }  # fmt: skip
    print(f"  {regime + ':':<12} {what} ...", flush=True)
    return evolve(config, run_dir)


def run_figures(result: RunResult, unseen: Evaluator) -> dict[str, Any]:
    """A run's column of the table: its champion through the evaluation protocol.

    The suite figures (success, mean R̄, input recognition, per column) come
    from the standard suite, the unseen ones from ``unseen``, an
    :class:`~amaze.evaluation.protocol.Evaluator` of the target's unseen
    family mazes in their 4 rotations: the same mazes and the same protocol
    for both runs (for the coevolution run, the same figures as its
    ``summary.json``'s ``unseen_success_rate`` and ``unseen_normalized_reward``).
    """
    from amaze.evaluation.protocol import evaluate

    suite = evaluate(result.agent, ROBOT)
    unseen_report = unseen.evaluate(result.agent)
    s = result.summary
    return {
        "folder": str(result.out),
        "agent_file": str(agent_file(result)),
        "success_rate": suite.success_rate,
        "normalized_reward": suite.normalized_reward,
        "input_recognition": suite.input_recognition,
        "column_success": {k: v["success_rate"] for k, v in suite.per_column().items()},
        "unseen_success_rate": unseen_report.success_rate,
        "unseen_normalized_reward": unseen_report.normalized_reward,
        "unseen_episodes": len(unseen_report.episodes),
        "env_steps": int(s["env_steps"]),
        "seconds": float(s["seconds"]),
        "generations": int(s["generations"]),
    }


def agent_file(result: RunResult) -> Path:
    """The run folder's agent file, as its summary names it (``champion.npz`` if it does not)."""
    return result.out / str(result.summary.get("agent", "champion.npz"))


def run_headline(out: Path, steps: int = BUDGET_STEPS) -> dict[str, dict[str, Any]]:
    """Evolve with both regimes, print the table, save champion trajectories; the figures.

    The figures are also written to ``out/headline.json``.
    """
    from amaze.curriculum.validation import unseen_mazes
    from amaze.evaluation.protocol import Evaluator
    from amaze.maze import rotations
    from evolution.config import coevolution_cmaes

    print(
        f"\nthe headline: CMA-ES ({ROBOT} robot, options {json.dumps(coevolution_cmaes(ROBOT))},"
        " seed"
        f" {SEED}) in two regimes,\n{steps:,} env steps each, toward the family of {TARGET}:"
    )
    unseen = Evaluator(ROBOT, rotations(unseen_mazes(TARGET, SEED)), inputs=False)
    table: dict[str, dict[str, Any]] = {}
    for regime in RUNS:
        result = evolve_run(regime, out, steps)
        table[regime] = run_figures(result, unseen)
        save_rotations_strip(result.agent, out / "agents" / f"evaluation_maze_{regime}.png")
    print(f"\n{format_comparison(table)}")
    print(
        f"one seed, {steps:,} steps: for 5 seeds x 300 s and the statistics, see"
        " docs/regimes/coevolution.md"
    )
    (out / "headline.json").write_text(json.dumps(table, indent=1) + "\n")
    return table


def save_rotations_strip(agent: Any, path: Path) -> Path:
    """``agent`` in the 4 rotations of the paper's evaluation maze, side by side in one PNG.

    The maze is of the target's family and new to both runs: the picture
    shows one unseen maze the way the table's unseen columns count them.
    """
    from PIL import Image

    from amaze.agents.trajectories import render_trajectory
    from amaze.evaluation.policy import record_episode
    from amaze.maze import rotations
    from amaze.maze.render import save_picture

    pictures = []
    for maze in rotations(PAPER_EVALUATION_MAZE):
        result, trajectory = record_episode(maze, ROBOT, agent)
        caption = f"{maze} · R̄ {float(result.normalized_reward[0]):+.3f}"
        pictures.append(render_trajectory(maze, trajectory, robot=ROBOT, caption=caption))
    size = (sum(p.width for p in pictures), max(p.height for p in pictures))
    strip = Image.new("RGB", size, "white")
    for k, picture in enumerate(pictures):
        strip.paste(picture, (sum(p.width for p in pictures[:k]), 0))
    return save_picture(strip, path)


def format_comparison(table: Mapping[str, Mapping[str, Any]]) -> str:
    """The runs side by side: one row per figure, one column per run."""
    names = list(table)
    first = table[names[0]]
    rows: list[tuple[str, list[str]]] = [
        ("trained on", [RUNS[n][0] if n in RUNS else "" for n in names]),
        ("standard suite: success", [f"{100 * t['success_rate']:.1f}%" for t in table.values()]),
    ]
    for column in first["column_success"]:
        rows.append(
            (f"  {column}", [f"{100 * t['column_success'][column]:.1f}%" for t in table.values()])
        )
    rows += [
        ("standard suite: mean R̄", [f"{t['normalized_reward']:+.3f}" for t in table.values()]),
        ("input recognition", [percent(t["input_recognition"]) for t in table.values()]),
        (
            f"unseen family mazes ({first['unseen_episodes'] // 4} x 4): success",
            [f"{100 * t['unseen_success_rate']:.1f}%" for t in table.values()],
        ),
        (
            "unseen family mazes: mean R̄",
            [f"{t['unseen_normalized_reward']:+.3f}" for t in table.values()],
        ),
        ("env steps", [f"{t['env_steps']:,}" for t in table.values()]),
        ("seconds", [f"{t['seconds']:.1f}" for t in table.values()]),
        ("generations", [str(t["generations"]) for t in table.values()]),
    ]
    label = max(len(name) for name, _ in rows)
    width = max(len(cell) for _, cells in rows for cell in [*cells, *names]) + 2
    lines = [" " * label + "".join(f"{n:>{width}}" for n in names)]
    lines += [f"{name:<{label}}" + "".join(f"{c:>{width}}" for c in cells) for name, cells in rows]
    return "\n".join(lines)


def percent(value: float | None) -> str:
    """A share as a percentage, or n/a."""
    return "n/a" if value is None else f"{100 * value:.1f}%"


# -- outputs and the command line ----------------------------------------------------


def print_outputs(out: Path, table: Mapping[str, Mapping[str, Any]]) -> None:
    """Where every output is, then three commands to go further."""
    root = out.resolve()
    agent = Path(table["coevolution"]["agent_file"]).name
    print(f"\noutputs in {root}/:")
    for path, what in (
        ("classes.png", "two mazes of each class, one class a row"),
        ("mazes/*.png, mazes.csv", "every example maze (light and dark themes), the maze table"),
        ("agents/summary.json, suite_*.csv", "oracle and random on the suite, per episode"),
        ("agents/inputs_random.png, .csv", "the random controller's input-recognition test"),
        ("agents/trajectory_*.png, episode_*", "oracle and random in the paper's evaluation maze"),
        ("agents/evaluation_maze_*.png", "both champions in its 4 rotations (unseen by both)"),
        ("headline.json", "the table above"),
        ("coevolution/population.png", "the maze population at the end, with its scores"),
        ("coevolution/coevolution.png", "fitness, validation success, difficulty over steps"),
        ("coevolution/trajectories/", "its champion in the target's 4 rotations"),
        ("direct/fitness.png", "fitness over steps"),
        ("direct/trajectories/", "its champion in the target's 4 rotations (its training maze)"),
        (f"*/{agent}, summary.json", "each run's champion and figures (a run folder each)"),
    ):
        print(f"  {path:<36} {what}")
    print("\nto go further:")
    for command, why in further_commands(Path(table["coevolution"]["agent_file"]).resolve()):
        print(f"  {command}\n      # {why}")


def further_commands(champion: Path) -> list[tuple[str, str]]:
    """Three commands to go further, each with what it does; ``champion`` is an agent file."""
    return [
        (
            f"amaze-evolve --regime coevolution --robot {ROBOT} --budget-seconds 300"
            f" --seed {SEED} --out runs/co",
            "a run of the README's results: 5 minutes on 2 cores",
        ),
        (
            "amaze-experiment run smoke --out studies/smoke --workers 2",
            "a study (trainers x algorithms x seeds), then `amaze-experiment report studies/smoke`",
        ),
        (
            f"amaze run {PAPER_EVALUATION_MAZE} --controller {champion} --gif champion.gif",
            "watch the co-evolved champion (or any agent file) in any maze",
        ),
    ]


def main(argv: list[str] | None = None) -> int:
    """``python -m experiments.demo [--out DIR]``: the three parts, then where everything is."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default="demo_output", help="output folder (default demo_output)")
    parser.add_argument("--steps", type=int, default=BUDGET_STEPS, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.steps < 1:
        parser.error(f"--steps {args.steps} must be at least 1")
    out = Path(args.out)
    if hasattr(sys.stdout, "reconfigure"):  # each line as it is printed, into a pipe or file too
        sys.stdout.reconfigure(line_buffering=True)
    print(f"amaze-evo demo: mazes, built-in controllers, then two evolution runs -> {out}/")
    started = time.perf_counter()
    run_mazes(out)
    run_controllers(out)
    table = run_headline(out, args.steps)
    print_outputs(out, table)
    print(f"\ndemo done in {time.perf_counter() - started:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
