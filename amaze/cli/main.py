"""The ``amaze`` command: inspect, render and measure mazes; run agents in them.

Sub-commands: ``inspect``, ``render``, ``stats`` (mazes from their strings;
``-`` reads them from standard input, one per line), ``run`` (alias ``play``:
one controller, one episode, optional trajectory PNG and GIF), ``inputs``
(the input-recognition test), ``suite`` (the standard evaluation suite, or
the paper's with ``--paper``: list, render, evaluate a controller),
``evaluate`` (any agent on any mazes, by the evaluation protocol),
``interpolate`` (the stages of an interpolation curriculum between two mazes)
and ``draw-signs`` (arrow images to train sighted agents on, and held-out ones).
User mistakes print one line ``error: ...`` on standard error and exit with
status 2; there is no traceback for bad input.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import warnings
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

from amaze.errors import AmazeError, MazeStringError, UsageError
from amaze.maze.signs import register_custom_signs
from amaze.runs.command import CommandParser, run_command

if TYPE_CHECKING:
    from amaze.evaluation.protocol import EvaluationReport


def _maze_strings(arguments: Sequence[str]) -> Iterator[str]:
    """The maze strings of the command line, reading ``-`` from standard input."""
    for argument in arguments:
        if argument == "-":
            for line in sys.stdin:
                if line.strip():
                    yield line.strip()
        else:
            yield argument


def _mazes(arguments: Sequence[str]) -> Iterator:
    from amaze.maze.maze import Maze

    for text in _maze_strings(arguments):
        yield Maze.from_string(text)


def _cmd_inspect(args: argparse.Namespace) -> None:
    from amaze.maze.description import describe, summary

    for index, maze in enumerate(_mazes(args.mazes)):
        if args.json:
            print(json.dumps(describe(maze), separators=(",", ":")), flush=True)
        else:
            print(("\n" if index else "") + summary(maze), flush=True)


def _cmd_render(args: argparse.Namespace) -> None:
    from amaze.maze.maze import Maze
    from amaze.maze.render import RenderOptions, save_maze_png

    maze = Maze.from_string(args.maze)
    options = RenderOptions(
        theme="dark" if args.dark else "light",
        colorblind=args.colorblind,
        solution=args.solution,
        **({"cell_size": args.cell_size} if args.cell_size is not None else {}),
    )
    output = Path(args.output)
    if output.is_dir():
        raise UsageError(f"output '{output}' is a folder; give a file name such as maze.png")
    if output.suffix.lower() != ".png":
        raise UsageError(f"output '{output}' must end in .png")
    path = save_maze_png(maze, output, options)
    print(f"{maze.to_string()} -> {path}")


def _cmd_stats(args: argparse.Namespace) -> None:
    from amaze.maze.description import STATS_COLUMNS, format_table, stats_rows

    rows = list(stats_rows(_mazes(args.mazes)))
    print(format_table(rows))
    if args.csv:
        path = Path(args.csv)
        tmp = path.with_name(path.name + ".tmp")
        with tmp.open("w", newline="") as stream:
            writer = csv.DictWriter(stream, fieldnames=STATS_COLUMNS)
            writer.writeheader()
            writer.writerows(rows)
        tmp.replace(path)
        print(f"wrote {len(rows)} rows to {path}")


def _output_file(text: str | None, suffix: str) -> Path | None:
    """A writable output file name with the given suffix, or None."""
    if text is None:
        return None
    path = Path(text)
    if path.is_dir():
        raise UsageError(f"output '{path}' is a folder; give a file name ending in {suffix}")
    if path.suffix.lower() != suffix:
        raise UsageError(f"output '{path}' must end in {suffix}")
    path.parent.mkdir(parents=True, exist_ok=True)
    return path


def _controller(args: argparse.Namespace):
    from amaze.evaluation.controllers import make_controller

    return make_controller(args.controller, args.robot, seed=args.seed)


def _cmd_run(args: argparse.Namespace) -> None:
    from amaze.agents.robot import as_robot
    from amaze.evaluation.policy import record_episode
    from amaze.maze.maze import Maze

    trajectory_png = _output_file(args.trajectory, ".png")
    gif = _output_file(args.gif, ".gif")
    maze = Maze.from_string(args.maze)
    robot = as_robot(args.robot)
    policy = _controller(args)
    result, trajectory = record_episode(maze, robot, policy, deadline_factor=args.deadline_factor)
    outcome = {
        "maze": maze.to_string(),
        "robot": robot.to_string(),
        "controller": args.controller,
        "success": bool(result.success[0]),
        "steps": int(result.steps[0]),
        "path_length": int(result.path_length[0]),
        "collisions": int(result.collisions[0]),
        "backsteps": int(result.backsteps[0]),
        "cumulative_reward": float(result.cumulative_reward[0]),
        "pretty_reward": float(result.pretty_reward[0]),
        "normalized_reward": float(result.normalized_reward[0]),
    }
    if args.json:
        print(json.dumps(outcome))
    else:
        print(
            f"{outcome['maze']} ({outcome['robot']}, {args.controller}):"
            f" {'success' if outcome['success'] else 'failure'} in {outcome['steps']} steps"
            f" (path length {outcome['path_length']}), {outcome['collisions']} collisions,"
            f" {outcome['backsteps']} backward steps"
        )
        print(
            f"  reward {outcome['cumulative_reward']:.2f}, pretty reward"
            f" {outcome['pretty_reward']:+.3f}, R̄ {outcome['normalized_reward']:+.3f}"
        )
    if trajectory_png is not None or gif is not None:
        from amaze.agents.trajectories import save_episode_gif, save_trajectory_png

        caption = (
            f"{args.controller} controller · R̄ {outcome['normalized_reward']:+.3f}"
            f" · pretty reward {outcome['pretty_reward']:+.3f}"
        )
        if trajectory_png is not None:
            save_trajectory_png(maze, trajectory, trajectory_png, caption=caption)
            print(f"trajectory -> {trajectory_png}")
        if gif is not None:
            save_episode_gif(maze, trajectory, gif)
            print(f"animation -> {gif}")


def _cmd_inputs(args: argparse.Namespace) -> None:
    from amaze.evaluation.inputs import evaluate_inputs, inputs_for_maze

    csv_path = _output_file(args.csv, ".csv")
    png_path = _output_file(args.png, ".png")
    input_set = inputs_for_maze(
        args.signs_from, args.robot, empty_intersections=args.empty_intersections
    )
    policy = _controller(args)
    if callable(getattr(policy, "bind", None)):
        raise UsageError(
            f"controller '{args.controller}' reads the maze itself; the input-recognition"
            " test needs a controller that acts on its observations"
        )
    recognition = evaluate_inputs(policy, input_set)
    rates = ", ".join(f"{name} {100 * rate:.1f}%" for name, rate in recognition.rates.items())
    print(
        f"{len(input_set)} inputs ({args.robot}, {args.controller}):"
        f" {100 * recognition.overall:.1f}% correct; {rates}"
    )
    if csv_path is not None:
        recognition.write_csv(csv_path)
        print(f"table -> {csv_path}")
    if png_path is not None:
        from amaze.evaluation.inputs_picture import save_summary_png

        save_summary_png(recognition, png_path)
        print(f"summary -> {png_path}")


def _cmd_suite(args: argparse.Namespace) -> None:
    from amaze.evaluation.suite import (
        PAPER_EVALUATION_MAZE,
        PAPER_TRAINING_MAZE,
        paper_suite,
        standard_suite,
    )

    render_path = _output_file(args.render, ".png")
    csv_path = _output_file(args.csv, ".csv")
    if csv_path is not None and args.evaluate is None:
        raise UsageError("--csv needs --evaluate CONTROLLER")
    suite = paper_suite() if args.paper else standard_suite()
    title = "the paper's evaluation suite" if args.paper else "the standard evaluation suite"
    if args.evaluate is not None:
        from amaze.evaluation.protocol import Evaluator

        args.controller = args.evaluate
        policy = _controller(args)
        evaluator = Evaluator(args.robot, suite, deadline_factor=args.deadline_factor)
        report = evaluator.evaluate(policy)
        print(f"{args.evaluate} controller on {title}:")
        print(report.format())
        if csv_path is not None:
            report.write_csv(csv_path)
            print(f"episodes -> {csv_path}")
    elif args.json:
        print(json.dumps(suite.to_dict()))
    elif args.paper:
        last = suite.seed_offset + suite.sample_size - 1
        print(
            f"{title}: {len(suite)} mazes x 4 rotations (chosen by its script among the seeds"
            f" {suite.seed_offset}..{last} of each family)"
        )
        for maze in suite.mazes:
            print(
                f"  {maze.column:<9} {maze.row:<6} entropy={maze.script_entropy:.3f} nats"
                f"  S={maze.surprisingness:.3f}  {maze.string}"
            )
    else:
        print(f"standard evaluation suite: {len(suite)} mazes x 4 rotations"
              f" (S from samples of {suite.sample_size} mazes per column)")  # fmt: skip
        for maze in suite.mazes:
            print(f"  {maze.column:<9} {maze.row:<6} S={maze.surprisingness:.3f}  {maze.string}")
        print(f"paper pair: train {PAPER_TRAINING_MAZE}, evaluate {PAPER_EVALUATION_MAZE}")
    if render_path is not None:
        from amaze.maze.maze import Maze
        from amaze.maze.render import render_mazes_grid

        mazes = [Maze.from_string(m.string) for m in suite.mazes]
        columns = len({m.column for m in suite.mazes})
        rows = len(mazes) // columns
        by_row = [mazes[c * rows + r] for r in range(rows) for c in range(columns)]
        render_mazes_grid(by_row, columns=columns).save(render_path)
        print(f"suite picture -> {render_path}")


#: The ``amaze evaluate`` argument that stands for the standard suite's 18 mazes.
SUITE_ARGUMENT = "suite"
#: The ``amaze evaluate`` argument that stands for the paper's suite's 18 mazes.
PAPER_SUITE_ARGUMENT = "paper"


def _listed_mazes(lines: Iterable[str], source: str) -> Iterator[tuple[str, str]]:
    """(maze string, where it was read) of a list: blank lines and ``#`` comments skipped."""
    for number, line in enumerate(lines, start=1):
        text = line.split("#", 1)[0].strip()
        if text:
            yield text, f"{source}, line {number}"


def _maze_file(argument: str) -> Iterator[tuple[str, str]]:
    """The maze strings of a file, one per line."""
    path = Path(argument)
    if path.is_dir():
        raise UsageError(f"maze file '{path}' is a folder")
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except UnicodeDecodeError:
        raise UsageError(f"maze file '{path}' is not UTF-8 text") from None
    yield from _listed_mazes(lines, f"maze file '{path}'")


def _evaluation_arguments(arguments: Sequence[str]) -> Iterator[tuple[str, str | None]]:
    """(maze string, where it was read or None) of ``amaze evaluate``'s maze arguments.

    An argument is ``-`` (standard input), ``suite`` (the standard suite's
    mazes), ``paper`` (the paper's suite's), the path of an existing file of
    maze strings, or else a maze string.
    """
    for argument in arguments:
        if argument == "-":
            yield from _listed_mazes(sys.stdin, "standard input")
        elif argument == SUITE_ARGUMENT:
            from amaze.evaluation.suite import standard_suite

            yield from ((m, None) for m in standard_suite().maze_strings(rotations=False))
        elif argument == PAPER_SUITE_ARGUMENT:
            from amaze.evaluation.suite import paper_suite

            yield from ((m, None) for m in paper_suite().maze_strings(rotations=False))
        elif Path(argument).exists():
            yield from _maze_file(argument)
        else:
            yield argument, None


def _evaluation_mazes(arguments: Sequence[str]) -> list[str]:
    """The canonical strings of the mazes to evaluate on, each checked (not generated).

    A seedless string draws its seed here, once. An empty list is a usage error.
    """
    from amaze.maze.spec import MazeSpec

    mazes = []
    for text, where in _evaluation_arguments(arguments):
        try:
            mazes.append(MazeSpec.from_string(text).to_string())
        except MazeStringError as error:
            message = str(error) if f"'{text}'" in str(error) else f"maze '{text}': {error}"
            raise MazeStringError(f"{where}: {message}" if where else message) from None
    if not mazes:
        raise UsageError("no maze to evaluate on: give maze strings, a file of them, - or suite")
    return mazes


def _evaluation_outcome(args: argparse.Namespace, report: EvaluationReport) -> dict[str, Any]:
    """The JSON object of ``amaze evaluate``: the report's summary, per maze figures."""
    outcome = {"agent": args.agent, **report.summary(), "mean_steps": report.mean_steps}
    if args.agent == "random":
        outcome["seed"] = args.seed
    outcome["mazes"] = [
        {
            "maze": maze,
            "episodes": scores["episodes"],
            "success_rate": scores["success_rate"],
            "normalized_reward": scores["normalized_reward"],
            "pretty_reward": scores["pretty_reward"],
            "mean_steps": scores["mean_steps"],
        }
        for (maze, _), scores in report.per_maze().items()
    ]
    return outcome


def _evaluation_table(outcome: dict[str, Any]) -> str:
    """The readable table of ``amaze evaluate``: one row per maze, then all of them."""
    rows = [(m["maze"], m) for m in outcome["mazes"]] + [("all", outcome)]
    width = max(len(name) for name, _ in rows)
    # 'mean R̄' has a combining macron: 7 characters, 6 columns wide
    header = f"{'maze':<{width}} {'episodes':>8} {'success':>8} {'mean R̄':>9} {'mean steps':>10}"
    lines = [f"  {header}"]
    for name, scores in rows:
        lines.append(
            f"  {name:<{width}} {scores['episodes']:>8} {100 * scores['success_rate']:7.1f}%"
            f" {scores['normalized_reward']:+8.3f} {scores['mean_steps']:10.1f}"
        )
    recognition = outcome["input_recognition"]
    if recognition is not None:
        rates = ", ".join(f"{k} {100 * v:.1f}%" for k, v in outcome["input_rates"].items())
        paper = 100 * outcome["paper_input_recognition"]
        lines.append(
            f"  input recognition {100 * recognition:.1f}% ({rates}); as the paper scored it"
            f" {paper:.1f}%"
        )
    return "\n".join(lines)


def _cmd_evaluate(args: argparse.Namespace) -> None:
    from amaze.agents.robot import as_robot
    from amaze.evaluation.controllers import make_controller, run_folder_agent
    from amaze.evaluation.protocol import evaluate

    csv_path = _output_file(args.csv, ".csv")
    mazes = _evaluation_mazes(args.mazes)
    if Path(args.agent).is_dir():  # a run folder: its agent, named in the report
        args.agent = str(run_folder_agent(Path(args.agent)))
    policy = make_controller(args.agent, args.robot, seed=args.seed)
    robot = as_robot(getattr(policy, "robot", None) or args.robot or "DD")
    report = evaluate(
        policy, robot, mazes, rotations=args.rotations, deadline_factor=args.deadline_factor
    )
    outcome = _evaluation_outcome(args, report)
    if args.script_reward:
        from amaze.evaluation.script_reward import script_rewards

        rewards = script_rewards(policy, robot, [e.maze for e in report.episodes])
        outcome["script_reward"] = sum(rewards) / len(rewards)
    if args.json:
        print(json.dumps(outcome))
    else:
        print(f"{args.agent} ({outcome['robot']}) on {report.played()}:")
        print(_evaluation_table(outcome))
        if args.script_reward:
            scored = outcome["script_reward"]
            print(f"  mean R̄ as the paper's evaluation script scored it: {scored:+.3f}")
    if csv_path is not None:
        report.write_csv(csv_path)
        print(f"episodes -> {csv_path}", file=sys.stderr if args.json else sys.stdout)


def _cmd_interpolate(args: argparse.Namespace) -> None:
    from amaze.curriculum.interpolation import interpolate, interpolation_start
    from amaze.maze.maze import Maze
    from amaze.maze.spec import MazeSpec

    render_path = _output_file(args.render, ".png")
    end = MazeSpec.from_string(args.end)  # parsed once: a seedless END draws one seed
    start = interpolation_start(end) if args.start == "trivial" else args.start
    stages = interpolate(start, end, args.stages, seed=args.seed)
    strings = [stage.to_string() for stage in stages]
    if args.json:
        print(json.dumps(strings))
    else:
        for index, stage in enumerate(stages):
            maze = Maze.generate(stage)
            counts = maze.stats()
            print(
                f"{index:>2} {strings[index]}  {maze.maze_class.label}"
                f" path={counts['path']} intersections={counts['intersections']}"
                f" clues={counts['clues']} lures={counts['lures']} traps={counts['traps']}"
            )
    if render_path is not None:
        from amaze.maze.render import render_mazes_grid

        labels = [f"{index}: {text}" for index, text in enumerate(strings)]
        columns = min(len(stages), 5)
        render_mazes_grid(strings, columns=columns, labels=labels).save(render_path)
        print(f"stages picture -> {render_path}", file=sys.stderr if args.json else sys.stdout)


def _cmd_draw_signs(args: argparse.Namespace) -> None:
    from amaze.maze.arrow_styles import (
        DEFAULT_HEADS,
        DEFAULT_SHAFT_WIDTH,
        HELD_OUT_FOLDER,
        TRAINING_FOLDER,
        write_sign_styles,
    )

    shaft_width = args.shaft_width or DEFAULT_SHAFT_WIDTH
    groups = write_sign_styles(args.out, args.training, args.seed, args.heads, shaft_width)
    training, held_out = groups[TRAINING_FOLDER], groups[HELD_OUT_FOLDER]
    folder = Path(args.out)
    print(f"{len(training)} training styles (seed {args.seed}) -> {folder / TRAINING_FOLDER}:")
    print(f"  {' '.join(training)}")
    print(f"{len(held_out)} held-out styles (never train on them) -> {folder / HELD_OUT_FOLDER}:")
    print(f"  {' '.join(held_out)}")
    listed = json.dumps({"coevolution": {"shapes": ["arrow", *training]}})
    drawn = json.dumps(
        {
            "coevolution": {
                "shapes": ["arrow"],
                "sign_styles": len(training),
                "sign_styles_seed": args.seed,
                **({} if args.heads == DEFAULT_HEADS else {"sign_styles_heads": list(args.heads)}),
                **(
                    {}
                    if shaft_width == DEFAULT_SHAFT_WIDTH
                    else {"sign_styles_shaft_width": list(shaft_width)}
                ),
            }
        }
    )
    print(
        f"use them: amaze --signs {folder / TRAINING_FOLDER} ... (maze strings such as"
        f" M4_10x10_C{training[0]}-1), or AMAZE_CUSTOM_SIGNS={folder / TRAINING_FOLDER}"
        " in the environment of any command"
    )
    print(
        "train on them (amaze-evolve, or amaze-train --framework jax, --regime coevolution"
        f" --config FILE.json): {drawn} (the run draws these styles itself), or with them"
        f" registered: {listed}"
    )


def _deadline_factor(text: str) -> float:
    """The value of ``--deadline-factor``: a finite number in [1, 1000].

    Checked as the library checks it (:func:`~amaze.agents.rewards.check_deadline_factor`)
    when the command line is read, so that ``nan`` or ``0`` is one ``error:`` line
    naming the option rather than a late failure.
    """
    from amaze.agents.rewards import check_deadline_factor

    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    try:
        return check_deadline_factor(value)
    except AmazeError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def _shaft_width(text: str) -> tuple[float, float]:
    """The value of ``draw-signs --shaft-width``: ``LOW,HIGH``, checked as the library checks it."""
    from amaze.maze.arrow_styles import check_shaft_width

    try:
        numbers = [float(part) for part in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not LOW,HIGH (two numbers)") from None
    try:
        return check_shaft_width(numbers)
    except AmazeError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def _add_agent_options(
    parser: argparse.ArgumentParser, controller: bool = True, robot: str | None = "DD"
) -> None:
    """``--robot`` (default ``robot``), ``--controller``, ``--seed`` and ``--deadline-factor``."""
    parser.add_argument(
        "--robot",
        default=robot,
        help="robot string: DD, H15, CC15, ..."
        + (f" ({robot})" if robot else " (default: the agent file's; DD for random and oracle)"),
    )
    if controller:
        parser.add_argument(
            "--controller",
            default="random",
            help="random, oracle, or a saved agent: tabular .json, SB3 .zip, evolved .npz"
            " (default random)",
        )
    parser.add_argument("--seed", type=int, default=0, help="seed of random controllers (0)")
    parser.add_argument(
        "--deadline-factor",
        type=_deadline_factor,
        default=4.0,
        metavar="F",
        help="episodes end after F x path length time units, F in [1, 1000] (4)",
    )


def _add_inspect(commands: argparse._SubParsersAction) -> None:
    """``amaze inspect``: describe mazes, one line (or JSON object) per maze."""
    inspect = commands.add_parser("inspect", help="describe mazes (JSON Lines with --json)")
    inspect.add_argument("mazes", nargs="+", metavar="MAZE", help="maze strings; - reads stdin")
    inspect.add_argument("--json", action="store_true", help="one JSON object per maze and line")
    inspect.set_defaults(run=_cmd_inspect)


def _add_render(commands: argparse._SubParsersAction) -> None:
    """``amaze render``: draw one maze to a PNG file."""
    render = commands.add_parser("render", help="draw a maze to a PNG file")
    render.add_argument("maze", metavar="MAZE", help="maze string")
    render.add_argument("-o", "--output", default="maze.png", help="PNG file (default maze.png)")
    render.add_argument("--dark", action="store_true", help="dark theme")
    render.add_argument("--colorblind", action="store_true", help="colour-blind-safe palette")
    render.add_argument(
        "--no-solution", dest="solution", action="store_false", help="do not draw the solution"
    )
    render.add_argument(
        "--cell-size", type=int, metavar="PX", help="pixels per cell, 4 to 512 (default: automatic)"
    )
    render.set_defaults(run=_cmd_render)


def _add_stats(commands: argparse._SubParsersAction) -> None:
    """``amaze stats``: the statistics and metrics table of mazes."""
    stats = commands.add_parser("stats", help="statistics and metrics table of mazes")
    stats.add_argument("mazes", nargs="+", metavar="MAZE", help="maze strings; - reads stdin")
    stats.add_argument("--csv", metavar="FILE", help="also write the table as CSV")
    stats.set_defaults(run=_cmd_stats)


def _add_run(commands: argparse._SubParsersAction, name: str) -> None:
    """``amaze run`` (or its alias ``amaze play``): one episode of a controller in a maze."""
    run = commands.add_parser(
        name,
        help="run a controller for one episode in a maze"
        + (" (same as run)" if name == "play" else ""),
    )
    run.add_argument("maze", metavar="MAZE", help="maze string")
    _add_agent_options(run)
    run.add_argument("--trajectory", metavar="PNG", help="save the trajectory picture")
    run.add_argument("--gif", metavar="GIF", help="save an animation of the episode")
    run.add_argument("--json", action="store_true", help="print the outcome as JSON")
    run.set_defaults(run=_cmd_run)


def _add_inputs(commands: argparse._SubParsersAction) -> None:
    """``amaze inputs``: the input-recognition test of a controller."""
    inputs = commands.add_parser("inputs", help="the input-recognition test of a controller")
    _add_agent_options(inputs)
    inputs.add_argument(
        "--signs-from",
        default="M0_20x20_C1_l.25_L.25_t.5_T.5",
        metavar="MAZE",
        help="take the clue, lure and trap signs of this maze string (C1, L.25, T.5)",
    )
    inputs.add_argument(
        "--empty-intersections", action="store_true", help="also test sign-less intersections"
    )
    inputs.add_argument("--csv", metavar="FILE", help="write every input and answer as CSV")
    inputs.add_argument("--png", metavar="FILE", help="write the summary picture")
    inputs.set_defaults(run=_cmd_inputs)


def _add_suite(commands: argparse._SubParsersAction) -> None:
    """``amaze suite``: list, render or evaluate on the standard evaluation suite."""
    suite = commands.add_parser(
        "suite", help="list, render or evaluate on the standard evaluation suite"
    )
    suite.add_argument(
        "--paper",
        action="store_true",
        help="the paper's evaluation suite (the 18 mazes of its Table 3) instead",
    )
    suite.add_argument("--json", action="store_true", help="print the suite as JSON")
    suite.add_argument("--render", metavar="PNG", help="draw the 18 mazes (columns x rows)")
    suite.add_argument(
        "--evaluate",
        metavar="CONTROLLER",
        help="evaluate random, oracle or a saved agent (.json, .zip, .npz)",
    )
    _add_agent_options(suite, controller=False)
    suite.add_argument("--csv", metavar="FILE", help="with --evaluate: one row per episode")
    suite.set_defaults(run=_cmd_suite)


def _add_evaluate(commands: argparse._SubParsersAction) -> None:
    """``amaze evaluate``: score an agent on mazes by the evaluation protocol."""
    evaluate = commands.add_parser(
        "evaluate", help="score an agent on mazes by the evaluation protocol"
    )
    evaluate.add_argument(
        "agent",
        metavar="AGENT",
        help="a saved agent (evolved .npz, SB3 .zip, tabular .json), a run folder (its agent),"
        " random or oracle",
    )
    evaluate.add_argument(
        "mazes",
        nargs="+",
        metavar="MAZE",
        help="maze strings, files of them (one per line, # comments), - (stdin),"
        " suite (the standard suite's 18 mazes) or paper (the paper's suite's 18 mazes)",
    )
    evaluate.add_argument(
        "--rotations",
        type=int,
        choices=(1, 4),  # amaze.evaluation.protocol.ROTATIONS
        default=4,
        help="4: each maze in its four rotations, as training and the suite (default);"
        " 1: each maze as given",
    )
    _add_agent_options(evaluate, controller=False, robot=None)
    evaluate.add_argument(
        "--script-reward",
        action="store_true",
        help="also the mean R̄ as the paper's evaluation script scored it (collisions -0.02,"
        " backward steps -0.01, collisions in the start cell counted as backward steps;"
        " discrete moves only; each episode replayed and recorded, slower)",
    )
    evaluate.add_argument("--json", action="store_true", help="print one JSON object")
    evaluate.add_argument("--csv", metavar="FILE", help="write one row per episode")
    evaluate.set_defaults(run=_cmd_evaluate)


def _add_interpolate(commands: argparse._SubParsersAction) -> None:
    """``amaze interpolate``: the interpolation curriculum from a start maze to an end maze."""
    interpolate = commands.add_parser(
        "interpolate", help="the interpolation curriculum from a start maze to an end maze"
    )
    interpolate.add_argument(
        "start", metavar="START", help="first maze string, or 'trivial' (5x5 unicursive)"
    )
    interpolate.add_argument("end", metavar="END", help="target maze string (the last stage)")
    interpolate.add_argument(
        "-n", "--stages", type=int, default=10, metavar="N", help="number of stages (10)"
    )
    interpolate.add_argument(
        "--seed", type=int, help="seed of the intermediate stages (default: the end maze's)"
    )
    interpolate.add_argument("--json", action="store_true", help="print a JSON list of strings")
    interpolate.add_argument("--render", metavar="PNG", help="draw every stage in one picture")
    interpolate.set_defaults(run=_cmd_interpolate)


def _add_draw_signs(commands: argparse._SubParsersAction) -> None:
    """``amaze draw-signs``: write arrow sign images, training styles and held-out ones."""
    draw = commands.add_parser(
        "draw-signs",
        help="write arrow sign images: varied training styles and held-out styles (PNG)",
    )
    draw.add_argument(
        "out", metavar="OUT", help="folder to write OUT/training/ and OUT/held-out/ in"
    )
    draw.add_argument(
        "--training",
        type=int,
        default=16,
        metavar="N",
        help="number of training styles, 1 to 256 (16)",
    )
    draw.add_argument("--seed", type=int, default=0, help="seed of the training styles (0)")
    draw.add_argument(
        "--heads",
        type=lambda text: tuple(text.split(",")),
        default=("filled", "open"),
        metavar="A,B",
        help="heads the training styles may have: filled, open, hollow, hairline (filled,open)",
    )
    draw.add_argument(
        "--shaft-width",
        type=_shaft_width,
        default=None,
        metavar="LOW,HIGH",
        help="range of the training styles' shaft widths, shares of the image side within"
        " 0.05,0.3 (0.05,0.16: thin shafts)",
    )
    draw.set_defaults(run=_cmd_draw_signs)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``amaze`` and its sub-commands.

    The sub-commands are added in the order that ``amaze --help`` lists them,
    one ``_add_<command>`` function each.
    """
    parser = CommandParser(
        version=True,
        prog="amaze",
        description="Generate, inspect, render and measure AMaze mazes from their strings"
        " (e.g. M4_20x20_C1_l.25_L.25_t.5_T.5).",
    )
    parser.add_argument(
        "--signs",
        action="append",
        default=[],
        metavar="PATH",
        help="register custom sign images: a PNG file or a folder of them (repeatable)",
    )
    commands = parser.add_subparsers(dest="command", required=True, parser_class=CommandParser)
    _add_inspect(commands)
    _add_render(commands)
    _add_stats(commands)
    for name in ("run", "play"):
        _add_run(commands, name)
    _add_inputs(commands)
    _add_suite(commands)
    _add_evaluate(commands)
    _add_interpolate(commands)
    _add_draw_signs(commands)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``amaze``; returns the exit status (0, or 2 for a user mistake)."""

    def body() -> None:
        args = build_parser().parse_args(argv)
        for path in args.signs:
            register_custom_signs(path)
        with warnings.catch_warnings():
            warnings.simplefilter("always")
            warnings.showwarning = _show_warning
            args.run(args)

    return run_command(body)


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    print(f"warning: {message}", file=sys.stderr)


def entry_point() -> NoReturn:
    sys.exit(main())


if __name__ == "__main__":
    entry_point()
