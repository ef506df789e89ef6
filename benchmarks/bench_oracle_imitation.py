"""Teach an evolution network the oracle's actions on family mazes; score it on the suites.

    python benchmarks/bench_oracle_imitation.py [--robot CC15] [--hidden 16 [16 ...]] [--pool 5]
        [--pooling mean] [--filters F --stride S] [--iterations 10] [--mazes 64] [--seed 0]
        [--learning-rate-decay 1] [--keep last|best|average [--average-from I]]
        [--guide AGENT [--track] [--teacher-only]]
        [--out FILE.npz] [--networks DIR] [--csv FILE]

:func:`evolution.imitation.imitate` teaches a network of evolution's kind (the
pooled image, the weights shared by the four directions, the
``(tanh(s_E - s_W), tanh(s_N - s_S))`` accelerations) the actions of the
oracle, which knows the way, by DAgger on ``--mazes`` mazes of the paper's
training family (new seeds, never a suite's). After each iteration it prints
the network's success and path progress on 64 validation mazes of the family
and on 32 unseen ones (one episode each). It hands over the last iteration's
network (``--keep last``, the default) or the one with the highest validation
success, then path progress (``--keep best``; the unseen mazes and the suites
play no part in the choice), or the mean of the parameters of the iterations
from ``--average-from`` (default: half the iterations) to the last
(``--keep average``, stochastic weight averaging; the running mean's
validation and unseen-family success are printed after each of those
iterations), and prints that network's success, path progress
and mean R̄ on the paper's suite and on the standard suite (72 episodes each;
the standard suite is what runs and ``amaze evaluate AGENT suite`` report).
``--learning-rate-decay D`` multiplies the learning rate by ``D`` per
iteration. Other robots work too (``--robot H15``, ``--robot DD``: taught the
oracle's directions); ``--pool`` is for image robots, and so are ``--filters``
(a convolutional network: F evolved 3x3 filters slid with ``--stride`` over
the image instead of pooling it, :mod:`evolution.convolution`).

Two uses. A capacity check: a network that drives the suite this way can
represent a solution, and CMA-ES's failure with it is one of search (fitness,
curriculum, budget); one that cannot is too small or sees too little. And a
trainer with a privileged teacher: the teacher knows each maze's solution
while teaching, the agent ``--out`` writes sees only its own inputs; its
results are reported apart from those of RL and evolution, which learn from
rewards alone (docs/robots.md).

``--guide AGENT`` (continuous robots) teaches instead a
:class:`~amaze.evaluation.controllers.GuidedController`'s actions: the robot
steered, by the oracle's law, where the hybrid agent ``AGENT`` (an agent file
of the hybrid robot with the same vision, ``H7`` for ``CC7``, e.g. one evolved
from rewards alone) chooses to go from the image of its cell. That teacher
knows nothing of the way to the goal: a continuous network taught by it
learns continuous control from an agent that learnt the mazes from rewards,
and goes no further than its guide. Printed first: the teacher's own success,
driving alone, on the validation mazes (seconds to measure; a guide whose
teacher fails there cannot teach there, see docs/robots.md) and on the
standard suite; ``--teacher-only`` prints them and stops. ``--track`` keeps
the guide on its own track (``GuidedController(track=True)``): a robot that
strays from the guide's cell is steered back to it by the maze's open walls
instead of the guide being asked again where it strayed, which turns a
memoryless guide round (see docs/robots.md). ``--csv FILE``
writes the run's figures as one row (the network, the teacher, the kept
iteration's, the suites'). ``--networks DIR`` writes every iteration's
network as an agent file, ``DIR/iteration-NN.npz`` (the iterations that the
rule did not hand over, to score or compare afterwards: ``amaze evaluate
DIR/iteration-07.npz suite``).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from amaze.agents.engine import BatchEngine
from amaze.agents.robot import as_robot
from amaze.curriculum.validation import unseen_mazes, validation_mazes
from amaze.errors import AmazeError
from amaze.evaluation.controllers import GuidedController
from amaze.evaluation.policy import run_episodes
from amaze.evaluation.suite import PAPER_TRAINING_MAZE, paper_suite, standard_suite
from amaze.runs.folder import write_rows
from evolution.agent_file import load_agent, save_network_agent
from evolution.config import EvolutionConfigError
from evolution.imitation import KEEP, TEACHER_DAMPING, TEACHER_GAIN, ImitationConfig, imitate
from evolution.networks import NetworkSpec
from evolution.population import PopulationEvaluator

#: Family mazes (apart from the taught and the unseen) that ``--keep best`` selects on.
VALIDATION = 64


def judge(spec: NetworkSpec, mazes: list[str]) -> PopulationEvaluator:
    """An evaluator of ``spec``'s networks on ``mazes`` (compiled once), path progress its
    fitness."""
    return PopulationEvaluator(mazes, spec.robot, fitness="path_progress")


def guided_teacher(spec: NetworkSpec, path: Path, track: bool = False) -> GuidedController:
    """The continuous ``spec`` robot steered where the hybrid agent in ``path`` goes
    (``track``: on the guide's own track, see :class:`GuidedController`)."""
    if spec.robot_info.kind != "continuous":
        raise EvolutionConfigError(f"--guide steers continuous robots (CC), not {spec.robot}")
    guide = load_agent(path)
    teacher = GuidedController(
        spec.robot, guide, gain=TEACHER_GAIN, damping=TEACHER_DAMPING, track=track
    )
    if as_robot(getattr(guide, "robot", "")) != teacher.guide_robot:
        raise EvolutionConfigError(
            f"--guide {path}: a {guide.robot} agent; {spec.robot} needs a guide of robot"
            f" {teacher.guide_robot}"
        )
    return teacher


def teacher_success(spec: NetworkSpec, teacher: GuidedController, mazes: list[str]) -> float:
    """The teacher's success rate on ``mazes`` (one episode per maze), driving alone."""
    results = run_episodes(BatchEngine(mazes, spec.robot, len(mazes)), teacher)
    return float(np.mean(results.success))


def score(
    spec: NetworkSpec, params: np.ndarray, evaluator: PopulationEvaluator
) -> tuple[float, float, float]:
    """Success, path progress and mean R̄ of the network ``params`` on ``evaluator``'s mazes."""
    result = evaluator.evaluate(spec.population(params[None, :]))
    return (
        float(result.success_rate[0]), float(result.fitness[0]),
        float(result.normalized_reward[0]),
    )  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robot", default="CC15")
    parser.add_argument("--hidden", type=int, nargs="*", default=[16], help="hidden layer sizes")
    parser.add_argument(
        "--pool", type=int, help="side of the pooled image grid (image robots; default 5)"
    )
    parser.add_argument("--pooling", default="mean", help="mean or max")
    parser.add_argument(
        "--filters", type=int, default=0, help="3x3 filters instead of pooling (image robots)"
    )
    parser.add_argument("--stride", type=int, help="the filters' stride (default: the spec's)")
    parser.add_argument("--iterations", type=int, default=10)
    parser.add_argument("--mazes", type=int, default=64, help="training family mazes")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--learning-rate-decay", type=float, default=1.0,
        help="the learning rate's factor per iteration (default 1: constant)",
    )  # fmt: skip
    parser.add_argument(
        "--keep", choices=KEEP, default="last",
        help="hand over the last iteration's network, the best on validation mazes, or the"
        " mean of the late iterations' parameters",
    )  # fmt: skip
    parser.add_argument(
        "--average-from", type=int, metavar="I",
        help="with --keep average: the first iteration averaged (default: iterations // 2)",
    )  # fmt: skip
    parser.add_argument(
        "--guide", type=Path, metavar="AGENT",
        help="teach a continuous robot steered where this hybrid agent goes, not the oracle",
    )  # fmt: skip
    parser.add_argument(
        "--teacher-only", action="store_true",
        help="with --guide: print the teacher's success and stop (seconds), teaching nothing",
    )  # fmt: skip
    parser.add_argument(
        "--track", action="store_true",
        help="with --guide: keep the guide on its own track, bring strays back to it",
    )  # fmt: skip
    parser.add_argument("--out", type=Path, help="write the taught network as an agent file")
    parser.add_argument(
        "--networks", type=Path, metavar="DIR",
        help="write every iteration's network as an agent file DIR/iteration-NN.npz",
    )  # fmt: skip
    parser.add_argument("--csv", type=Path, metavar="FILE", help="write the figures to FILE")
    args = parser.parse_args(argv)
    for option, path in (("--out", args.out), ("--csv", args.csv)):
        if path is not None and not path.parent.is_dir():
            print(f"error: {option} {path}: folder {path.parent} does not exist", file=sys.stderr)
            return 2
    if args.networks is not None and not args.networks.is_dir():
        print(f"error: --networks {args.networks}: not a folder", file=sys.stderr)
        return 2
    if args.teacher_only and (args.guide is None or args.out or args.csv or args.networks):
        print("error: --teacher-only checks a --guide's teacher and teaches nothing:"
              " give --guide, and no --out, --networks or --csv", file=sys.stderr)  # fmt: skip
        return 2
    if args.track and args.guide is None:
        print("error: --track keeps a --guide on its track: give --guide", file=sys.stderr)
        return 2
    if args.mazes < 1:
        print(f"error: --mazes {args.mazes}: teach on at least one maze", file=sys.stderr)
        return 2
    try:
        spec = NetworkSpec(
            robot=args.robot, hidden=tuple(args.hidden), pool=args.pool,
            pooling=args.pooling, symmetry="rotations", filters=args.filters,
            stride=args.stride,
        )  # fmt: skip
        config = ImitationConfig(
            iterations=args.iterations, seed=args.seed,
            learning_rate_decay=args.learning_rate_decay, keep=args.keep,
            average_from=args.average_from,
        )  # fmt: skip
        mazes = validation_mazes(PAPER_TRAINING_MAZE, args.mazes, 10_000 + args.seed)
        teacher = None if args.guide is None else guided_teacher(spec, args.guide, args.track)
    except (AmazeError, EvolutionConfigError, ValueError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    family = unseen_mazes(PAPER_TRAINING_MAZE, args.seed)
    drawn = validation_mazes(PAPER_TRAINING_MAZE, VALIDATION + len(mazes) + len(family),
                             20_000 + args.seed)  # fmt: skip
    validation = [maze for maze in drawn if maze not in {*mazes, *family}][:VALIDATION]
    if spec.filters:
        inputs = f"{spec.filters} filters, stride {spec.stride} ({spec.n_inputs} maps' pixels)"
    elif spec.pool is not None:
        inputs = f"pool {spec.pool} ({spec.pooling})"
    else:
        inputs = f"{spec.n_inputs} inputs"
    print(f"{spec.robot}, hidden {list(spec.hidden)}, {inputs}, {spec.n_params} parameters;"
          f" taught on {len(mazes)} family mazes, validated on {len(validation)} others,"
          f" scored on {len(family)} others; hands over the {args.keep} network")  # fmt: skip
    teacher_name = "oracle" if args.guide is None else f"guide {args.guide}"
    if args.track:
        teacher_name += " on its track"
    if teacher is not None:
        teacher_validation = teacher_success(spec, teacher, validation)
        success = teacher_success(spec, teacher, standard_suite().maze_strings())
        print(f"teacher: {args.robot} steered where {args.guide} goes"
              f"{' on its own track' if args.track else ''}; its success on the"
              f" validation mazes {teacher_validation:.3f},"
              f" on the standard suite {success:.3f}")  # fmt: skip
        if args.teacher_only:
            print("--teacher-only: stopped before teaching; --iterations, --keep,"
                  " --average-from and --learning-rate-decay were not used")  # fmt: skip
            return 0
    start = time.perf_counter()
    row: dict[str, object] = {
        "robot": spec.robot, "hidden": " ".join(map(str, spec.hidden)), "pool": spec.pool,
        "pooling": spec.pooling, "filters": spec.filters, "stride": spec.stride,
        "parameters": spec.n_params, "seed": args.seed, "mazes": len(mazes),
        "learning_rate_decay": args.learning_rate_decay, "keep": args.keep,
        "average_from": config.first_averaged if args.keep == "average" else "",
        "iterations": args.iterations, "teacher": teacher_name,
    }  # fmt: skip
    if teacher is not None:
        row.update(teacher_validation_success=teacher_validation, teacher_standard_success=success)
    family_judge = judge(spec, family)
    averaged: list[np.ndarray] = []  # --keep average: the parameters averaged so far

    algorithm = "oracle imitation (DAgger)" if teacher is None else "guided imitation (DAgger)"

    def report(record: dict[str, float], params: np.ndarray) -> None:
        success, progress, _ = score(spec, params, family_judge)
        if args.networks is not None:
            save_network_agent(
                args.networks / f"iteration-{record['iteration']:02.0f}.npz", spec, params,
                algorithm=algorithm, teacher=teacher_name, seed=args.seed, mazes=mazes,
                iteration=int(record["iteration"]),
            )  # fmt: skip
        line = (f"iteration {record['iteration']:2.0f}  beta {record['beta']:.3f}"
                f"  samples {record['samples']:>9.0f}  loss {record['loss']:.4f}"
                f"  validation success {record['validation_success']:.3f}"
                f"  progress {record['validation_progress']:.3f}"
                f"  family success {success:.3f}  progress {progress:.3f}")  # fmt: skip
        if "average_validation_success" in record:
            averaged.append(params)
            mean_success, _, _ = score(spec, np.mean(averaged, axis=0), family_judge)
            line += (f"  | mean of {len(averaged)}: validation"
                     f" {record['average_validation_success']:.3f}"
                     f"  family {mean_success:.3f}")  # fmt: skip
        print(f"{line}  ({time.perf_counter() - start:.0f} s)", flush=True)

    result = imitate(
        spec, mazes, config, validation=validation, teacher=teacher, on_iteration=report
    )
    kept = result.history[result.kept_iteration]
    key = "average_" if args.keep == "average" else ""  # the running mean's record keys
    params = result.params
    family_success, family_progress, _ = score(spec, params, family_judge)
    row.update(
        kept_iteration=result.kept_iteration, samples=int(kept["samples"]), loss=kept["loss"],
        validation_success=kept[f"{key}validation_success"],
        validation_progress=kept[f"{key}validation_progress"],
        family_success=family_success, family_progress=family_progress,
    )  # fmt: skip
    if args.keep == "average":
        print(f"handed over: the mean of the networks after iterations {result.averaged_from}"
              f" to {result.kept_iteration} (average)")  # fmt: skip
    else:
        print(f"handed over: the network after iteration {result.kept_iteration} ({args.keep})")
    for name, suite, prefix in (
        ("paper suite", paper_suite(), "suite"), ("standard suite", standard_suite(), "standard"),
    ):  # fmt: skip
        mazes_played = suite.maze_strings()
        success, progress, reward = score(spec, params, judge(spec, mazes_played))
        print(f"{name} ({len(mazes_played)} episodes): success {success:.3f}"
              f"  path progress {progress:.3f}  mean R̄ {reward:+.3f}")  # fmt: skip
        row.update({
            f"{prefix}_success": success, f"{prefix}_progress": progress,
            f"{prefix}_reward": reward,
        })  # fmt: skip
    row.update(seconds=round(time.perf_counter() - start, 1))
    if args.csv is not None:
        write_rows(args.csv, [row])
        print(f"figures written to {args.csv}")
    if args.out is not None:
        path = save_network_agent(
            args.out, spec, params, algorithm=algorithm, teacher=teacher_name,
            seed=args.seed, mazes=mazes,
        )  # fmt: skip
        knew = "knew each maze's solution" if teacher is None else "followed the guide"
        print(f"taught network written to {path} (its teacher {knew})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
