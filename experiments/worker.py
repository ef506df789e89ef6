"""One run of a study in its own process: ``python -m experiments.worker --config FILE --out DIR``.

A new folder starts the run from ``FILE`` (a whole config, as the study
planned it); a folder holding a killed run resumes it; a finished one is left
alone. The trainer is the one of the config's ``algo``
(:func:`experiments.trainers.run_class`). Bad input exits with status 2 and
one ``error:`` line, as every command of the project.
"""

from __future__ import annotations

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
    if (out / CONFIG_FILE).exists():
        result = trainer.resume(out)
    else:
        result = trainer.fresh(config, out)
    print(result.headline)
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command; return the exit status (2 for bad input)."""
    return run_command(lambda: _run(sys.argv[1:] if argv is None else argv))


if __name__ == "__main__":
    raise SystemExit(main())
