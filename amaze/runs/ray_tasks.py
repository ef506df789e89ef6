"""Jobs as Ray tasks: one run (a replicate, a run of a study) on one CPU of a cluster.

:class:`RayLauncher` is the :class:`~amaze.runs.launchers.Launcher` of
``--backend ray``: each :class:`~amaze.runs.launchers.Job` becomes one task of
one CPU (:func:`run_job`), so a study or a set of replicates fills the cluster
and Ray queues what does not fit. The task runs the job's command line as a
child process of its Ray worker, the worker's own Python standing in for the
driver's, with one thread per pool (``NUMBA_NUM_THREADS=1``,
``OMP_NUM_THREADS=1``), and appends its output to the job's log. The log, the
run folders and the working directory are read and written by every node:
they must be on a filesystem that all the nodes share, at the same path.

A task whose worker died or whose node was lost is run again by Ray, as is
one whose command was killed by a signal (the out-of-memory killer,
``kill -9``): :data:`TASK_RETRIES` times. The command of a retried task finds
its folder holding a run and resumes it from its last checkpoint (the
study's worker does so by itself; a replicate's job gives ``--resume``), so
a retry continues the run rather than restarting it. A command that exits
with a non-zero status (a bad config, a bug) is not retried: its status is
the job's. The child dies with its worker (``PR_SET_PDEATHSIG`` on Linux), so
a retried task never runs beside an orphan of the lost one writing the same
folder.

Nothing here imports Ray at module level: the task is declared when a
launcher is made (:func:`remote_job`), after :func:`~amaze.runs.cluster.connect`.
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from collections.abc import Sequence
from dataclasses import dataclass, replace
from datetime import UTC, datetime
from pathlib import Path
from types import ModuleType
from typing import Any

from amaze.errors import one_line
from amaze.runs.cluster import connect
from amaze.runs.launchers import Job, die_with_parent

__all__ = ["LOST_STATUS", "TASK_RETRIES", "RayLauncher", "RunKilled", "remote_job", "run_job"]

#: How many times Ray runs a task again after its worker died, its node was
#: lost or its command was killed by a signal. A few: enough to ride out a
#: preempted node or an out-of-memory kill, since each retry resumes from the
#: run's checkpoint; not forever, since a run that keeps dying (a config too
#: large for the nodes' memory) would otherwise never be reported as failed.
TASK_RETRIES = 3
#: The exit status recorded for a job that Ray gave up on without a status of
#: its command (its worker or node lost more than :data:`TASK_RETRIES` times,
#: or a command that could not start); the job's log says why.
LOST_STATUS = 1
#: The environment every task's command gets on top of its worker's.
TASK_ENVIRONMENT = {"NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "PYTHONUNBUFFERED": "1"}


class RunKilled(RuntimeError):
    """A task's command was killed by a signal: the task is retried (``retry_exceptions``)."""

    def __init__(self, returncode: int) -> None:
        super().__init__(returncode)
        self.returncode = returncode

    def __str__(self) -> str:
        return f"the run was killed by signal {-self.returncode}"


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


def _python_here(command: Sequence[str]) -> list[str]:
    """``command`` with this interpreter for the driver's (the paths may differ across nodes)."""
    argv = list(command)
    if argv and Path(argv[0]).name.startswith("python"):
        argv[0] = sys.executable
    return argv


def run_job(job: Job, cwd: str) -> int:
    """The body of a job's Ray task: run its command in ``cwd``; return its exit status.

    The first line appended to the log names the host and the Ray worker's
    process; the next one the command's process (so that it can be found,
    e.g. to be killed). Raises :class:`RunKilled` when the command is killed
    by a signal.
    """
    command = _python_here(job.command_now())
    environment = {**os.environ, **TASK_ENVIRONMENT}
    with job.log.open("a", encoding="utf-8") as log:
        log.write(
            f"--- {_now()}: Ray task on {socket.gethostname()}, worker process {os.getpid()}\n"
        )
        log.flush()
        process = subprocess.Popen(
            command,
            stdout=log,
            stderr=subprocess.STDOUT,
            cwd=cwd,
            env=environment,
            preexec_fn=die_with_parent(),
        )
    with job.log.open("a", encoding="utf-8") as log:
        log.write(f"--- {_now()}: run process {process.pid}: {' '.join(command)}\n")
    try:
        code = process.wait()
    finally:
        if process.poll() is None:  # the task was cancelled: the command goes with it
            process.kill()
            process.wait()
    if code < 0:
        raise RunKilled(code)
    return code


def remote_job(ray: ModuleType) -> Any:
    """:func:`run_job` as a Ray remote function: one CPU, retried as the module docstring says."""
    return ray.remote(num_cpus=1, max_retries=TASK_RETRIES, retry_exceptions=[RunKilled])(run_job)


@dataclass(frozen=True)
class _Task:
    """A job submitted to Ray: its result's reference, and the job for its log."""

    ref: Any
    job: Job


class RayLauncher:
    """Jobs as Ray tasks of one CPU (see the module docstring)."""

    threads = 1
    retries = TASK_RETRIES
    #: Seconds to wait for cancelled tasks to be gone.
    STOP_SECONDS = 30.0

    def __init__(self, ray: ModuleType, cwd: str | os.PathLike | None = None) -> None:
        self.ray = ray
        self.cwd = str(Path(cwd or os.getcwd()).absolute())
        self.task = remote_job(ray)

    @classmethod
    def connect(cls, address: str | None = None) -> RayLauncher:
        """A launcher on the cluster at ``address`` (:func:`~amaze.runs.cluster.connect`)."""
        return cls(connect(address))

    def start(self, job: Job) -> _Task:
        # the task runs elsewhere: its files are named from the root
        marker = None if job.resume_when is None else job.resume_when.absolute()
        job = replace(job, log=job.log.absolute(), resume_when=marker)
        job.log.parent.mkdir(parents=True, exist_ok=True)
        return _Task(self.task.remote(job, self.cwd), job)

    def poll(self, handle: object) -> int | None:
        assert isinstance(handle, _Task)
        ready, _ = self.ray.wait([handle.ref], timeout=0)
        if not ready:
            return None
        try:
            return int(self.ray.get(handle.ref))
        except RunKilled as killed:
            code = int(killed.returncode)
            why = f"killed by signal {-code} (tried {TASK_RETRIES + 1} times)"
        except self.ray.exceptions.RayError as error:  # lost, or an error of the task itself
            cause = getattr(error, "cause", None) or error
            code = LOST_STATUS
            why = f"Ray gave up on its task: {type(cause).__name__}: {one_line(cause)}"
        with handle.job.log.open("a", encoding="utf-8") as log:
            log.write(f"--- {_now()}: the run failed, {why}\n")
        return code

    def stop(self, handles: Sequence[object]) -> None:
        refs = [h.ref for h in handles if isinstance(h, _Task)]
        for ref in refs:
            self.ray.cancel(ref, force=True)  # kills the worker, and its command with it
        if refs:
            self.ray.wait(refs, num_returns=len(refs), timeout=self.STOP_SECONDS)
