"""The command-line skeleton: one parser and one error contract for every command.

``amaze``, ``amaze-evolve`` and ``amaze-train`` share:

* :class:`CommandParser`: argparse whose usage errors raise
  :class:`~amaze.errors.UsageError` instead of printing usage and exiting;
* :func:`run_command`: the error contract (``docs/architecture.md``,
  "Errors"): a user mistake (:class:`~amaze.errors.AmazeError`, an unreadable
  or unwritable file) prints one line ``error: ...`` on standard error and
  exits with status 2, never a traceback; a closed pipe ends quietly, an
  interrupt exits with 130;
* :class:`TrainingCommand`: a whole training command built from a trainer's
  :class:`~amaze.runs.lifecycle.Run` class: its config's fields become the
  options (:class:`~amaze.runs.config.RunConfig`), plus ``--config``,
  ``--out``, ``--resume``, ``--replicates``, ``--workers`` and ``--progress``.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import NoReturn

from amaze.errors import AmazeError, UsageError, one_line
from amaze.runs.lifecycle import Run
from amaze.runs.replicates import replicate_command

__all__ = ["EXIT_USAGE", "CommandParser", "TrainingCommand", "run_command"]

#: Exit status of a command given bad input.
EXIT_USAGE = 2


class CommandParser(argparse.ArgumentParser):
    """argparse whose usage errors raise :class:`~amaze.errors.UsageError` (one line, exit 2)."""

    def error(self, message: str) -> NoReturn:
        raise UsageError(f"{self.prog}: {message}")


def run_command(body: Callable[[], int | None]) -> int:
    """Run a command's ``body`` under the error contract; return the exit status."""
    try:
        return body() or 0
    except BrokenPipeError:
        # The reader went away (e.g. `amaze inspect ... | head`): stop quietly.
        sys.stdout = open(os.devnull, "w")
        return 0
    except (AmazeError, OSError) as error:
        print(f"error: {one_line(error)}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        return 130


@dataclass(frozen=True)
class TrainingCommand:
    """A training command (``amaze-evolve``, ``amaze-train``) around a trainer's run class."""

    prog: str
    description: str
    #: The module run as ``python -m module`` by each replicate.
    module: str
    run_class: type[Run]

    def parser(self) -> CommandParser:
        """The command's parser: the config's fields, then the run options."""
        parser = CommandParser(prog=self.prog, description=self.description)
        config = parser.add_argument_group("run config (config.json keys)")
        self.run_class.config_class.add_arguments(config)
        options = self.run_class.config_class.options_field
        run = parser.add_argument_group("run")
        run.add_argument(
            "--config",
            metavar="FILE.json",
            help="a whole config, or "
            + (f"the {options!r} alone" if options else "part of one")
            + "; command-line options win over it",
        )
        run.add_argument("--out", metavar="DIR", help="the run folder to create")
        run.add_argument("--resume", metavar="DIR", help="continue the killed run in DIR")
        run.add_argument(
            "--replay",
            metavar="RUN_DIR",
            help="rerun RUN_DIR's config with its recorded curriculum decisions, into --out",
        )
        run.add_argument(
            "--replicates",
            type=int,
            default=1,
            metavar="K",
            help="seeds S..S+K-1, each in OUT/seed-<s>",
        )
        run.add_argument(
            "--workers",
            type=int,
            metavar="N",
            help="replicates run at once (default: one per core)",
        )
        run.add_argument(
            "--progress",
            action=argparse.BooleanOptionalAction,
            help="progress bar (default: on when stderr is a terminal)",
        )
        return parser

    def main(self, argv: Sequence[str] | None = None) -> int:
        """Run the command; return the exit status (2 for bad input)."""
        argv = list(sys.argv[1:] if argv is None else argv)
        return run_command(lambda: self._run(argv))

    def _run(self, argv: list[str]) -> int:
        args = self.parser().parse_args(argv)
        progress = sys.stderr.isatty() if args.progress is None else args.progress
        if args.resume:
            result = self.run_class.resume(args.resume, progress_bar=progress)
        elif args.replay:
            if not args.out:
                raise UsageError("--replay needs --out, the folder of the new run")
            result = self.run_class.replay(args.replay, args.out, progress_bar=progress)
        elif args.replicates != 1:
            return replicate_command(
                self.module, argv, args.seed, args.replicates, args.out, args.workers
            )
        else:
            if not args.out:
                raise UsageError("--out is required (or --resume DIR)")
            config_class = self.run_class.config_class
            data = config_class.from_file_and_arguments(args, args.config)
            result = self.run_class.fresh(data, args.out, progress_bar=progress)
        print(result.headline)
        print(f"run folder: {result.out} ({', '.join(result.outputs)})")
        return 0

    def entry_point(self) -> NoReturn:
        """Console-script entry point."""
        raise SystemExit(self.main())
