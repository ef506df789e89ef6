"""Independent replicates of a training command, run as parallel worker processes.

Training commands (``amaze-train``, ``amaze-evolve``) accept ``--replicates K``:
seeds ``S .. S+K-1`` each train in their own process, into ``OUT/seed-<s>``, at
most ``workers`` at a time. Processes, not threads: every replicate has its own
interpreter, random generators and numba/torch thread pools, so replicates
cannot disturb one another and a crash stays in its folder. Each worker gets
an equal share of the cores (``NUMBA_NUM_THREADS``, ``OMP_NUM_THREADS``) so
``K`` workers do not oversubscribe the machine. A replicate's output goes to
``OUT/seed-<s>/log.txt``.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from amaze.errors import UsageError
from amaze.validation import check_integer

__all__ = [
    "Replicate",
    "plan_replicates",
    "replicate_command",
    "run_replicates",
    "strip_options",
    "worker_environment",
    "worker_threads",
]


@dataclass(frozen=True)
class Replicate:
    """One replicate: its seed, run folder and command line."""

    seed: int
    out: Path
    command: list[str]


def strip_options(argv: Sequence[str], options: Sequence[str]) -> list[str]:
    """``argv`` without ``options`` and their values (given as ``--x v`` or ``--x=v``)."""
    kept: list[str] = []
    skip = False
    for token in argv:
        if skip:
            skip = False
            continue
        name = token.split("=", 1)[0]
        if name in options:
            skip = "=" not in token
            continue
        kept.append(token)
    return kept


def plan_replicates(
    module: str, argv: Sequence[str], first_seed: int, count: int, out: str | os.PathLike
) -> list[Replicate]:
    """The command lines of ``count`` replicates of ``python -m module argv``.

    ``--replicates``, ``--workers``, ``--seed`` and ``--out`` are replaced by each
    replicate's own seed and folder ``out/seed-<s>``; every other option is kept.
    """
    check_integer("--replicates", count, minimum=1, error=UsageError)
    base = strip_options(argv, ("--replicates", "--workers", "--seed", "--out"))
    plan = []
    for seed in range(first_seed, first_seed + count):
        folder = Path(out) / f"seed-{seed}"
        command = [sys.executable, "-m", module, *base, "--seed", str(seed), "--out", str(folder)]
        plan.append(Replicate(seed, folder, command))
    return plan


def worker_threads(workers: int) -> int:
    """The threads each of ``workers`` parallel processes gets: an equal share of the cores."""
    return max(1, (os.cpu_count() or 1) // workers)


def worker_environment(workers: int) -> dict[str, str]:
    """The environment of one of ``workers`` parallel processes (its thread pools sized)."""
    threads = str(worker_threads(workers))
    env = dict(os.environ)
    env.update({"NUMBA_NUM_THREADS": threads, "OMP_NUM_THREADS": threads, "PYTHONUNBUFFERED": "1"})
    return env


def run_replicates(plan: Sequence[Replicate], workers: int | None = None) -> int:
    """Run ``plan``, at most ``workers`` processes at a time (default: one per core).

    Prints one line when each replicate starts and ends. Returns 0 when all
    succeeded, else the first non-zero exit status (the others still run).
    """
    if workers is None:
        workers = min(len(plan), os.cpu_count() or 1)
    check_integer("--workers", workers, minimum=1, error=UsageError)
    env = worker_environment(workers)
    waiting = list(plan)
    running: list[tuple[Replicate, subprocess.Popen, TextIO]] = []
    status = 0
    try:
        while waiting or running:
            while waiting and len(running) < workers:
                replicate = waiting.pop(0)
                replicate.out.mkdir(parents=True, exist_ok=True)
                log = (replicate.out / "log.txt").open("a")
                process = subprocess.Popen(
                    replicate.command, stdout=log, stderr=subprocess.STDOUT, env=env
                )
                running.append((replicate, process, log))
                print(f"seed {replicate.seed}: started, log in {replicate.out / 'log.txt'}")
            time.sleep(0.2)
            for entry in list(running):
                replicate, process, log = entry
                code = process.poll()
                if code is None:
                    continue
                log.close()
                running.remove(entry)
                print(f"seed {replicate.seed}: {'done' if code == 0 else f'failed ({code})'}")
                status = status or code
    finally:
        for _, process, log in running:  # interrupted: stop the workers still running
            process.terminate()
            process.wait()
            log.close()
    return status


def replicate_command(
    module: str,
    argv: Sequence[str],
    first_seed: int | None,
    count: int,
    out: str | None,
    workers: int | None = None,
    *,
    backend: str = "local",
    address: str | None = None,
) -> int:
    """What ``--replicates K`` does for the command ``python -m module``.

    Seeds ``first_seed`` (default 0) onwards, each in ``out/seed-<s>``, as
    parallel workers without progress bars (their output goes to log files).
    Bad values raise :class:`~amaze.errors.UsageError`.
    """
    if not out:
        raise UsageError("--out is required")
    seed = 0 if first_seed is None else first_seed
    plan = plan_replicates(module, [*argv, "--no-progress"], seed, count, out)
    if backend == "ray":
        raise UsageError("replicates on Ray are not available yet")
    return run_replicates(plan, workers)
