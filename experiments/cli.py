"""The ``amaze-experiment`` command: run studies, see where they stand, report them.

::

    amaze-experiment run smoke --out studies/smoke [--workers 2]
    amaze-experiment run my-study.toml --out studies/mine
    amaze-experiment run paper --out /shared/paper --backend ray --address auto   # a cluster
    amaze-experiment status studies/smoke
    amaze-experiment report studies/smoke      # report.md, runs.csv, tests.csv, figures/
    amaze-experiment list                      # the shipped studies
    amaze-experiment ablation studies/base studies/variant [...]   # one factor at a time

``run`` may be stopped (Ctrl-C, or ``kill`` of its process) and started
again at any time: finished runs are kept, killed ones resume
(:mod:`experiments.runner`). ``--backend ray`` runs each run as a Ray task
on the cluster at ``--address`` (:mod:`amaze.runs.cluster`). Bad input
prints one line ``error: ...`` and exits with status 2. ``report`` writes
the report of the runs it can read and prints a ``warning: ...`` line for
each run's file it cannot (:mod:`experiments.report`).
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path
from typing import NoReturn

from amaze.runs.cluster import add_backend_arguments, check_backend
from amaze.runs.command import CommandParser, run_command, terminated_as_interrupt
from amaze.runs.folder import write_bytes
from experiments.ablation import ablation_report
from experiments.report import write_report
from experiments.runner import format_status, run_study, study_status
from experiments.study import load_study, study_names

__all__ = ["entry_point", "main"]


def parser() -> CommandParser:
    p = CommandParser(
        version=True,
        prog="amaze-experiment",
        description="Run a study (a grid of trainers x algorithms x seeds), then report it.",
    )
    commands = p.add_subparsers(dest="command", required=True, parser_class=CommandParser)
    run = commands.add_parser("run", help="run a study's unfinished runs")
    run.add_argument("study", help=f"a shipped study ({', '.join(study_names())}) or a TOML file")
    run.add_argument("--out", required=True, metavar="DIR", help="the study's folder")
    run.add_argument(
        "--workers",
        type=int,
        metavar="N",
        help="runs at once (default: the cores; with Ray, the cluster's CPUs)",
    )
    add_backend_arguments(run)
    run.add_argument(
        "--progress",
        action="store_true",
        default=None,
        help="show the progress bar even when standard error is not a terminal",
    )
    status = commands.add_parser("status", help="what is done, running, failed")
    status.add_argument("out", metavar="DIR")
    report = commands.add_parser("report", help="write report.md, runs.csv and figures")
    report.add_argument("out", metavar="DIR")
    commands.add_parser("list", help="the shipped studies")
    ablation = commands.add_parser(
        "ablation",
        help="how far each variant study moves the base study's medians (experiments.ablation)",
    )
    ablation.add_argument("base", metavar="BASE", help="the base study's folder or runs.csv")
    ablation.add_argument(
        "variants", nargs="+", metavar="VARIANT", help="studies with one factor changed"
    )
    ablation.add_argument("--out", metavar="FILE", help="write the Markdown table there too")
    return p


def _run(argv: Sequence[str]) -> int:
    args = parser().parse_args(list(argv))
    if args.command == "list":
        for name in study_names():
            study = load_study(name)
            print(f"{name}: {len(study.runs)} runs. {study.description.strip().splitlines()[0]}")
        return 0
    if args.command == "status":
        print(format_status(*study_status(args.out)))
        return 0
    if args.command == "report":
        path = write_report(args.out, warn=_warn)
        print(f"report: {path}")
        return 0
    if args.command == "ablation":
        table = ablation_report(args.base, args.variants)
        if args.out:
            write_bytes(Path(args.out), table.encode("utf-8"))
        print(table, end="")
        return 0
    check_backend(args.backend, args.address)
    study = load_study(args.study)
    if args.progress is None:
        progress = "bar" if sys.stderr.isatty() else "lines"
    else:
        progress = "bar" if args.progress else "off"
    # `kill PID` stops the study as Ctrl-C does (a background job ignores Ctrl-C's SIGINT)
    with terminated_as_interrupt():
        try:
            status = run_study(
                study,
                args.out,
                workers=args.workers,
                progress=progress,
                backend=args.backend,
                address=args.address,
            )
        except KeyboardInterrupt:
            print(
                f"interrupted: finished runs are kept, the others resume from their last"
                f" checkpoint; go on with: amaze-experiment run {args.study} --out {args.out}",
                file=sys.stderr,
            )
            raise
    print(format_status(*study_status(args.out)))
    return status


def _warn(message: str) -> None:
    print(f"warning: {message}", file=sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command; return the exit status (2 for bad input, 1 when a run failed)."""
    return run_command(lambda: _run(sys.argv[1:] if argv is None else argv))


def entry_point() -> NoReturn:
    """Console-script entry point."""
    raise SystemExit(main())


if __name__ == "__main__":
    entry_point()
