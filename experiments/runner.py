"""Running a study: every planned run as a worker process, resumable at any time.

``amaze-experiment run STUDY --out DIR`` (:func:`run_study`) lays the study
out in ``DIR``:

* ``study.toml``: the study as it was first run (a later ``run`` of another
  study into ``DIR`` is refused: the folder is that study's);
* ``runs/<id>/``: each run's folder (``<trainer>_<algorithm>_<budget>_seed-<s>``);
* ``configs/<id>.json``: the config each run starts from;
* ``logs/<id>.txt``: what each run printed;
* ``state.json``: the runner's process, the runs in progress, the failures,
  and each run's wall-clock seconds and threads (its compute);
* ``runner.lock``: the folder's lock (:class:`StudyLock`), held by the
  runner and inherited by its workers.

Runs go at most ``workers`` at a time, each in its own process
(:mod:`experiments.worker`) with an equal share of the cores. A run with a
``summary.json`` is finished and never run again; a run killed mid-way
resumes from its last checkpoint; a failed run is tried again at the next
``run``. One progress bar covers the study, each run counting as the fraction
of its budget spent (from its ``progress.csv``).

One runner at a time: ``runner.lock`` is an ``flock`` that lasts while the
runner or any of its workers lives, so a runner started on a folder whose
lock is held is refused, naming the holder, and a lock left by processes that
are gone is taken. The workers die with their runner
(:func:`amaze.runs.launchers.die_with_parent`), even after ``kill -9``, and
each locks its run folder too (:mod:`experiments.worker`).

With ``backend="ray"`` each run is a Ray task of one CPU running the same
worker command (:mod:`amaze.runs.ray_tasks`; ``docs/ray.md``), with the same
bookkeeping (:func:`amaze.runs.launchers.run_jobs`); the study's folder must be
on a filesystem all the nodes share.
"""

from __future__ import annotations

import contextlib
import csv
import fcntl
import io
import json
import os
import sys
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from amaze.errors import UsageError
from amaze.runs.cluster import check_backend, cluster_cpus, connect
from amaze.runs.config import read_json_object
from amaze.runs.folder import write_bytes, write_json
from amaze.runs.launchers import Job, Launcher, ProcessLauncher, run_jobs
from amaze.runs.lifecycle import CONFIG_FILE, SUMMARY_FILE
from amaze.runs.progress import Progress
from amaze.runs.ray_tasks import RayLauncher
from amaze.validation import check_integer, parse_json
from experiments.study import PlannedRun, Study, StudyError, parse_study, read_study_text

__all__ = ["RunStatus", "StudyFolder", "StudyLock", "run_study", "study_status"]

STUDY_FILE = "study.toml"
STATE_FILE = "state.json"
LOCK_FILE = "runner.lock"
#: Seconds between two looks at the runs.
POLL_SECONDS = 0.5
#: Seconds a runner waits for a held lock before it is refused (``status``
#: holds it for an instant while it looks).
LOCK_WAIT_SECONDS = 1.0
#: Largest ``progress.csv`` read whole; of a larger one, its header and last rows.
MAX_PROGRESS_BYTES = 4 * 2**20
#: How much of the end of a larger ``progress.csv`` is read.
PROGRESS_TAIL_BYTES = 2**16


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
        source = f"study file {str(path)!r}"
        return parse_study(read_study_text(path, source), source)

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
        """The runner's records (``state.json``), checked; empty ones for a new folder.

        A damaged file is refused (:class:`StudyError` naming it and the
        field) rather than half-read: its failures and compute figures are
        what ``status``, ``run`` and the report say.
        """
        path = self.out / STATE_FILE
        if not path.exists():
            return {"runner": None, "running": [], "failed": {}, "wall_seconds": {}, "threads": {}}
        return checked_state(read_json_object(path, StudyError, "runner state"), path)

    def lock(self) -> StudyLock:
        """The folder's lock (not taken)."""
        return StudyLock(self.out / LOCK_FILE)

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
    try:  # a log that cannot be read counts as nothing spent: the bar is only a guide
        rows = list(csv.DictReader(io.StringIO(_progress_text(folder / "progress.csv"))))
    except (OSError, UnicodeError, csv.Error):
        return 0.0
    if not rows:
        return 0.0
    try:
        if run.budget_steps:
            fraction = float(rows[-1]["steps"]) / run.budget_steps
        elif run.budget_seconds:
            if "branches" in rows[-1]:
                seconds = sum(float(row["seconds"]) for row in rows)
            else:
                seconds = float(rows[-1]["seconds"])
            fraction = seconds / run.budget_seconds
        else:
            return 0.0
    except (KeyError, ValueError, TypeError):
        return 0.0
    return min(1.0, fraction) if fraction >= 0 else 0.0


def _progress_text(path: Path) -> str:
    """The text of a ``progress.csv``: whole up to :data:`MAX_PROGRESS_BYTES`, else its
    header and the whole rows of its last :data:`PROGRESS_TAIL_BYTES` (the last row is what
    counts; a curriculum's seconds are then summed over those rows only)."""
    with path.open("rb") as stream:
        size = os.fstat(stream.fileno()).st_size
        if size <= MAX_PROGRESS_BYTES:
            data = stream.read(MAX_PROGRESS_BYTES)
        else:
            header = stream.readline(PROGRESS_TAIL_BYTES)
            stream.seek(size - PROGRESS_TAIL_BYTES)
            data = header + stream.read(PROGRESS_TAIL_BYTES).partition(b"\n")[2]
    return data.decode("utf-8")


#: What each key of ``state.json`` holds: a list or an object, and its items' types and name.
STATE_KEYS: dict[str, tuple[type, tuple[type, ...], str]] = {
    "running": (list, (str,), "a run's id"),
    "failed": (dict, (dict,), "an object"),
    "wall_seconds": (dict, (int, float), "a number"),
    "threads": (dict, (int,), "an integer"),
}
#: The largest value of the numbers of ``state.json`` (each is at least 0): a run's
#: wall-clock seconds (about 30,000 years) and the threads it was given.
STATE_LIMITS = {"wall_seconds": 10**12, "threads": 2**20}


def checked_state(state: dict[str, Any], path: Path) -> dict[str, Any]:
    """``state`` read from ``path`` with every key of :data:`STATE_KEYS`; StudyError otherwise."""

    def bad(problem: str) -> StudyError:
        return StudyError(
            f"runner state {str(path)!r}: {problem} (delete the file to start the runner's"
            " records afresh: finished runs are kept)"
        )

    runner = state.setdefault("runner", None)
    if runner is not None and not isinstance(runner, dict):
        raise bad(f"runner {_cut(runner)} is neither null nor an object")
    for key, (kind, items, named) in STATE_KEYS.items():
        value = state.setdefault(key, kind())
        if not isinstance(value, kind):
            raise bad(f"{key} {_cut(value)} is not {'a list' if kind is list else 'an object'}")
        limit = STATE_LIMITS.get(key)
        for item in value if kind is list else value.values():
            if isinstance(item, bool) or not isinstance(item, items):
                raise bad(f"{key} holds {_cut(item)}, not {named}")
            if limit is not None and not 0 <= item <= limit:  # NaN is neither
                raise bad(f"{key} holds {_cut(item)}, not {named} in [0, {limit:,}]")
    return state


def _cut(value: Any, limit: int = 60) -> str:
    """``repr(value)`` cut to ``limit`` characters, for a message."""
    text = repr(value)
    return text if len(text) <= limit else f"{text[: limit - 4]}...{text[-1]}"


def process_start(pid: int) -> int | None:
    """When process ``pid`` started (clock ticks after boot, ``/proc``), ``None`` if unknown.

    With the pid, it names a process for good: a pid is reused, a pid and
    its start time are not.
    """
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        return int(fields[19])  # field 22 of stat(5); the name and pid come before ")"
    except (OSError, IndexError, ValueError):
        return None


def process_alive(pid: Any, start: Any = None) -> bool:
    """Whether process ``pid`` lives and, when ``start`` is given, started then (not a reuse)."""
    if not isinstance(pid, int) or isinstance(pid, bool) or pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass
    except OverflowError:
        return False
    return start is None or process_start(pid) in (None, start)


def _this_process() -> dict[str, Any]:
    """This process, as ``state.json`` and ``runner.lock`` record a runner."""
    return {"pid": os.getpid(), "start": process_start(os.getpid()), "started": _now()}


class StudyLock:
    """The lock of a study's folder: ``flock`` on ``runner.lock``.

    The runner takes it and its workers inherit it (their process holds the
    same open file), so it is held while the runner or any of its workers
    lives and released by the kernel when the last of them ends, however it
    ends: there is never a stale lock to clean. The file holds the runner's
    pid and start time, only to name it in messages.
    """

    def __init__(self, path: Path) -> None:
        self.path = path
        #: The open file of the lock while this process holds it.
        self.fd: int | None = None

    def acquire(self, folder: str) -> None:
        """Take the lock; :class:`UsageError` naming its holder when someone holds it.

        A file system without locks (``ENOLCK``...) is let be: the runner
        recorded in ``state.json`` is then all that keeps a second one out.
        """
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        deadline = time.monotonic() + LOCK_WAIT_SECONDS
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() < deadline:
                    time.sleep(0.05)
                    continue
                os.close(fd)
                raise UsageError(self._held_message(folder)) from None
            except OSError:
                os.close(fd)
                return
        self.fd = fd
        os.ftruncate(fd, 0)
        os.pwrite(fd, json.dumps(_this_process()).encode("utf-8"), 0)

    def release(self) -> None:
        """Let the lock go (it lasts while a worker that inherited it lives)."""
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None

    def held(self) -> bool | None:
        """Whether another process holds the lock now; ``None`` when that cannot be told."""
        try:
            fd = os.open(self.path, os.O_RDONLY | os.O_CLOEXEC)
        except FileNotFoundError:
            return False
        except OSError:
            return None
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return True
        except OSError:
            return None
        finally:
            os.close(fd)  # closing the file lets a lock it took go
        return False

    def holder(self) -> dict[str, Any]:
        """The runner the file names (``{}`` when it names none)."""
        try:
            holder = parse_json(self.path.read_bytes(), f"lock {str(self.path)!r}")
        except (OSError, ValueError):
            return {}
        return holder if isinstance(holder, dict) else {}

    def _held_message(self, folder: str) -> str:
        holder = self.holder()
        pid, since = _cut(holder.get("pid"), 20), str(holder.get("started"))[:40]
        if process_alive(holder.get("pid"), holder.get("start")):
            return f"{folder!r} is being run by process {pid} (since {since}); stop it first"
        return (
            f"{folder!r} is locked by a worker of a runner that is gone (process {pid}, since"
            f" {since}): a run still trains there; stop it first (its log in logs/ names its"
            " process)"
        )


@contextlib.contextmanager
def locked(folder: StudyFolder) -> Iterator[StudyLock]:
    """The folder's lock, held in the block (see :class:`StudyLock`)."""
    lock = folder.lock()
    lock.acquire(str(folder.out))
    try:
        yield lock
    finally:
        lock.release()


def runner_active(folder: StudyFolder, state: dict[str, Any]) -> bool:
    """Whether a runner (or a worker of one) works in ``folder`` now, other than this process.

    The lock says; where it cannot, the runner ``state.json`` records, if
    that process still lives.
    """
    held = folder.lock().held()
    if held is not None:
        return held
    runner = state.get("runner") or {}
    pid = runner.get("pid")
    return pid != os.getpid() and process_alive(pid, runner.get("start"))


def failed_runs(folder: StudyFolder, study: Study, state: dict[str, Any]) -> list[PlannedRun]:
    """The runs that failed the last time they ran and have not finished since.

    A finished run (its ``summary.json``, written last) is done, whatever
    ``state.json`` still says of an earlier attempt: ``status`` and ``run``'s
    exit status both go by this.
    """
    return [run for run in study.runs if run.id in state["failed"] and not folder.finished(run)]


def study_status(out: str | os.PathLike) -> tuple[Study, list[RunStatus]]:
    """The study in ``out`` and where each of its runs stands."""
    folder = StudyFolder(out)
    study = folder.study()
    state = folder.state()
    active = runner_active(folder, state)
    failed = {run.id for run in failed_runs(folder, study, state)}
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
        elif run.id in failed:
            failure = state["failed"][run.id]
            statuses.append(
                RunStatus(
                    run,
                    "failed",
                    f"exit {_cut(failure.get('status'))}, see {folder.log_file(run)}",
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
    progress: str = "off",
    python: str = sys.executable,
    backend: str = "local",
    address: str | None = None,
) -> int:
    """Run every unfinished run of ``study`` in ``out``; 0 when all are finished, else 1.

    See the module docstring: ``backend="ray"`` runs each run as a Ray task
    on the cluster at ``address``; ``progress`` is shown as
    :class:`~amaze.runs.progress.Progress` shows it (``bar``, ``lines``, ``off``).
    Raises :class:`~amaze.errors.UsageError`
    for a folder that holds another study or is being run by another
    process (or a worker of one), and for a cluster that cannot be reached.
    The exit status says what ``status`` says: 1 when a run of the study is
    failed (:func:`failed_runs`).
    """
    check_backend(backend, address)
    if workers is not None:
        workers = check_integer("--workers", workers, minimum=1, maximum=256, error=UsageError)
    ray = connect(address) if backend == "ray" else None
    folder = StudyFolder(out)
    folder.adopt(study)
    with locked(folder) as lock:
        state = folder.state()
        if lock.fd is None:  # no lock on this file system: the runner on record decides
            _refuse_recorded_runner(folder, state)
        _forget_finished_failures(folder, study, state)
        waiting = [run for run in study.runs if not folder.finished(run)]
        launcher: Launcher
        if ray is not None:
            launcher = RayLauncher(ray)
            workers = workers or cluster_cpus(ray)
        else:
            workers = workers or max(1, os.cpu_count() or 1)
            inherited = () if lock.fd is None else (lock.fd,)
            launcher = ProcessLauncher(min(workers, max(1, len(waiting))), pass_fds=inherited)
        state.update({"runner": {**_this_process(), "backend": backend}, "running": []})
        folder.save_state(state)
        try:
            _run_waiting(study, folder, state, launcher, waiting, workers, progress, python)
        finally:
            state["running"] = []
            state["runner"] = None
            folder.save_state(state)
    return 1 if failed_runs(folder, study, state) else 0


def _refuse_recorded_runner(folder: StudyFolder, state: dict[str, Any]) -> None:
    """Refuse the folder when the runner ``state.json`` names still lives.

    Only where the folder cannot be locked: a lock taken says for sure that no
    runner works there, where a pid on record may have been reused since.
    """
    runner = state.get("runner") or {}
    pid = runner.get("pid")
    if pid != os.getpid() and process_alive(pid, runner.get("start")):
        raise UsageError(
            f"{str(folder.out)!r} is being run by process {pid} (since"
            f" {runner.get('started')}); stop it first"
        )


def _forget_finished_failures(folder: StudyFolder, study: Study, state: dict[str, Any]) -> None:
    """Drop the failures of runs that have finished since (their summary says they are done)."""
    for run in study.runs:
        if run.id in state["failed"] and folder.finished(run):
            del state["failed"][run.id]


def _run_waiting(
    study: Study,
    folder: StudyFolder,
    state: dict[str, Any],
    launcher: Launcher,
    waiting: list[PlannedRun],
    workers: int,
    progress: str,
    python: str,
) -> None:
    """Run ``waiting``, keeping ``state`` and the progress shown up to date as runs end."""
    started_at: dict[str, float] = {}
    done = len(study.runs) - len(waiting)
    shown = Progress(float(len(study.runs)), "runs", study.name, mode=progress, initial=done)

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
        if folder.finished(run):  # its summary is written last: done, whatever the exit
            state["failed"].pop(run.id, None)
            done += 1
        else:
            state["failed"][run.id] = {"status": code, "time": _now()}
            failed = f"{run.id}: failed (exit {code}), see {folder.log_file(run)}"
            if shown.bar is not None:
                shown.bar.write(failed)
            else:
                print(failed, flush=True)
        state["running"] = list(started_at)
        folder.save_state(state)

    def polled(running: list[PlannedRun]) -> None:
        shown.update(
            done + sum(folder.fraction(run) for run in running),
            running=len(running),
            failed=len(state["failed"]),
        )

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
        shown.close()
    finally:
        if shown.bar is not None:
            shown.bar.close()


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
