"""Maze generation throughput (mazes per second, median of repeats).

Generates complex mazes ``M<seed>_<n>x<n>_C1_l.25_L.25_t.5_T.5`` for consecutive
seeds, from their parsed specs (parsing excluded), at 10x10 and 20x20.

With ``--reference-python PATH`` the same workload also runs in the reference
library amaze-benchmarker 1.0, installed in a separate throw-away virtual
environment (never a dependency of this project), for a side-by-side figure::

    python3 -m venv /tmp/refvenv && /tmp/refvenv/bin/pip install amaze-benchmarker==1.0
    python benchmarks/bench_generation.py --reference-python /tmp/refvenv/bin/python

``--whole-process N`` also times what a user waits for: a fresh process that
generates ``N`` complex 20x20 mazes and computes their metrics, ``amaze stats -``
here and ``Maze.from_string`` + ``Simulation.compute_metrics`` in the reference
(wall-clock from start to exit, interpreter and imports included, median of
``--repeats``). It also prints the fixed part of ours: starting Python and
importing the command, and loading the compiled generator's machine code
(numba's cache) for the first maze.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
import warnings

TEMPLATE = "M{seed}_{size}x{size}_C1_l.25_L.25_t.5_T.5"

REFERENCE_SCRIPT = """
import json, logging, statistics, sys, time
logging.disable(logging.CRITICAL)
from amaze import Maze
size, count, repeats = (int(a) for a in sys.argv[1:4])
template = "M{}_{}x{}_C1_l.25_L.25_t.5_T.5"
specs = [Maze.BuildData.from_string(template.format(s, size, size)) for s in range(count)]
rates = []
for _ in range(repeats):
    start = time.perf_counter()
    for spec in specs:
        Maze.generate(spec, warnings=False)
    rates.append(count / (time.perf_counter() - start))
print(json.dumps(statistics.median(rates)))
"""


def ours(size: int, count: int, repeats: int) -> float:
    from amaze.maze.maze import Maze
    from amaze.maze.spec import MazeSpec

    specs = [MazeSpec.from_string(TEMPLATE.format(seed=s, size=size)) for s in range(count)]
    Maze.generate(specs[0])  # compile (or load the compiled cache) outside the timing
    rates = []
    for _ in range(repeats):
        start = time.perf_counter()
        for spec in specs:
            Maze.generate(spec)
        rates.append(count / (time.perf_counter() - start))
    return statistics.median(rates)


def reference(python: str, size: int, count: int, repeats: int) -> float:
    env = {**os.environ, "QT_QPA_PLATFORM": "offscreen", "KGD_AMAZE_NOCACHE": "1"}
    with tempfile.TemporaryDirectory() as scratch:  # the reference writes ./resources
        result = subprocess.run(
            [python, "-c", REFERENCE_SCRIPT, str(size), str(count), str(repeats)],
            cwd=scratch,
            env=env,
            capture_output=True,
            text=True,
            check=True,
        )
    return json.loads(result.stdout.strip().splitlines()[-1])


WHOLE_REFERENCE_SCRIPT = """
import logging, sys
logging.disable(logging.CRITICAL)
from amaze import InputType, Maze, Simulation
for line in sys.stdin:
    maze = Maze.from_string(line.strip())
    maze.stats()
    Simulation.compute_metrics(maze, InputType.DISCRETE, 15)
"""

FIRST_MAZE_SCRIPT = """
import sys, time
start = time.perf_counter()
import amaze.cli.main
imported = time.perf_counter()
from amaze.maze.maze import Maze
Maze.from_string(sys.argv[1])
print(imported - start, time.perf_counter() - imported)
"""


def _wall_clock(command: list[str], stdin: str, repeats: int, **kwargs: object) -> float:
    """Median seconds from start to exit of ``command`` fed ``stdin``."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        subprocess.run(
            command, input=stdin, text=True, check=True, stdout=subprocess.DEVNULL, **kwargs
        )
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def whole_process(count: int, repeats: int, reference_python: str | None) -> None:
    """Print the whole-process times of ``amaze stats`` (and the reference) on ``count`` mazes."""
    specs = "".join(TEMPLATE.format(seed=s, size=20) + "\n" for s in range(count))
    stats = [sys.executable, "-m", "amaze", "stats", "-"]
    _wall_clock(stats, specs, 1)  # numba's cache written if missing, files in the page cache
    ours = _wall_clock(stats, specs, repeats)
    fixed = [
        subprocess.run(
            [sys.executable, "-c", FIRST_MAZE_SCRIPT, TEMPLATE.format(seed=0, size=20)],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.split()
        for _ in range(repeats)
    ]
    imports = statistics.median(float(f[0]) for f in fixed)
    first = statistics.median(float(f[1]) for f in fixed)
    line = f"whole process, {count} complex 20x20 mazes: amaze stats {ours:.2f} s"
    if reference_python:
        env = {**os.environ, "QT_QPA_PLATFORM": "offscreen", "PYTHONHASHSEED": "0"}
        with tempfile.TemporaryDirectory() as scratch:
            ref = _wall_clock(
                [reference_python, "-c", WHOLE_REFERENCE_SCRIPT],
                specs,
                repeats,
                cwd=scratch,
                env=env,
            )
        line += f"   reference {ref:.2f} s   ratio {ref / ours:5.1f}x"
    print(line)
    print(
        f"  of ours, fixed: Python start and imports {imports:.2f} s,"
        f" first maze (loading the compiled code) {first:.2f} s",
        flush=True,
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[10, 20])
    parser.add_argument("--count", type=int, default=1000, help="mazes per repeat")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--reference-python", metavar="PATH", help="python of a reference venv")
    parser.add_argument(
        "--whole-process",
        type=int,
        nargs="*",
        metavar="N",
        help="also time whole processes generating and measuring N mazes (default 1000)",
    )
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    print(f"maze generation, {args.count} mazes x {args.repeats} repeats, median")
    for size in args.sizes:
        rate = ours(size, args.count, args.repeats)
        line = f"{size:3d}x{size:<3d} amaze-evo {rate:10.0f} mazes/s"
        if args.reference_python:
            ref = reference(args.reference_python, size, min(args.count, 300), args.repeats)
            line += f"   reference {ref:8.0f} mazes/s   ratio {rate / ref:5.1f}x"
        print(line, flush=True)
    for count in [1000] if args.whole_process == [] else args.whole_process or []:
        whole_process(count, args.repeats, args.reference_python)


if __name__ == "__main__":
    sys.exit(main())
