"""Commands run in their own processes, at most N at a time, wherever a launcher puts them.

Replicates (:mod:`amaze.runs.replicates`) and the runs of a study
(``experiments.runner``) are command lines that train into a folder and log
into a file. :func:`run_jobs` is their one loop: it starts :class:`Job`\\ s
while fewer than ``workers`` run, polls them, reports each end and, when
interrupted (Ctrl-C), stops the ones still running. Where a job runs is the
launcher's business, so the loop is the same on every backend:

* :class:`ProcessLauncher`: a child process of this one, with an equal share
  of the cores (``NUMBA_NUM_THREADS``, ``OMP_NUM_THREADS``);
* ``RayLauncher`` (:mod:`amaze.runs.ray_tasks`): a Ray task of one CPU on a
  cluster, retried when its worker or node is lost.
"""

from __future__ import annotations

import os
import subprocess
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol, TypeVar

__all__ = [
    "Job",
    "Launcher",
    "ProcessLauncher",
    "run_jobs",
    "worker_environment",
    "worker_threads",
]

Key = TypeVar("Key")


@dataclass(frozen=True)
class Job:
    """A command line run in its own process, its output appended to ``log``.

    A job that may be started twice on the same folder (a retried Ray task,
    a study run again) gives ``resume``: the command to run instead when the
    file ``resume_when`` exists as the job starts (the folder holds a run
    already, so a fresh start would be refused).
    """

    command: list[str]
    log: Path
    resume: list[str] | None = None
    resume_when: Path | None = None

    def command_now(self) -> list[str]:
        """The command to run now: ``resume`` when ``resume_when`` exists, else ``command``."""
        if self.resume is not None and self.resume_when is not None and self.resume_when.exists():
            return list(self.resume)
        return list(self.command)


class Launcher(Protocol):
    """Starts jobs somewhere, says when each has ended, stops them."""

    #: The threads (numba, OpenMP) each job gets, as the study runner records them.
    threads: int
    #: How many times a job may be started again after its process was lost (0: never).
    retries: int

    def start(self, job: Job) -> object:
        """Start ``job``; return its handle."""
        ...

    def poll(self, handle: object) -> int | None:
        """``None`` while the job runs, then its exit status (0: success)."""
        ...

    def stop(self, handles: Sequence[object]) -> None:
        """Stop the jobs of ``handles`` and wait until they are gone."""
        ...


def worker_threads(workers: int) -> int:
    """The threads each of ``workers`` parallel processes gets: an equal share of the cores."""
    return max(1, (os.cpu_count() or 1) // workers)


def worker_environment(workers: int) -> dict[str, str]:
    """The environment of one of ``workers`` parallel processes (its thread pools sized)."""
    threads = str(worker_threads(workers))
    env = dict(os.environ)
    env.update({"NUMBA_NUM_THREADS": threads, "OMP_NUM_THREADS": threads, "PYTHONUNBUFFERED": "1"})
    return env


class ProcessLauncher:
    """Jobs as child processes of this one, each with an equal share of ``workers`` of the cores."""

    retries = 0
    #: Seconds a stopped process has to end after SIGTERM before it is killed.
    STOP_SECONDS = 30.0

    def __init__(self, workers: int) -> None:
        self.threads = worker_threads(workers)
        self.environment = worker_environment(workers)

    def start(self, job: Job) -> subprocess.Popen:
        job.log.parent.mkdir(parents=True, exist_ok=True)
        with job.log.open("a", encoding="utf-8") as log:
            return subprocess.Popen(
                job.command_now(), stdout=log, stderr=subprocess.STDOUT, env=self.environment
            )

    def poll(self, handle: object) -> int | None:
        assert isinstance(handle, subprocess.Popen)
        return handle.poll()

    def stop(self, handles: Sequence[object]) -> None:
        processes = [h for h in handles if isinstance(h, subprocess.Popen)]
        for process in processes:
            process.terminate()
        for process in processes:
            try:
                process.wait(timeout=self.STOP_SECONDS)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()


def run_jobs(
    launcher: Launcher,
    keys: Sequence[Key],
    workers: int,
    prepare: Callable[[Key], Job],
    ended: Callable[[Key, int], None],
    *,
    started: Callable[[Key], None] | None = None,
    polled: Callable[[list[Key]], None] | None = None,
    stopped: Callable[[list[Key]], None] | None = None,
    poll_seconds: float = 0.2,
) -> None:
    """Run the job of every key, in order, at most ``workers`` at a time.

    ``prepare(key)`` gives a key's job just before it starts (and may write
    what it needs); ``started(key)`` follows its start, ``ended(key, status)``
    its end; ``polled(running keys)`` follows every look at the running jobs.
    When the loop is interrupted (Ctrl-C, an error in a callback), the jobs
    still running are stopped, then ``stopped(their keys)`` is called and the
    exception goes on.
    """
    waiting = list(keys)
    running: list[tuple[Key, object]] = []
    try:
        while waiting or running:
            while waiting and len(running) < workers:
                key = waiting.pop(0)
                running.append((key, launcher.start(prepare(key))))
                if started is not None:
                    started(key)
            time.sleep(poll_seconds)
            for entry in list(running):
                status = launcher.poll(entry[1])
                if status is None:
                    continue
                running.remove(entry)
                ended(entry[0], status)
            if polled is not None:
                polled([key for key, _ in running])
    finally:
        if running:  # interrupted: stop the jobs still running
            launcher.stop([handle for _, handle in running])
            if stopped is not None:
                stopped([key for key, _ in running])
