"""Synthetic study folders for the report's tests: summaries and anytime evaluations by formula."""

from __future__ import annotations

import csv
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from amaze.runs.anytime import EVALUATION_FIELDS, EVALUATIONS_FILE
from amaze.runs.folder import write_json
from experiments.runner import STATE_FILE, STUDY_FILE, StudyFolder
from experiments.study import PlannedRun, parse_study

#: A run's ``summary.json`` from its planned run.
Summary = Callable[[PlannedRun], dict[str, Any]]
#: A run's ``evaluations.csv`` rows from its planned run (``None``: no file).
Evaluations = Callable[[PlannedRun], Sequence[dict[str, Any]] | None]


def evaluation_rows(
    success: Sequence[float],
    rbar: Sequence[float],
    steps: Sequence[float],
    seconds: Sequence[float],
    digest: str = "0123456789abcdef",
    points: Sequence[int] | None = None,
) -> list[dict[str, Any]]:
    """Rows of an ``evaluations.csv`` at ``points`` (default ``1 .. len(success)``)."""
    points = list(points or range(1, len(success) + 1))
    rows = []
    for index, point in enumerate(points):
        rows.append(
            {
                "point": point,
                "fraction": point / points[-1],
                "position": point,
                "env_steps": steps[index],
                "training_seconds": seconds[index],
                "elapsed_seconds": seconds[index] + 0.1,
                "evaluation_seconds": 0.1,
                "success_rate": success[index],
                "normalized_reward": rbar[index],
                "mean_steps": 10.0,
                "family_success_rate": success[index],
                "family_normalized_reward": rbar[index],
                "training_success_rate": success[index],
                "training_normalized_reward": rbar[index],
                "evaluation_set": digest,
            }
        )
    return rows


def write_evaluations(path: Path, rows: Sequence[dict[str, Any]]) -> None:
    with path.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=EVALUATION_FIELDS, lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)


def make_study(
    out: Path, text: str, summary: Summary, evaluations: Evaluations | None = None
) -> StudyFolder:
    """A study folder of ``text`` whose every run is finished with the files given."""
    out.mkdir(parents=True, exist_ok=True)
    (out / STUDY_FILE).write_text(text)
    folder = StudyFolder(out)
    wall = {}
    for run in parse_study(text).runs:
        write_json(folder.run_folder(run) / "summary.json", summary(run))
        write_json(folder.run_folder(run) / "config.json", run.config)
        rows = evaluations(run) if evaluations else None
        if rows is not None:
            write_evaluations(folder.run_folder(run) / EVALUATIONS_FILE, rows)
        wall[run.id] = 10.0
    state = {
        "runner": None,
        "running": [],
        "failed": {},
        "wall_seconds": wall,
        "threads": dict.fromkeys(wall, 1),
    }
    write_json(out / STATE_FILE, state)
    return folder


def markdown_tables(text: str) -> list[list[str]]:
    """The Markdown tables of ``text``, each as its lines."""
    tables, current = [], []
    for line in text.splitlines():
        if line.startswith("|"):
            current.append(line)
        elif current:
            tables.append(current)
            current = []
    if current:
        tables.append(current)
    return tables
