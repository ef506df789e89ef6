"""Independent replicates of a training command, run as parallel worker processes.

Training commands (``amaze-train``, ``amaze-evolve``) accept ``--replicates K``:
seeds ``S .. S+K-1`` each train in their own process, into ``OUT/seed-<s>``, at
most ``workers`` at a time. Processes, not threads: every replicate has its own
interpreter, random generators and numba/torch thread pools, so replicates
cannot disturb one another and a crash stays in its folder. Each worker gets
an equal share of the cores (``NUMBA_NUM_THREADS``, ``OMP_NUM_THREADS``) so
``K`` workers do not oversubscribe the machine. A replicate's output goes to
``OUT/seed-<s>/log.txt``, with a progress line at least every 30 s
(:mod:`amaze.runs.progress`). When all have ended, a table gives each seed's
figures (suite success, R̄, input recognition, env steps), then their
minimum, maximum, median and interquartile range (:func:`replicates_table`):
the maximum and the median are what the paper's Table 3 gives.

With ``--backend ray`` each replicate is a Ray task of one CPU
(:mod:`amaze.runs.ray_tasks`), all of them at once by default (Ray queues
what the cluster cannot hold). A replicate evaluates its population
locally, in its task: ``--backend``, ``--address`` and ``--actors`` are not
passed on, and ``--actors`` (Ray actors inside one run) is refused with
``--replicates``. A task that Ray runs again, or a replicate whose folder
holds a run already, resumes that run (``--resume``) instead of failing.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from amaze.errors import UsageError
from amaze.runs.cluster import check_backend
from amaze.runs.config import MAX_SEED
from amaze.runs.launchers import (
    Job,
    Launcher,
    ProcessLauncher,
    run_jobs,
    worker_environment,
    worker_threads,
)
from amaze.runs.lifecycle import CONFIG_FILE, LOG_FILE, SUMMARY_FILE
from amaze.runs.ray_tasks import RayLauncher
from amaze.validation import check_integer

__all__ = [
    "NOT_PASSED_ON",
    "Replicate",
    "plan_replicates",
    "replicate_command",
    "run_replicates",
    "strip_options",
    "worker_environment",
    "worker_threads",
]


#: Options of the whole command that its replicates do not get: each replicate
#: runs (and evaluates its population) in its own process or Ray task.
NOT_PASSED_ON = ("--backend", "--address", "--actors")


@dataclass(frozen=True)
class Replicate:
    """One replicate: its seed, run folder and command line, and how to resume it."""

    seed: int
    out: Path
    command: list[str]
    #: The command line that continues the replicate's run from its folder.
    resume: list[str] | None = None

    @property
    def log(self) -> Path:
        """The file the replicate's output goes to."""
        return self.out / LOG_FILE

    @property
    def marker(self) -> Path:
        """The file that says the replicate's folder holds a run (to be resumed)."""
        return self.out / CONFIG_FILE


def strip_options(
    argv: Sequence[str], options: Sequence[str], flags: Sequence[str] = ()
) -> list[str]:
    """``argv`` without ``options`` and their values (given as ``--x v`` or ``--x=v``)
    and without the ``flags`` (options that take no value)."""
    kept: list[str] = []
    skip = False
    for token in argv:
        if skip:
            skip = False
            continue
        name = token.split("=", 1)[0]
        if name in flags:
            continue
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
    replicate's own seed and folder ``out/seed-<s>``; so are the options of
    where the work runs (:data:`NOT_PASSED_ON`); every other option is kept.
    """
    check_integer("--replicates", count, minimum=1, error=UsageError)
    check_integer("--seed", first_seed, minimum=0, maximum=MAX_SEED, error=UsageError)
    if first_seed + count - 1 > MAX_SEED:
        raise UsageError(
            f"--seed {first_seed} with --replicates {count} reaches seed"
            f" {first_seed + count - 1}, above {MAX_SEED}"
        )
    mine = ("--replicates", "--workers", "--seed", "--out")
    base = strip_options(argv, (*mine, *NOT_PASSED_ON), flags=("--progress", "--no-progress"))
    plan = []
    for seed in range(first_seed, first_seed + count):
        folder = Path(out) / f"seed-{seed}"
        command = [sys.executable, "-m", module, *base, "--seed", str(seed), "--out", str(folder)]
        resume = [sys.executable, "-m", module, "--resume", str(folder)]
        plan.append(Replicate(seed, folder, command, resume))
    return plan


def run_replicates(
    plan: Sequence[Replicate], workers: int | None = None, launcher: Launcher | None = None
) -> int:
    """Run ``plan``, at most ``workers`` at a time, as ``launcher`` starts them.

    The default launcher is processes of this machine, at most one per core
    by default. A launcher that may start a replicate again (Ray's retries)
    gets its resume command for when its folder holds a run already. Prints
    one line when each replicate starts and ends. Returns 0 when all
    succeeded, else the first non-zero exit status (the others still run).
    """
    if workers is None:
        workers = min(len(plan), os.cpu_count() or 1) if launcher is None else len(plan)
    check_integer("--workers", workers, minimum=1, error=UsageError)
    if launcher is None:
        launcher = ProcessLauncher(workers)
    resumes = launcher.retries > 0
    status = 0

    def prepare(replicate: Replicate) -> Job:
        replicate.out.mkdir(parents=True, exist_ok=True)
        if resumes and replicate.resume is not None:
            return Job(replicate.command, replicate.log, replicate.resume, replicate.marker)
        return Job(replicate.command, replicate.log)

    def started(replicate: Replicate) -> None:
        print(f"seed {replicate.seed}: started, log in {replicate.log}")

    def ended(replicate: Replicate, code: int) -> None:
        nonlocal status
        print(f"seed {replicate.seed}: {'done' if code == 0 else f'failed ({code})'}")
        status = status or code

    run_jobs(launcher, list(plan), workers, prepare, ended, started=started)
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
    parallel workers without progress bars (their output goes to log files):
    processes of this machine, or with ``backend="ray"`` tasks on the Ray
    cluster at ``address`` (see the module docstring). Bad values raise
    :class:`~amaze.errors.UsageError`.
    """
    check_backend(backend, address)
    if not out:
        raise UsageError("--out is required")
    if any(token.split("=", 1)[0] == "--actors" for token in argv):
        raise UsageError(
            "--actors spreads the evaluation of one run over Ray actors; with --replicates"
            " each replicate is one process (one Ray task with --backend ray) that evaluates"
            " locally: give --replicates or --actors, not both"
        )
    seed = 0 if first_seed is None else first_seed
    if backend != "ray":
        plan = plan_replicates(module, argv, seed, count, out)
        status = run_replicates(plan, workers)
    else:
        # every node reads the command lines: their paths must not depend on its folder
        plan = plan_replicates(module, argv, seed, count, Path(out).absolute())
        if workers is not None:
            check_integer("--workers", workers, minimum=1, error=UsageError)
        status = run_replicates(plan, workers, RayLauncher.connect(address))
    print(replicates_table(plan))
    return status


#: The figures of a replicate's ``summary.json`` the closing table shows: (key, heading).
TABLE_FIGURES = (
    ("success_rate", "success"),
    ("normalized_reward", "R̄"),
    ("input_recognition", "inputs"),
    ("env_steps", "env steps"),
)


def replicates_table(plan: Sequence[Replicate]) -> str:
    """Each replicate's figures from its ``summary.json``, then their min, max, median and IQR.

    A replicate without a readable summary (failed, or interrupted) shows
    as such and is left out of the statistics.
    """
    from amaze.runs.config import read_json_object

    rows, values = [], {key: [] for key, _ in TABLE_FIGURES}
    for replicate in plan:
        try:
            summary = read_json_object(replicate.out / SUMMARY_FILE, UsageError, "summary")
        except UsageError:
            rows.append([f"seed {replicate.seed}", "no summary (see its log.txt)"])
            continue
        cells = [f"seed {replicate.seed}"]
        for key, _ in TABLE_FIGURES:
            value = summary.get(key)
            number = isinstance(value, int | float) and not isinstance(value, bool)
            cells.append(_cell(key, value) if number else "n/a")
            if number:
                values[key].append(float(value))
        rows.append(cells)
    for name, stat in TABLE_STATISTICS:
        rows.append(
            [name, *(_cell(k, stat(values[k])) if values[k] else "n/a" for k, _ in TABLE_FIGURES)]
        )
    header = ["replicate", *(heading for _, heading in TABLE_FIGURES)]
    widths = [
        max(len(str(row[i])) for row in [header, *rows] if i < len(row)) for i in range(len(header))
    ]
    lines = [
        "  ".join(str(cell).rjust(widths[i]) for i, cell in enumerate(row))
        for row in [header, *rows]
    ]
    return "\n".join(lines)


def _median(values: Sequence[float]) -> float:
    import numpy as np

    return float(np.median(values))


def _iqr(values: Sequence[float]) -> float:
    import numpy as np

    low, high = np.percentile(values, [25, 75])
    return float(high - low)


#: The rows under the replicates' own: (name, statistic). Median and IQR stay the last two
#: lines, as they were before min and max came (scripts read them there); min and max set the
#: table beside the paper's Table 3, which gives each cell's max and median.
TABLE_STATISTICS = (("min", min), ("max", max), ("median", _median), ("IQR", _iqr))


def _cell(key: str, value: float) -> str:
    return f"{value:,.0f}" if key == "env_steps" else f"{value:.3f}"
