"""Population evaluation on Ray actors: overhead, scaling, and a killed actor.

CMA-ES generations (ask, evaluate, tell) of MLP policies (8 -> 16 -> 4, tanh;
DD robot) on the standard evaluation suite (18 mazes x 4 rotations = 72
episodes per individual), with the local backend (this process, numba's
threads) and with :class:`evolution.backends.RayBackend` on N actors (one
CPU, one numba thread each). Figures are generations per second, medians of
``--repeats`` timings of ``--generations`` generations each, after one
warm-up generation (actors starting, kernels compiling, the suite read from
the object store); ``eval ms`` is the median evaluation time of a generation
and ``other ms`` the rest (CMA-ES's ask and tell in this process). Every
mode starts CMA-ES from the same seed, and the
script checks that every mode's fitness values are bit-identical to the
local backend's.

Modes:

* ``overhead``: local, then Ray with each of ``--actors`` (default 1,2) at
  ``--populations`` (default 64);
* ``scaling``: the same over actors 1,2,4,8,16 and populations 64..1024 by
  default, with the speed-up over one actor and over the local backend;
* ``failure``: one generation of ``--populations`` individuals on
  ``--actors`` actors during which one actor's process is killed (SIGKILL)
  ``--kill-after`` seconds in; prints whether the result equals the local
  backend's, the generation's time and the actor's new process id.

The cluster is a private one on this machine unless ``--address`` names one;
its CPUs are ``--cpus`` (default: all cores).

Usage: ``python benchmarks/bench_ray.py overhead|scaling|failure [--actors 1,2]
[--populations 64] [--generations 5] [--repeats 3] [--cpus N] [--address ADDR]``
"""

from __future__ import annotations

import argparse
import os
import signal
import statistics
import threading
import time

import numpy as np

from amaze.evaluation.suite import standard_suite
from evolution.algorithms import make_algorithm
from evolution.backends import Backend, LocalBackend, RayBackend

NETWORK = {"hidden": [16], "activation": "tanh"}


def _integers(text: str) -> list[int]:
    return [int(value) for value in text.split(",") if value.strip()]


def generations(backend: Backend, population: int, count: int, mazes: list[str]) -> tuple:
    """Seconds of each generation and of its evaluation (warm-up excluded), first fitness."""
    algorithm = make_algorithm(
        "cmaes", {"network": NETWORK, "population_size": population}, "DD", 0
    )
    evaluator = backend.evaluator(mazes, "DD")
    first = None
    times, evaluations = [], []
    for _ in range(count + 1):
        started = time.perf_counter()
        candidates = algorithm.ask()
        result = evaluator.evaluate(algorithm.population_policy(candidates))
        algorithm.tell(candidates, result.fitness)
        times.append(time.perf_counter() - started)
        evaluations.append(result.seconds)
        if first is None:
            first = result.fitness.copy()
    return times[1:], evaluations[1:], first  # the first generation warms up


def measure(backend: Backend, population: int, args: argparse.Namespace, mazes: list[str]):
    """(generations per second, median seconds of evaluation, the first generation's fitness)."""
    per_generation, per_evaluation = [], []
    first = None
    for _ in range(args.repeats):
        times, evaluations, fitness = generations(backend, population, args.generations, mazes)
        per_generation.append(statistics.median(times))
        per_evaluation.append(statistics.median(evaluations))
        first = fitness if first is None else first
    return 1.0 / statistics.median(per_generation), statistics.median(per_evaluation), first


def table(args: argparse.Namespace, mazes: list[str]) -> None:
    print(
        f"{'population':>10} {'backend':>10} {'gen/s':>8} {'eval ms':>8} {'other ms':>8}"
        f" {'vs 1 actor':>10} {'vs local':>9} {'identical':>9}"
    )
    for population in args.populations:
        local_rate, local_eval, reference = measure(LocalBackend(), population, args, mazes)
        print(
            f"{population:>10} {'local':>10} {local_rate:>8.2f} {local_eval * 1e3:>8.0f}"
            f" {(1 / local_rate - local_eval) * 1e3:>8.0f} {'':>10} {1:>9.2f} {'':>9}"
        )
        one_actor = None
        for actors in args.actors:
            with RayBackend(actors=actors, address=args.address) as backend:
                rate, evaluation, fitness = measure(backend, population, args, mazes)
            one_actor = rate if actors == args.actors[0] else one_actor
            same = "yes" if np.array_equal(fitness, reference) else "NO"
            print(
                f"{population:>10} {f'{actors} actors':>10} {rate:>8.2f} {evaluation * 1e3:>8.0f}"
                f" {(1 / rate - evaluation) * 1e3:>8.0f} {rate / one_actor:>10.2f}"
                f" {rate / local_rate:>9.2f} {same:>9}",
                flush=True,
            )


def failure(args: argparse.Namespace, mazes: list[str]) -> None:
    population, actors = args.populations[0], args.actors[-1]
    algorithm = make_algorithm(
        "cmaes", {"network": NETWORK, "population_size": population}, "DD", 0
    )
    policy = algorithm.population_policy(algorithm.ask())
    reference = LocalBackend().evaluator(mazes, "DD").evaluate(policy)
    with RayBackend(actors=actors, address=args.address) as backend:
        evaluator = backend.evaluator(mazes, "DD")
        evaluator.evaluate(policy)  # warm-up: actors started, suite read
        started = time.perf_counter()
        evaluator.evaluate(policy)
        normal = time.perf_counter() - started
        victim = backend.actor_pids()[0]
        killer = threading.Timer(args.kill_after, os.kill, (victim, signal.SIGKILL))
        started = time.perf_counter()
        killer.start()
        result = evaluator.evaluate(policy)
        seconds = time.perf_counter() - started
        killer.join()
        after = backend.actor_pids()[0]
    same = np.array_equal(result.fitness, reference.fitness) and (
        result.env_steps == reference.env_steps
    )
    print(
        f"{population} individuals on {actors} actors: a generation takes {normal:.2f} s;"
        f" actor {victim} killed {args.kill_after:.2f} s into the next one, which took"
        f" {seconds:.2f} s; the actor now runs as process {after};"
        f" result identical to the local backend's: {'yes' if same else 'NO'}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("mode", choices=("overhead", "scaling", "failure"))
    parser.add_argument("--actors", type=_integers)
    parser.add_argument("--populations", type=_integers)
    parser.add_argument("--generations", type=int, default=5)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--cpus", type=int, default=os.cpu_count())
    parser.add_argument("--address")
    parser.add_argument("--kill-after", type=float, default=0.3)
    args = parser.parse_args()
    defaults = {
        "overhead": ([1, 2], [64]),
        "scaling": ([1, 2, 4, 8, 16], [64, 256, 1024]),
        "failure": ([2], [256]),
    }[args.mode]
    args.actors = args.actors or defaults[0]
    args.populations = args.populations or defaults[1]

    import ray

    if args.address is None:
        ray.init(num_cpus=args.cpus, include_dashboard=False, logging_level="warning")
    mazes = standard_suite().maze_strings()
    print(
        f"CMA-ES, MLP 8-16-4 (DD), standard suite ({len(mazes)} episodes per individual);"
        f" {os.cpu_count()} cores, Ray CPUs {int(ray.cluster_resources().get('CPU', 0))},"
        f" medians of {args.repeats} x {args.generations} generations"
    )
    if args.mode == "failure":
        failure(args, mazes)
    else:
        table(args, mazes)
    ray.shutdown()


if __name__ == "__main__":
    main()
