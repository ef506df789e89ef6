"""Speed of one neuroevolution generation: a population of MLPs played on the batch engine.

A population of ``--population`` tanh MLPs (DD robot by default, hidden
layers ``--hidden``, seeded random weights as evolution starts from) is
evaluated with :class:`evolution.population.PopulationEvaluator`:

* on the standard evaluation suite (18 mazes x 4 rotations = 72 episodes per
  individual): wall-clock time of one generation; goal for 64 DD policies:
  at most 2 s;
* on the paper's training maze in its 4 rotations (4 episodes per individual).

Policy-steps/s counts the useful environment steps (the steps of the scored
episodes, ``PopulationResult.env_steps``, as an RL learner would count them)
per second of evaluation, network and environment together; goal on DD: at
least 5 million per second. The mazes are prepared once (as every run does);
that time is printed separately. Figures are medians of ``--repeats`` runs
after one warm-up (which compiles the kernels on a first run).

``--network JSON`` (repeatable) measures networks of other kinds in the same
run, each the ``--hidden`` network with the given spec fields, e.g. the pooled
network against convolutional ones on ``H15``::

    python benchmarks/bench_evolution.py --robot H15 --network '{"symmetry": "rotations"}' \
        --network '{"symmetry": "rotations", "filters": 4}'

Usage: ``python benchmarks/bench_evolution.py [--repeats 7] [--population 64]
[--hidden 16] [--robot DD] [--network JSON]... [--threads auto|on|off]``
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import numpy as np

from amaze.evaluation.suite import PAPER_TRAINING_MAZE, standard_suite
from amaze.maze import rotations
from evolution.networks import NetworkSpec
from evolution.population import PopulationEvaluator


def _hidden(text: str) -> tuple[int, ...]:
    return tuple(int(width) for width in text.split(",") if width.strip())


def measure(
    name: str, evaluator: PopulationEvaluator, spec: NetworkSpec, args: argparse.Namespace
) -> None:
    parallel = {"auto": None, "on": True, "off": False}[args.threads]
    params = spec.initial_params(np.random.default_rng(0), args.population)
    population = spec.population(params, parallel=parallel)
    result = evaluator.evaluate(population)  # warm-up (compilation on a first run)
    times = []
    for _ in range(args.repeats):
        started = time.perf_counter()
        result = evaluator.evaluate(population)
        times.append(time.perf_counter() - started)
    median = statistics.median(times)
    agent_steps = evaluator.engine(args.population).n_agents * int(
        result.per_episode("steps").max()
    )
    print(
        f"{name}: {args.population} x {evaluator.n_episodes} episodes, median"
        f" {median * 1e3:.0f} ms per generation (min {min(times) * 1e3:.0f},"
        f" max {max(times) * 1e3:.0f}; {args.repeats} repeats)"
    )
    print(
        f"  {result.env_steps} useful steps: {result.env_steps / median / 1e6:.2f} M policy-steps/s"
        f" ({agent_steps} agent-steps stepped by the batch; best R̄ {result.fitness.max():+.3f})"
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--population", type=int, default=64)
    parser.add_argument("--hidden", type=_hidden, default=(16,), help="widths, e.g. 16 or 32,32")
    parser.add_argument("--robot", default="DD", help="DD, or an image robot such as H15")
    parser.add_argument(
        "--network", type=json.loads, action="append",
        help='spec fields of a network to measure (repeatable), e.g. \'{"filters": 4}\'',
    )  # fmt: skip
    parser.add_argument(
        "--threads", choices=("auto", "on", "off"), default="auto",
        help="multi-threaded forward pass: by load (auto), always or never",
    )  # fmt: skip
    args = parser.parse_args(argv)

    started = time.perf_counter()
    robot = NetworkSpec(args.robot).robot
    suite = PopulationEvaluator(standard_suite().maze_strings(), robot)
    paper = PopulationEvaluator(rotations(PAPER_TRAINING_MAZE), robot)
    print(f"mazes prepared in {time.perf_counter() - started:.2f} s (once per run)")
    for fields in args.network or [{}]:
        spec = NetworkSpec.from_dict({"robot": args.robot, "hidden": list(args.hidden), **fields})
        print(f"network {spec.to_dict()}: {spec.n_params} parameters")
        measure("standard suite", suite, spec, args)
        measure("paper training maze x 4 rotations", paper, spec, args)


if __name__ == "__main__":
    main()
