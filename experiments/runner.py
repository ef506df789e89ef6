"""Running a study: every planned run as a worker process, resumable at any time.

``amaze-experiment run STUDY --out DIR`` (:func:`run_study`) lays the study
out in ``DIR``:

* ``study.toml``: the study as it was first run (a later ``run`` of another
  study into ``DIR`` is refused: the folder is that study's);
* ``runs/<id>/``: each run's folder (``<trainer>_<algorithm>_<budget>_seed-<s>``);
* ``configs/<id>.json``: the config each run starts from;
* ``logs/<id>.txt``: what each run printed;
* ``state.json``: the runner's process, the runs in progress, the failures,
  and each run's wall-clock seconds and threads (its compute).

Runs go at most ``workers`` at a time, each in its own process
(:mod:`experiments.worker`) with an equal share of the cores. A run with a
``summary.json`` is finished and never run again; a run killed mid-way
resumes from its last checkpoint; a failed run is tried again at the next
``run`` (its log says why it failed). Interrupting the runner (Ctrl-C)
stops the workers, which resume next time: a study can be stopped and
restarted at any moment without losing a finished run. One progress bar
covers the whole study: each run counts as the fraction of its budget it
has spent (read from its ``progress.csv``), with an ETA.

With ``backend="ray"`` (``--backend ray``) each run is a Ray task of one CPU
running the same worker command (:mod:`amaze.runs.ray_tasks`), at most
``workers`` at once (default: the cluster's CPUs), so a study fills a
cluster; the study's folder must be on a filesystem all the nodes share.
A run whose worker or node is lost, or whose process is killed, is retried
by Ray and resumes from its checkpoint; a run that fails (non-zero exit) is
recorded as failed, as on this machine. The bookkeeping, the progress bar
and the interruption are the same for both backends (one loop,
:func:`amaze.runs.launchers.run_jobs`); ``state.json`` records one thread
per run on Ray.
"""

from __future__ import annotations

import csv
import io
import json
import os
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from amaze.errors import UsageError
from amaze.runs.cluster import check_backend, cluster_cpus, connect
from amaze.runs.folder import write_bytes, write_json
from amaze.runs.launchers import Job, Launcher, ProcessLauncher, run_jobs
from amaze.runs.lifecycle import CONFIG_FILE, SUMMARY_FILE
from amaze.runs.ray_tasks import RayLauncher
from amaze.validation import check_integer
from experiments.study import PlannedRun, Study, StudyError, parse_study

__all__ = ["RunStatus", "StudyFolder", "run_study", "study_status"]

STUDY_FILE = "study.toml"
STATE_FILE = "state.json"
#: Seconds between two looks at the runs.
POLL_SECONDS = 0.5


@dataclass(frozen=True)
class RunStatus:
    """Where a planned run stands: done, running, failed, interrupted or pending."""

    run: PlannedRun
    state: str
    detail: str = ""


class StudyFolder:
    """A study's folder (see the module docstring)."""

    def __init__(self, out: str | os.PathLike) -> None:
        self.out = Path(out)

    def run_folder(self, run: PlannedRun) -> Path:
        return self.out / "runs" / run.id

    def config_file(self, run: PlannedRun) -> Path:
        return self.out / "configs" / f"{run.id}.json"

    def log_file(self, run: PlannedRun) -> Path:
        return self.out / "logs" / f"{run.id}.txt"

    def study(self) -> Study:
        """The study the folder holds."""
        path = self.out / STUDY_FILE
        if not path.is_file():
            raise UsageError(f"{str(self.out)!r} holds no study (no {STUDY_FILE})")
        return parse_study(path.read_text(encoding="utf-8"), f"study file {str(path)!r}")

    def adopt(self, study: Study) -> None:
        """Make the folder ``study``'s, or check that it is already."""
        path = self.out / STUDY_FILE
        if path.exists():
            held = self.study()
            if held.text != study.text:
                raise UsageError(
                    f"{str(self.out)!r} holds the study {held.name!r} with other contents"
                    f" ({str(path)!r}): give another --out"
                )
            return
        if self.out.exists() and any(self.out.iterdir()):
            raise UsageError(f"{str(self.out)!r} is not empty and holds no study")
        write_bytes(path, study.text.encode("utf-8"))

    def state(self) -> dict[str, Any]:
        path = self.out / STATE_FILE
        if not path.is_file():
            return {"runner": None, "running": [], "failed": {}, "wall_seconds": {}, "threads": {}}
        try:
            state = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError) as problem:
            raise StudyError(f"runner state {str(path)!r} is damaged: {problem}") from None
        for key, empty in (("running", []), ("failed", {}), ("wall_seconds", {}), ("threads", {})):
            state.setdefault(key, empty)
        return state

    def save_state(self, state: dict[str, Any]) -> None:
        write_json(self.out / STATE_FILE, state)

    def finished(self, run: PlannedRun) -> bool:
        return (self.run_folder(run) / SUMMARY_FILE).is_file()

    def fraction(self, run: PlannedRun) -> float:
        """How much of its budget a run has spent, from the last row of its ``progress.csv``."""
        if self.finished(run):
            return 1.0
        return spent_fraction(self.run_folder(run), run)


def spent_fraction(folder: Path, run: PlannedRun) -> float:
    """The fraction of ``run``'s budget spent as ``folder/progress.csv`` says (0 without one).

    Steps when the budget has steps (the ``steps`` column), else seconds
    (``seconds``, summed over the rows of a curriculum, whose rows are branches).
    """
    path = folder / "progress.csv"
    try:
        text = path.read_text(encoding="utf-8")
    except OSError:
        return 0.0
    rows = list(csv.DictReader(io.StringIO(text)))
    if not rows:
        return 0.0
    try:
        if run.budget_steps:
            return min(1.0, float(rows[-1]["steps"]) / run.budget_steps)
        if run.budget_seconds:
            if "branches" in rows[-1]:
                seconds = sum(float(row["seconds"]) for row in rows)
            else:
                seconds = float(rows[-1]["seconds"])
            return min(1.0, seconds / run.budget_seconds)
    except (KeyError, ValueError):
        return 0.0
    return 0.0


def _alive(pid: Any) -> bool:
    if not isinstance(pid, int) or pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def study_status(out: str | os.PathLike) -> tuple[Study, list[RunStatus]]:
    """The study in ``out`` and where each of its runs stands."""
    folder = StudyFolder(out)
    study = folder.study()
    state = folder.state()
    runner = state.get("runner") or {}
    active = _alive(runner.get("pid")) and runner.get("pid") != os.getpid()
    statuses = []
    for run in study.runs:
        if folder.finished(run):
            seconds = state["wall_seconds"].get(run.id)
            detail = f"{seconds:.0f} s" if isinstance(seconds, int | float) else ""
            statuses.append(RunStatus(run, "done", detail))
        elif active and run.id in state["running"]:
            statuses.append(
                RunStatus(run, "running", f"{100 * folder.fraction(run):.0f} % of its budget")
            )
        elif run.id in state["failed"]:
            failure = state["failed"][run.id]
            statuses.append(
                RunStatus(
                    run,
                    "failed",
                    f"exit {failure.get('status')}, see {folder.log_file(run)}",
                )
            )
        elif (folder.run_folder(run) / CONFIG_FILE).exists():
            statuses.append(
                RunStatus(run, "interrupted", f"{100 * folder.fraction(run):.0f} %, resumes")
            )
        else:
            statuses.append(RunStatus(run, "pending"))
    return study, statuses


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


def run_study(
    study: Study,
    out: str | os.PathLike,
    *,
    workers: int | None = None,
    progress_bar: bool = True,
    python: str = sys.executable,
    backend: str = "local",
    address: str | None = None,
) -> int:
    """Run every unfinished run of ``study`` in ``out``; 0 when all are finished, else 1.

    See the module docstring: ``backend="ray"`` runs each run as a Ray task
    on the cluster at ``address``. Raises :class:`~amaze.errors.UsageError`
    for a folder that holds another study or is being run by another
    process, and for a cluster that cannot be reached.
    """
    from tqdm import tqdm

    check_backend(backend, address)
    if workers is not None:
        workers = check_integer("--workers", workers, minimum=1, maximum=256, error=UsageError)
    ray = connect(address) if backend == "ray" else None
    folder = StudyFolder(out)
    folder.adopt(study)
    state = folder.state()
    runner = state.get("runner") or {}
    if _alive(runner.get("pid")) and runner.get("pid") != os.getpid():
        raise UsageError(
            f"{str(folder.out)!r} is being run by process {runner['pid']} (since"
            f" {runner.get('started')}); stop it first"
        )
    waiting = [run for run in study.runs if not folder.finished(run)]
    launcher: Launcher
    if ray is not None:
        launcher = RayLauncher(ray)
        workers = workers or cluster_cpus(ray)
    else:
        workers = workers or max(1, os.cpu_count() or 1)
        launcher = ProcessLauncher(min(workers, max(1, len(waiting))))
    state.update(
        {"runner": {"pid": os.getpid(), "started": _now(), "backend": backend}, "running": []}
    )
    folder.save_state(state)
    started_at: dict[str, float] = {}
    done = len(study.runs) - len(waiting)
    bar = tqdm(
        total=float(len(study.runs)),
        initial=float(done),
        unit="run",
        desc=study.name,
        disable=not progress_bar,
        dynamic_ncols=True,
        bar_format="{l_bar}{bar}| {n:.1f}/{total:.0f} runs [{elapsed}<{remaining}{postfix}]",
    )

    def prepare(run: PlannedRun) -> Job:
        write_json(folder.config_file(run), run.config)
        folder.log_file(run).parent.mkdir(parents=True, exist_ok=True)
        with folder.log_file(run).open("a", encoding="utf-8") as log:
            log.write(f"--- {_now()}: started by the study runner\n")
        command = [python, "-m", "experiments.worker", "--config", str(folder.config_file(run))]
        return Job([*command, "--out", str(folder.run_folder(run))], folder.log_file(run))

    def started(run: PlannedRun) -> None:
        started_at[run.id] = time.monotonic()
        state["running"] = list(started_at)
        folder.save_state(state)

    def spent(run: PlannedRun) -> None:
        seconds = state["wall_seconds"].get(run.id, 0.0) + (
            time.monotonic() - started_at.pop(run.id)
        )
        state["wall_seconds"][run.id] = round(seconds, 3)
        state["threads"][run.id] = launcher.threads

    def ended(run: PlannedRun, code: int) -> None:
        nonlocal done
        spent(run)
        if code == 0 and folder.finished(run):
            state["failed"].pop(run.id, None)
            done += 1
        else:
            state["failed"][run.id] = {"status": code, "time": _now()}
            bar.write(f"{run.id}: failed (exit {code}), see {folder.log_file(run)}")
        state["running"] = list(started_at)
        folder.save_state(state)

    def polled(running: list[PlannedRun]) -> None:
        bar.n = done + sum(folder.fraction(run) for run in running)
        bar.set_postfix_str(f"{len(running)} running, {len(state['failed'])} failed")
        bar.refresh()

    def stopped(running: list[PlannedRun]) -> None:  # interrupted: they resume next time
        for run in running:
            spent(run)

    try:
        run_jobs(
            launcher,
            waiting,
            workers,
            prepare,
            ended,
            started=started,
            polled=polled,
            stopped=stopped,
            poll_seconds=POLL_SECONDS,
        )
    finally:
        state["running"] = []
        state["runner"] = None
        folder.save_state(state)
        bar.close()
    failed = [run_id for run_id in state["failed"] if run_id in {r.id for r in study.runs}]
    return 1 if failed else 0


def format_status(study: Study, statuses: Sequence[RunStatus]) -> str:
    """A table of the runs per treatment, then the runs that are not done, one a line."""
    states = ("done", "running", "interrupted", "failed", "pending")
    lines = [f"study {study.name}: {len(statuses)} runs"]
    width = max(len(t) for t in study.treatments)
    lines.append(f"  {'treatment':<{width}}  " + "  ".join(f"{s:>11}" for s in states))
    for treatment in study.treatments:
        mine = [s for s in statuses if s.run.treatment == treatment]
        counts = [sum(s.state == state for s in mine) for state in states]
        lines.append(f"  {treatment:<{width}}  " + "  ".join(f"{c:>11}" for c in counts))
    totals = [sum(s.state == state for s in statuses) for state in states]
    lines.append(f"  {'all':<{width}}  " + "  ".join(f"{c:>11}" for c in totals))
    for status in statuses:
        if status.state not in ("done", "pending"):
            lines.append(f"{status.state:>11}: {status.run.id} ({status.detail})")
    return "\n".join(lines)
