"""Maze metrics throughput (mazes per second, median of repeats).

Computes every complexity metric (:func:`amaze.maze.metrics.compute_metrics`) of complex
mazes ``M<seed>_<n>x<n>_C1_l.25_L.25_t.5_T.5`` for consecutive seeds, at 10x10 and
20x20. The mazes are generated before the timing; the per-cell sign table that a
maze builds on first use (``Maze.cell_signs``) is cleared before every repeat, so
it is counted, as the reference counts its own sign map.

With ``--reference-python PATH`` the same workload also runs in the reference
library amaze-benchmarker 1.0 (``Simulation.compute_metrics(maze,
InputType.DISCRETE, 15)``), installed in a separate throw-away virtual environment
(never a dependency of this project); the ratio is printed, and the metrics of the
first mazes are compared with ours::

    python3 -m venv /tmp/refvenv && /tmp/refvenv/bin/pip install amaze-benchmarker==1.0
    python benchmarks/bench_metrics.py --reference-python /tmp/refvenv/bin/python
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
from pathlib import Path
from typing import Any

TEMPLATE = "M{seed}_{size}x{size}_C1_l.25_L.25_t.5_T.5"
MIN_REPEATS = 5

REFERENCE_SCRIPT = """
import json, logging, statistics, sys, time
logging.disable(logging.CRITICAL)
from amaze import InputType, Maze, Simulation
size, count, repeats, n_check = (int(a) for a in sys.argv[1:5])
mazes = [Maze.from_string(f"M{s}_{size}x{size}_C1_l.25_L.25_t.5_T.5") for s in range(count)]
rates = []
for _ in range(repeats):
    start = time.perf_counter()
    for maze in mazes:
        Simulation.compute_metrics(maze, InputType.DISCRETE, 15)
    rates.append(count / (time.perf_counter() - start))
check = []
for maze in mazes[:n_check]:
    m = Simulation.compute_metrics(maze, InputType.DISCRETE, 15)
    check.append({str(getattr(k, "name", k)).lower(): v for k, v in m.items()})
print(json.dumps({"rate": statistics.median(rates), "metrics": check}))
"""


def _mazes(size: int, count: int) -> list[Any]:
    from amaze.maze.maze import Maze

    return [Maze.from_string(TEMPLATE.format(seed=s, size=size)) for s in range(count)]


def ours(size: int, count: int, repeats: int) -> tuple[float, list[dict[str, Any]]]:
    """Median mazes/s of :func:`compute_metrics`, and the metrics (reference layout)."""
    from amaze.maze.metrics import compute_metrics

    mazes = _mazes(size, count)
    compute_metrics(mazes[0])  # first-call costs (caches) outside the timing
    rates = []
    for _ in range(repeats):
        for maze in mazes:
            vars(maze).pop("cell_signs", None)  # rebuilt on use: counted in the timing
        start = time.perf_counter()
        for maze in mazes:
            compute_metrics(maze)
        rates.append(count / (time.perf_counter() - start))
    return statistics.median(rates), [compute_metrics(m).to_reference_dict() for m in mazes]


def reference(
    python: str, size: int, count: int, repeats: int, n_check: int
) -> tuple[float, list[dict[str, Any]]]:
    """The same workload in the reference library (a subprocess in a scratch folder)."""
    env = {**os.environ, "QT_QPA_PLATFORM": "offscreen", "PYTHONHASHSEED": "0"}
    with tempfile.TemporaryDirectory() as scratch:  # the reference writes ./resources
        result = subprocess.run(
            [python, "-c", REFERENCE_SCRIPT, str(size), str(count), str(repeats), str(n_check)],
            cwd=scratch,
            env=env,
            capture_output=True,
            text=True,
            check=False,
        )
    if result.returncode:
        sys.exit(f"the reference run failed:\n{result.stderr}")
    data = json.loads(result.stdout.strip().splitlines()[-1])
    return data["rate"], data["metrics"]


def _flatten(metrics: dict[str, Any], prefix: str = "") -> dict[str, float]:
    flat: dict[str, float] = {}
    for key, value in metrics.items():
        if isinstance(value, dict):
            flat.update(_flatten(value, f"{prefix}{key}."))
        else:
            flat[prefix + key] = float(value)
    return flat


def largest_difference(a: list[dict[str, Any]], b: list[dict[str, Any]]) -> float:
    """The largest absolute difference between two lists of metrics dictionaries."""
    worst = 0.0
    for x, y in zip(a, b, strict=False):
        fx, fy = _flatten(x), _flatten(y)
        worst = max([worst, *(abs(fx[k] - fy[k]) for k in fx.keys() & fy.keys())])
    return worst


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        epilog="The mazes are generated before the timing; only the metrics are timed.",
    )
    parser.add_argument("--sizes", type=int, nargs="+", default=[10, 20], help="maze sides")
    parser.add_argument("--count", type=int, default=300, help="mazes per repeat (default 300)")
    parser.add_argument(
        "--repeats", type=int, default=7, help=f"timed repeats, at least {MIN_REPEATS} (default 7)"
    )
    parser.add_argument(
        "--reference-python",
        metavar="PATH",
        help="python of a virtual environment with amaze-benchmarker 1.0, for the ratio",
    )
    parser.add_argument(
        "--check",
        type=int,
        default=20,
        help="with --reference-python: compare the metrics of this many mazes (default 20)",
    )
    args = parser.parse_args(argv)
    if args.repeats < MIN_REPEATS:
        parser.error(f"--repeats must be at least {MIN_REPEATS}")
    if args.count < 1:
        parser.error("--count must be positive")
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    warnings.simplefilter("ignore")

    print(f"metrics throughput, {args.count} mazes x {args.repeats} repeats (median), mazes/s")
    header = f"{'maze':<34} {'amaze':>10}"
    if args.reference_python:
        header += f" {'reference':>10} {'ratio':>7} {'max |diff|':>11}"
    print(header)
    for size in args.sizes:
        rate, values = ours(size, args.count, args.repeats)
        line = f"{TEMPLATE.format(seed='<s>', size=size):<34} {rate:>10.0f}"
        if args.reference_python:
            n_check = min(args.check, args.count)
            ref_rate, ref_values = reference(
                args.reference_python, size, args.count, args.repeats, n_check
            )
            diff = largest_difference(values[:n_check], ref_values)
            line += f" {ref_rate:>10.0f} {rate / ref_rate:>6.1f}x {diff:>11.1e}"
        print(line, flush=True)


if __name__ == "__main__":
    main()
