"""A study, run and reported from Python: what ``amaze-experiment run`` and ``report`` do.

A *study* (docs: "Studies and reports") is a grid of trainers x algorithms x
budgets x seeds, written in TOML. Here it is inline text, read by
:func:`experiments.study.parse_study` (:func:`~experiments.study.load_study`
reads a file or a shipped study by name, such as ``"smoke"``). Then:

* :func:`experiments.runner.run_study` runs every run of the grid, each in its
  own worker process, a few at a time, into a folder it can resume later
  (a finished run is never run again);
* :func:`experiments.runner.study_status` and
  :func:`~experiments.runner.format_status` say where the runs stand;
* :func:`experiments.report.write_report` writes ``report.md``, ``runs.csv``
  (one row per run), ``tests.csv`` and ``figures/`` into the folder.

The study compares CMA-ES trained directly on one maze (in its 4 rotations)
with CMA-ES trained on 8 mazes of the same family (domain randomisation, the
study's ``domain-randomisation`` trainer with mazes of our own), at equal
budgets of env steps, 3 seeds each. Every run's final agent is judged on the
same evaluation set: 24 mazes of the family that no run trained on, and the
maze itself, each in its 4 rotations.

Run it::

    python examples/study_from_python.py            # 6 runs of 10 M env steps: about 40 s
    python examples/study_from_python.py --tiny     # 2 runs of 30 k env steps: a smoke test
    python examples/study_from_python.py --out studies/mine   # keep the folder (resumable)

Needs only the project's dependencies.
"""

from __future__ import annotations

import argparse
import csv
import statistics
import tempfile
import time
from pathlib import Path

from experiments.report import write_report
from experiments.runner import format_status, run_study, study_status
from experiments.study import parse_study

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--tiny", action="store_true", help="2 runs of 30 k env steps (tests)")
parser.add_argument("--out", help="the study's folder (default: a temporary one)")
parser.add_argument("--workers", type=int, default=2, help="runs at a time")
args = parser.parse_args()

seeds = 1 if args.tiny else 3
steps = 30_000 if args.tiny else 10_000_000
family = ", ".join(f'"M{100 + i}_10x10_C1"' for i in range(8))  # 8 mazes of one family
STUDY = f"""
name = "direct-vs-family"
description = "CMA-ES on one maze, or on 8 mazes of its family."
seeds = {seeds}
robot = "DD"
trainers = ["direct", "domain-randomisation"]
algorithms = ["cmaes"]

[budgets]
steps = {{ steps = {steps} }}

[options.all]
# every run's evaluation set: this maze and 24 of its family (new seeds), 4 rotations each
evaluation_maze = "M4_10x10_C1"

[options.direct]
mazes = ["M4_10x10_C1"]     # trained on the one maze (in its 4 rotations)

[options.domain-randomisation]
mazes = [{family}]
"""

study = parse_study(STUDY, "the example's study")  # every run's config is checked here
print(f"study {study.name!r}: {len(study.runs)} runs, treatments {', '.join(study.treatments)}")

with tempfile.TemporaryDirectory() as scratch:
    out = Path(args.out or Path(scratch) / "study")
    started = time.perf_counter()
    # progress="off": quiet; "bar" or "lines" show the study's progress on stderr
    status = run_study(study, out, workers=args.workers, progress="off")
    print(f"ran in {time.perf_counter() - started:.1f} s (exit status {status})")
    print(format_status(*study_status(out)))

    report = write_report(out)  # report.md, runs.csv, tests.csv and figures/
    sections = [line[3:] for line in report.read_text().splitlines() if line.startswith("## ")]
    print(f"{report.name}: {'; '.join(sections)}")

    # runs.csv: one row per run, with its final agent's scores on the evaluation set
    with open(out / "runs.csv", newline="") as stream:
        rows = list(csv.DictReader(stream))
    for treatment in study.treatments:
        rates = [
            float(row["eval_set_success_rate"]) for row in rows if row["treatment"] == treatment
        ]
        print(
            f"{treatment}: success on the evaluation set {', '.join(f'{r:.2f}' for r in rates)}"
            f" (median {statistics.median(rates):.2f}, n={len(rates)})"
        )
