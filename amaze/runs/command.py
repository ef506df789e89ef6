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
  ``--out``, ``--resume``, ``--replicates``, ``--workers``, ``--backend``,
  ``--address`` and ``--progress``. Its progress is a bar on a terminal and
  plain lines otherwise (:mod:`amaze.runs.progress`); Ctrl-C and SIGTERM end
  it with one line saying what is saved and the command that resumes it.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import platform
import signal
import sys
from collections.abc import Callable, Iterator, Sequence
from contextlib import AbstractContextManager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NoReturn

from amaze import __version__
from amaze.errors import AmazeError, UsageError, one_line
from amaze.runs.cluster import add_backend_arguments, check_backend
from amaze.runs.config import RunConfig
from amaze.runs.lifecycle import Run, RunResult
from amaze.runs.replicates import replicate_command

__all__ = ["EXIT_USAGE", "CommandParser", "TrainingCommand", "run_command"]

#: Exit status of a command given bad input.
EXIT_USAGE = 2


class CommandParser(argparse.ArgumentParser):
    """argparse whose usage errors raise :class:`~amaze.errors.UsageError` (one line, exit 2).

    ``version=True`` (a command's top-level parser) adds ``--version``, which
    prints the command, the package version and the Python and numpy versions
    (what a bug report or a methods section needs) and exits with status 0.
    """

    def __init__(self, *args: object, version: bool = False, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        if version:
            self.add_argument("--version", action="version", version=version_line())

    def error(self, message: str) -> NoReturn:
        raise UsageError(f"{self.prog}: {message}")


def version_line() -> str:
    """``%(prog)s <version> (Python x.y.z, numpy x.y.z)``, as ``--version`` prints it."""
    import numpy

    return (
        f"%(prog)s {__version__} (amaze-evo; Python {platform.python_version()},"
        f" numpy {numpy.__version__})"
    )


def run_command(body: Callable[[], int | None]) -> int:
    """Run a command's ``body`` under the error contract; return the exit status."""
    try:
        try:
            return body() or 0
        except Exception as error:
            interrupt = interrupt_behind(error)
            if interrupt is None:
                raise
            raise interrupt from None
    except BrokenPipeError:
        # The reader went away (e.g. `amaze inspect ... | head`): stop quietly.
        sys.stdout = open(os.devnull, "w")
        return 0
    except (AmazeError, OSError) as error:
        print(f"error: {one_line(error)}", file=sys.stderr)
        return EXIT_USAGE
    except Terminated:
        return 128 + signal.SIGTERM
    except KeyboardInterrupt:
        return 130


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where the program runs, so that it ends as an interrupt does."""


def interrupt_behind(error: BaseException) -> KeyboardInterrupt | None:
    """The interrupt (Ctrl-C or :class:`Terminated`) that ``error`` was raised while handling.

    A signal can land inside a library's write (checkpoints and checkpoint
    folders hold signals back, :func:`amaze.runs.folder.signals_deferred`; an
    agent file's ``savez`` does not), whose clean-up then raises an error of
    its own with the interrupt as its context. The run stopped because of the
    interrupt, so it ends as one (exit status, message), not with a traceback.
    """
    seen: set[int] = set()
    cause: BaseException | None = error
    while cause is not None and id(cause) not in seen:
        if isinstance(cause, KeyboardInterrupt):
            return cause
        seen.add(id(cause))
        cause = cause.__cause__ or cause.__context__
    return None


@contextlib.contextmanager
def terminated_as_interrupt() -> Iterator[None]:
    """Meanwhile, SIGTERM raises :class:`Terminated` (the main thread only; else nothing)."""

    def terminate(signum: int, frame: object) -> None:
        raise Terminated

    try:
        previous = signal.signal(signal.SIGTERM, terminate)
    except ValueError:  # not the main thread: signals go elsewhere
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _named(target: str) -> Any:
    """The object named ``"module:name"``, its module imported now (names from the code only)."""
    module, _, name = target.partition(":")
    return getattr(importlib.import_module(module), name)


@dataclass(frozen=True)
class TrainingCommand:
    """A training command (``amaze-evolve``, ``amaze-train``) around a trainer's run class.

    ``--backend ray`` runs replicates as Ray tasks (:mod:`amaze.runs.replicates`).
    A trainer that can use Ray inside one run (population evaluation) gives
    ``add_arguments`` (its own options) and ``run_context`` (the context its
    runs go in, made from the parsed options); without them a single run with
    ``--backend ray`` is refused, as it would have nothing to distribute.

    ``run_class`` may be given as ``"module:Class"`` with its ``config_class``:
    the module (and whatever heavy library it loads, such as torch) is then
    imported only once the options and the config file have been checked, so
    that bad input is refused at the cost of the command's start alone.
    """

    prog: str
    description: str
    #: The module run as ``python -m module`` by each replicate.
    module: str
    run_class: type[Run] | str
    #: Adds the trainer's own run options to the parser's "run" group.
    add_arguments: Callable[[argparse._ArgumentGroup], None] | None = None
    #: The context a single run goes in (from the parsed options), e.g. its evaluation backend.
    run_context: Callable[[argparse.Namespace], AbstractContextManager[object]] | None = None
    #: The run class's config class (needed when ``run_class`` is a ``"module:Class"`` name).
    config_class: type[RunConfig] | None = None
    #: ``"module:function"`` checking a ``--resume`` folder before the run class is
    #: imported (files whose checks need none of its libraries).
    check_resume: str | None = None

    def trainer(self) -> type[Run]:
        """The run class, imported now if it was given by name."""
        return _named(self.run_class) if isinstance(self.run_class, str) else self.run_class

    def config(self) -> type[RunConfig]:
        """The run's config class (without importing a run class given by name)."""
        if self.config_class is not None:
            return self.config_class
        return self.trainer().config_class

    def parser(self) -> CommandParser:
        """The command's parser: the config's fields, then the run options."""
        parser = CommandParser(prog=self.prog, description=self.description, version=True)
        config = parser.add_argument_group("run config (config.json keys)")
        self.config().add_arguments(config)
        options = self.config().options_field
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
            help="rerun RUN_DIR's config with its recorded decisions (a curriculum's, or the"
            " edens-populations selector's picks), into --out",
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
            help="replicates run at once (default: one per core; with Ray, the cluster's CPUs)",
        )
        add_backend_arguments(run)
        if self.add_arguments is not None:
            self.add_arguments(run)
        run.add_argument(
            "--progress",
            action=argparse.BooleanOptionalAction,
            help="a progress bar (--no-progress: nothing; default: a bar on a terminal,"
            " else a plain line at least every 30 s)",
        )
        return parser

    def main(self, argv: Sequence[str] | None = None) -> int:
        """Run the command; return the exit status (2 for bad input)."""
        argv = list(sys.argv[1:] if argv is None else argv)
        return run_command(lambda: self._run(argv))

    def _run(self, argv: list[str]) -> int:
        args = self.parser().parse_args(argv)
        if args.progress is None:
            progress = "bar" if sys.stderr.isatty() else "lines"
        else:
            progress = "bar" if args.progress else "off"
        check_backend(args.backend, args.address)
        if args.workers is not None and args.replicates == 1:
            raise UsageError(
                f"--workers {args.workers} runs replicates at once: give --replicates K"
            )
        if args.replicates != 1:
            return replicate_command(
                self.module,
                argv,
                args.seed,
                args.replicates,
                args.out,
                args.workers,
                backend=args.backend,
                address=args.address,
            )
        if args.backend == "ray" and self.run_context is None:
            raise UsageError(
                f"{self.prog} --backend ray runs replicates on Ray (--replicates K);"
                " a single run has nothing to distribute"
            )
        context = self.run_context(args) if self.run_context else contextlib.nullcontext()
        with context, terminated_as_interrupt():
            try:
                result = self._one_run(args, progress)
            except (KeyboardInterrupt, Exception) as error:
                interrupt = interrupt_behind(error)
                if interrupt is None:
                    raise
                self._say_interrupted(args, interrupt)
                raise interrupt from None
        if result.finished_before:
            print(f"{result.out} holds a finished run (its summary.json): nothing was changed")
        print(result.headline)
        for line in Run.closing_lines(result.summary):
            print(line)
        print(f"run folder: {result.out} ({', '.join(result.outputs)})")
        return 0

    def _say_interrupted(self, args: argparse.Namespace, interrupt: KeyboardInterrupt) -> None:
        """One line: what stopped the run, what is saved, and the command that resumes it."""
        out = args.resume or args.out
        what = "terminated (SIGTERM)" if isinstance(interrupt, Terminated) else "interrupted"
        if out is None or not (Path(out) / "config.json").exists():
            print(f"{what}: nothing was written", file=sys.stderr)
            return
        print(
            f"{what}: {out} keeps what its last checkpoint saved; resume with:"
            f" {self.prog} --resume {out}",
            file=sys.stderr,
        )

    def _refuse_with(self, args: argparse.Namespace, mode: str, why: str) -> None:
        """Refuse the options that ``mode`` (``--resume``, ``--replay``) would ignore."""
        config_class = self.config()
        given = [
            "--" + f.name.replace("_", "-")
            for f in config_class.command_line_fields()
            if getattr(args, f.name, None) is not None
        ]
        given += config_class.given_extra_options(args)
        others = {"--config": args.config, "--resume": args.resume, "--replay": args.replay}
        if mode == "--resume":
            others["--out"] = args.out
        given += [flag for flag, value in others.items() if value and flag != mode]
        if given:
            raise UsageError(f"{mode} {why}: {', '.join(given)} would be ignored; leave them out")

    def _one_run(self, args: argparse.Namespace, progress: bool) -> RunResult:
        if args.resume:
            self._refuse_with(args, "--resume", "continues the run as its config.json says")
            if self.check_resume is not None:
                _named(self.check_resume)(args.resume)
            return self.trainer().resume(args.resume, progress=progress)
        if args.replay:
            self._refuse_with(args, "--replay", "reruns the replayed run's config.json")
            if not args.out:
                raise UsageError("--replay needs --out, the folder of the new run")
            return self.trainer().replay(args.replay, args.out, progress=progress)
        if not args.out:
            raise UsageError("--out is required (or --resume DIR)")
        data = self.config().from_file_and_arguments(args, args.config)
        return self.trainer().fresh(data, args.out, progress=progress)

    def entry_point(self) -> NoReturn:
        """Console-script entry point."""
        raise SystemExit(self.main())
