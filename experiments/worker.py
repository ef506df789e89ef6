"""One run of a study in its own process: ``python -m experiments.worker --config FILE --out DIR``.

A new folder starts the run from ``FILE`` (a whole config, as the study
planned it); a folder holding a killed run resumes it; a finished one is left
alone. The trainer is the one of the config's ``algo``
(:func:`experiments.trainers.run_class`). Bad input exits with status 2 and
one ``error:`` line, as every command of the project.

The worker names its process in its output (the run's log) and locks its
run folder (``flock`` on the folder itself) while it trains: a second
process started on the same folder, while the first still lives, is refused
rather than let write beside it (two writers would interleave their
checkpoints and ``progress.csv`` rows). The kernel releases the lock when
the worker ends, however it ends.
"""

from __future__ import annotations

import errno
import fcntl
import os
import sys
from collections.abc import Sequence
from pathlib import Path

from amaze.errors import UsageError
from amaze.runs.command import CommandParser, run_command
from amaze.runs.config import read_json_object
from amaze.runs.lifecycle import CONFIG_FILE, SUMMARY_FILE
from experiments.trainers import run_class

__all__ = ["main"]


def _run(argv: Sequence[str]) -> int:
    parser = CommandParser(prog="experiments.worker", description="one run of a study")
    parser.add_argument("--config", required=True, metavar="FILE.json")
    parser.add_argument("--out", required=True, metavar="DIR")
    args = parser.parse_args(list(argv))
    out = Path(args.out)
    if (out / SUMMARY_FILE).exists():
        print(f"{out}: finished already")
        return 0
    config = read_json_object(Path(args.config), UsageError, "run config")
    trainer = run_class(config.get("algo"))
    print(f"--- worker process {os.getpid()} in {out}", flush=True)
    lock_run_folder(out)
    # its log is a file: progress as a plain line at least every 30 s
    if (out / CONFIG_FILE).exists():
        result = trainer.resume(out, progress="lines")
    else:
        result = trainer.fresh(config, out, progress="lines")
    print(result.headline)
    return 0


def lock_run_folder(out: Path) -> int | None:
    """Lock the run folder ``out`` (created empty if new) for this process's lifetime.

    Returns the open folder that holds the lock, ``None`` on a file system
    whose locks cannot be taken this way (some network file systems). Raises
    :class:`UsageError` when another process holds it.
    """
    out.mkdir(parents=True, exist_ok=True)
    fd = os.open(out, os.O_RDONLY | os.O_CLOEXEC)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as problem:
        os.close(fd)
        if problem.errno in (errno.EWOULDBLOCK, errno.EAGAIN):
            raise UsageError(
                f"run folder {str(out)!r} is being trained by another process; stop it first"
            ) from None
        return None
    return fd  # left open: the lock lasts as long as this process


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command; return the exit status (2 for bad input)."""
    return run_command(lambda: _run(sys.argv[1:] if argv is None else argv))


if __name__ == "__main__":
    raise SystemExit(main())
