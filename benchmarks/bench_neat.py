"""Where a NEAT-like generation spends its time, and policy-steps/s overall and in evaluation.

Two measurements:

* **generations** (default): a :class:`~evolution.neat.NeatAlgorithm` of
  ``--population`` genomes (DD robot, default options otherwise) is driven
  through ``--generations`` generations of ask, compile, evaluate, tell on a
  :class:`~evolution.population.PopulationEvaluator`, each phase timed; the
  phases of ``tell`` (hall of fame, speciation, statistics, stagnation and
  offspring allotment, breeding: selection, crossover and mutation) are timed
  by wrapping the functions the algorithm calls. The first ``--warmup``
  generations are left out (the first one compiles or loads the numba kernels;
  genomes grow over a run, so later generations show the costs that grow with
  them); the figures are medians over the remaining generations. Maze sets
  (``--mazes``, several allowed): ``suite16``, the first 16 mazes of the
  standard evaluation suite in their 4 rotations (64 episodes per genome);
  ``suite``, the whole suite (18 x 4 = 72); ``paper``, the paper's training
  maze in its 4 rotations (4 episodes: the default of ``amaze-evolve``).
* **--e2e SECONDS**: the real ``amaze-evolve --algo neat`` command on each
  maze set, with a wall-clock budget, as a user runs it (start-up, validation
  of the champion on the suite, checkpoints, progress rows, figures): the
  process's wall-clock time, the run's training seconds and evaluation seconds
  (``summary.json``) and the policy-steps/s against each.

Policy-steps are the steps of the scored episodes (``PopulationResult.env_steps``).
"Outside" is the share of a generation's time not spent playing episodes.
Phases are medians over the generations; the throughput is also given over
the whole window (all steps over all seconds), which counts the garbage
collector's occasional full collections that medians leave out. Generations
run with the set-up's objects frozen out of the collector, as a run's
training does (:func:`amaze.runs.lifecycle.frozen_heap`); ``--gc-all``
leaves them in.

Usage: ``python benchmarks/bench_neat.py [--population 256] [--generations 40]
[--warmup 10] [--mazes suite16 suite paper] [--threads auto|on|off] [--seed 0]
[--gc-all] [--e2e SECONDS]``
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import json
import statistics
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numba

import evolution.neat.algorithm as neat_algorithm
from amaze.evaluation.suite import PAPER_TRAINING_MAZE, standard_suite
from amaze.runs.lifecycle import frozen_heap
from evolution.neat import NeatAlgorithm, NeatConfig
from evolution.population import PopulationEvaluator

#: Phases of ``tell`` and the functions of :mod:`evolution.neat.algorithm` they time.
TELL_PHASES = {
    "speciate": "speciation",
    "update_progress": "speciation",
    "shared_fitness": "allotment",
    "allot_offspring": "allotment",
    "remove_stagnant": "allotment",
}
COLUMNS = (
    "ask",
    "compile",
    "evaluate",
    "hall of fame",
    "speciation",
    "statistics",
    "allotment",
    "breeding",
    "tell other",
)


def maze_set(name: str) -> list[str]:
    """The mazes of a named set (each is played in its 4 rotations)."""
    if name == "suite16":
        return standard_suite().maze_strings(rotations=False)[:16]
    if name == "suite":
        return standard_suite().maze_strings(rotations=False)
    if name == "paper":
        return [PAPER_TRAINING_MAZE]
    raise SystemExit(f"error: unknown maze set {name!r} (suite16, suite, paper)")


class Timers:
    """Seconds per phase of the current generation."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = defaultdict(float)

    def wrap(self, phase: str, function: Callable[..., Any]) -> Callable[..., Any]:
        @functools.wraps(function)
        def timed(*args: Any, **kwargs: Any) -> Any:
            started = time.perf_counter()
            try:
                return function(*args, **kwargs)
            finally:
                self.seconds[phase] += time.perf_counter() - started

        return timed


def instrument(algorithm: NeatAlgorithm, timers: Timers) -> None:
    """Time the phases of ``algorithm.tell`` (wrapping what it calls; results unchanged)."""
    for name, phase in TELL_PHASES.items():
        setattr(neat_algorithm, name, timers.wrap(phase, getattr(neat_algorithm, name)))
    algorithm._reproduce = timers.wrap("breeding", algorithm._reproduce)
    algorithm._record = timers.wrap("statistics", algorithm._record)
    algorithm.hall_of_fame.update = timers.wrap("hall of fame", algorithm.hall_of_fame.update)


def generations(name: str, args: argparse.Namespace, parallel: bool | None) -> None:
    """Time ``args.generations`` generations on maze set ``name``; print the medians."""
    started = time.perf_counter()
    evaluator = PopulationEvaluator(
        maze_set(name), "DD", rotations=True, n_policies=args.population
    )
    prepared = time.perf_counter() - started
    config = NeatConfig(population_size=args.population)
    algorithm = NeatAlgorithm(config, "DD", seed=args.seed)
    timers = Timers()
    instrument(algorithm, timers)
    rows = []
    with contextlib.nullcontext() if args.gc_all else frozen_heap():
        for _ in range(args.generations):
            rows.append(_generation(algorithm, evaluator, timers, parallel))
    report(name, args, evaluator, algorithm, rows, prepared)


def _generation(
    algorithm: NeatAlgorithm,
    evaluator: PopulationEvaluator,
    timers: Timers,
    parallel: bool | None,
) -> dict[str, float]:
    """One generation, timed by phase."""
    timers.seconds.clear()
    t0 = time.perf_counter()
    genomes = algorithm.ask()
    t1 = time.perf_counter()
    policy = algorithm.population_policy(genomes)
    policy.parallel = parallel
    t2 = time.perf_counter()
    result = evaluator.evaluate(policy)
    t3 = time.perf_counter()
    algorithm.tell(genomes, result.fitness)
    t4 = time.perf_counter()
    row = dict(timers.seconds)
    row.update(ask=t1 - t0, compile=t2 - t1, evaluate=t3 - t2, total=t4 - t0)
    row["tell other"] = (t4 - t3) - sum(row.get(c, 0.0) for c in COLUMNS[3:-1])
    row["steps"] = result.env_steps
    return row


def report(
    name: str,
    args: argparse.Namespace,
    evaluator: PopulationEvaluator,
    algorithm: NeatAlgorithm,
    rows: list[dict[str, float]],
    prepared: float,
) -> None:
    """Print the medians of the phases and the throughput of generations after the warm-up."""
    window = rows[args.warmup :]
    stats = algorithm.stats()
    print(
        f"\n{name}: {args.population} genomes x {evaluator.n_episodes} episodes,"
        f" generations {args.warmup + 1}-{args.generations} ({len(window)}; mazes prepared in"
        f" {prepared:.2f} s; first generation {rows[0]['total']:.2f} s);"
        f" at the end {stats.get('connections', 0):.1f} enabled connections,"
        f" {stats.get('hidden', 0):.2f} hidden nodes, {stats.get('n_species', 0):.0f} species"
    )
    medians = {c: statistics.median(r.get(c, 0.0) for r in window) for c in (*COLUMNS, "total")}
    for column in COLUMNS:
        print(
            f"  {column:<13}{medians[column] * 1e3:9.2f} ms"
            f"  {100 * medians[column] / medians['total']:5.1f} %"
        )
    print(f"  {'total':<13}{medians['total'] * 1e3:9.2f} ms")
    overall = [r["steps"] / r["total"] for r in window]
    during = [r["steps"] / r["evaluate"] for r in window]
    outside = [1 - r["evaluate"] / r["total"] for r in window]
    print(
        f"  policy-steps/s: {statistics.median(overall) / 1e6:.2f} M overall,"
        f" {statistics.median(during) / 1e6:.2f} M during evaluation"
        f" (min-max overall {min(overall) / 1e6:.2f}-{max(overall) / 1e6:.2f} M);"
        f" outside evaluation {100 * statistics.median(outside):.1f} %"
        f" (median {statistics.median(r['steps'] for r in window):.0f} steps per generation)"
    )
    steps = sum(r["steps"] for r in window)
    total = sum(r["total"] for r in window)
    evaluation = sum(r["evaluate"] for r in window)
    print(
        f"  whole window: {steps / total / 1e6:.2f} M overall, {steps / evaluation / 1e6:.2f} M"
        f" during evaluation, outside evaluation {100 * (1 - evaluation / total):.1f} %"
    )


def end_to_end(name: str, args: argparse.Namespace) -> None:
    """One ``amaze-evolve --algo neat`` process on maze set ``name``; print its figures."""
    mazes = maze_set(name)
    with tempfile.TemporaryDirectory() as scratch:
        out = Path(scratch) / "run"
        command = [
            sys.executable, "-m", "evolution.cli", "--algo", "neat", "--seed", str(args.seed),
            "--population-size", str(args.population), "--budget-seconds", str(args.e2e),
            "--mazes", ",".join(mazes), "--out", str(out), "--no-progress",
        ]  # fmt: skip
        started = time.perf_counter()
        subprocess.run(command, check=True, capture_output=True, text=True)
        wall = time.perf_counter() - started
        summary = json.loads((out / "summary.json").read_text())
    steps, seconds = summary["env_steps"], summary["seconds"]
    evaluation = summary["evaluation_seconds"]
    print(
        f"\namaze-evolve on {name} ({len(mazes)} mazes x 4 rotations), population"
        f" {args.population}, --budget-seconds {args.e2e}: {summary['generations']} generations,"
        f" {steps} steps; process {wall:.1f} s, training {seconds:.1f} s, evaluation"
        f" {evaluation:.1f} s\n  policy-steps/s: {steps / wall / 1e6:.2f} M per process second,"
        f" {steps / seconds / 1e6:.2f} M per training second,"
        f" {steps / evaluation / 1e6:.2f} M per evaluation second;"
        f" outside evaluation {100 * (1 - evaluation / seconds):.1f} % of training"
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--population", type=int, default=256)
    parser.add_argument("--generations", type=int, default=40)
    parser.add_argument("--warmup", type=int, default=10, help="generations left out")
    parser.add_argument("--mazes", nargs="+", default=["suite16", "suite"])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--threads", choices=("auto", "on", "off"), default="auto",
        help="multi-threaded forward pass: by load (auto), always or never",
    )  # fmt: skip
    parser.add_argument("--gc-all", action="store_true", help="freeze no object (see above)")
    parser.add_argument("--e2e", type=float, metavar="SECONDS", help="time amaze-evolve runs")
    args = parser.parse_args(argv)
    if not 0 <= args.warmup < args.generations:
        raise SystemExit("error: --warmup must be below --generations")
    print(f"NEAT-like, DD robot, seed {args.seed}, numba threads {numba.get_num_threads()}")
    for name in args.mazes:
        if args.e2e:
            end_to_end(name, args)
        else:
            generations(name, args, {"auto": None, "on": True, "off": False}[args.threads])


if __name__ == "__main__":
    main()
