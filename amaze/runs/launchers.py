"""Commands run in their own processes, at most N at a time, wherever a launcher puts them.

Replicates (:mod:`amaze.runs.replicates`) and the runs of a study
(``experiments.runner``) are command lines that train into a folder and log
into a file. :func:`run_jobs` is their one loop: it starts :class:`Job`\\ s
while fewer than ``workers`` run, polls them, reports each end and, when
interrupted (Ctrl-C), stops the ones still running. Where a job runs is the
launcher's business, so the loop is the same on every backend:

* :class:`ProcessLauncher`: a child process of this one, with an equal share
  of the cores (``NUMBA_NUM_THREADS``, ``OMP_NUM_THREADS``), that dies with
  this process (:func:`die_with_parent`): a launcher killed outright
  (``kill -9``, the out-of-memory killer) leaves no job running behind it,
  writing into the folder that a new launcher's job then writes into too;
* ``RayLauncher`` (:mod:`amaze.runs.ray_tasks`): a Ray task of one CPU on a
  cluster, retried when its worker or node is lost.
"""

from __future__ import annotations

import ctypes
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol, TypeVar

__all__ = [
    "PR_SET_PDEATHSIG",
    "Job",
    "Launcher",
    "ProcessLauncher",
    "die_with_parent",
    "run_jobs",
    "worker_environment",
    "worker_threads",
]

Key = TypeVar("Key")
#: ``prctl`` option: the signal a process gets when its parent dies (Linux).
PR_SET_PDEATHSIG = 1


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


def die_with_parent() -> Callable[[], None] | None:
    """A ``preexec_fn`` that has the child killed (SIGKILL) when its parent dies.

    Linux's ``prctl(PR_SET_PDEATHSIG)``, set in the child between fork and
    exec; a parent that died before it took effect is caught by the child
    looking at its parent. ``None`` (nothing to do) on other systems. The
    signal comes when the thread that started the child ends: start children
    from a thread that lives as long as the process (the main thread).
    """
    if not sys.platform.startswith("linux"):
        return None
    libc = ctypes.CDLL(None, use_errno=True)  # loaded before the fork, not in the child
    parent = os.getpid()

    def preexec() -> None:
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
        if os.getppid() != parent:  # the parent died before prctl took effect
            os.kill(os.getpid(), signal.SIGKILL)

    return preexec


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
    """Jobs as child processes of this one, each with an equal share of ``workers`` of the cores.

    Each child dies with this process (:func:`die_with_parent`). ``pass_fds``
    are file descriptors every child inherits, such as a lock that must be
    held as long as this process or any of its jobs lives (the study
    runner's, ``experiments.runner``).
    """

    retries = 0
    #: Seconds a stopped process has to end after SIGTERM before it is killed.
    STOP_SECONDS = 30.0

    def __init__(self, workers: int, pass_fds: Sequence[int] = ()) -> None:
        self.threads = worker_threads(workers)
        self.environment = worker_environment(workers)
        self.pass_fds = tuple(pass_fds)

    def start(self, job: Job) -> subprocess.Popen:
        job.log.parent.mkdir(parents=True, exist_ok=True)
        with job.log.open("a", encoding="utf-8") as log:
            return subprocess.Popen(
                job.command_now(),
                stdout=log,
                stderr=subprocess.STDOUT,
                env=self.environment,
                pass_fds=self.pass_fds,
                preexec_fn=die_with_parent(),
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
