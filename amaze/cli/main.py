"""The ``amaze`` command: inspect, render and measure mazes from their strings.

Every sub-command takes maze strings (``-`` reads them from standard input, one
per line). User mistakes print one line ``error: ...`` on standard error and
exit with status 2; there is no traceback for bad input.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import sys
import warnings
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import NoReturn

from amaze.errors import AmazeError
from amaze.signs import register_custom_signs

EXIT_USAGE = 2


class UsageError(Exception):
    """A mistake in the command line: reported as one line, exit status 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:
        raise UsageError(f"{self.prog}: {message}")


def _maze_strings(arguments: Sequence[str]) -> Iterator[str]:
    """The maze strings of the command line, reading ``-`` from standard input."""
    for argument in arguments:
        if argument == "-":
            for line in sys.stdin:
                if line.strip():
                    yield line.strip()
        else:
            yield argument


def _mazes(arguments: Sequence[str]) -> Iterator:
    from amaze.maze import Maze

    for text in _maze_strings(arguments):
        yield Maze.from_string(text)


def _cmd_inspect(args: argparse.Namespace) -> None:
    from amaze.description import describe, summary

    for index, maze in enumerate(_mazes(args.mazes)):
        if args.json:
            print(json.dumps(describe(maze), separators=(",", ":")), flush=True)
        else:
            print(("\n" if index else "") + summary(maze), flush=True)


def _cmd_render(args: argparse.Namespace) -> None:
    from amaze.maze import Maze
    from amaze.render import RenderOptions, save_maze_png

    maze = Maze.from_string(args.maze)
    options = RenderOptions(
        theme="dark" if args.dark else "light",
        colorblind=args.colorblind,
        solution=args.solution,
        **({"cell_size": args.cell_size} if args.cell_size is not None else {}),
    )
    output = Path(args.output)
    if output.is_dir():
        raise UsageError(f"output '{output}' is a folder; give a file name such as maze.png")
    if output.suffix.lower() != ".png":
        raise UsageError(f"output '{output}' must end in .png")
    path = save_maze_png(maze, output, options)
    print(f"{maze.to_string()} -> {path}")


def _cmd_stats(args: argparse.Namespace) -> None:
    from amaze.description import STATS_COLUMNS, format_table, stats_rows

    rows = list(stats_rows(_mazes(args.mazes)))
    print(format_table(rows))
    if args.csv:
        path = Path(args.csv)
        tmp = path.with_name(path.name + ".tmp")
        with tmp.open("w", newline="") as stream:
            writer = csv.DictWriter(stream, fieldnames=STATS_COLUMNS)
            writer.writeheader()
            writer.writerows(rows)
        tmp.replace(path)
        print(f"wrote {len(rows)} rows to {path}")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``amaze`` and its sub-commands."""
    parser = _Parser(
        prog="amaze",
        description="Generate, inspect, render and measure AMaze mazes from their strings"
        " (e.g. M4_20x20_C1_l.25_L.25_t.5_T.5).",
    )
    parser.add_argument(
        "--signs",
        action="append",
        default=[],
        metavar="PATH",
        help="register custom sign images: a PNG file or a folder of them (repeatable)",
    )
    commands = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    inspect = commands.add_parser("inspect", help="describe mazes (JSON Lines with --json)")
    inspect.add_argument("mazes", nargs="+", metavar="MAZE", help="maze strings; - reads stdin")
    inspect.add_argument("--json", action="store_true", help="one JSON object per maze and line")
    inspect.set_defaults(run=_cmd_inspect)

    render = commands.add_parser("render", help="draw a maze to a PNG file")
    render.add_argument("maze", metavar="MAZE", help="maze string")
    render.add_argument("-o", "--output", default="maze.png", help="PNG file (default maze.png)")
    render.add_argument("--dark", action="store_true", help="dark theme")
    render.add_argument("--colorblind", action="store_true", help="colour-blind-safe palette")
    render.add_argument(
        "--no-solution", dest="solution", action="store_false", help="do not draw the solution"
    )
    render.add_argument("--cell-size", type=int, metavar="PX", help="pixels per cell")
    render.set_defaults(run=_cmd_render)

    stats = commands.add_parser("stats", help="statistics and metrics table of mazes")
    stats.add_argument("mazes", nargs="+", metavar="MAZE", help="maze strings; - reads stdin")
    stats.add_argument("--csv", metavar="FILE", help="also write the table as CSV")
    stats.set_defaults(run=_cmd_stats)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``amaze``; returns the exit status (0, or 2 for a user mistake)."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
        for path in args.signs:
            register_custom_signs(path)
        with warnings.catch_warnings():
            warnings.simplefilter("always")
            warnings.showwarning = _show_warning
            args.run(args)
    except BrokenPipeError:
        # The reader went away (e.g. `amaze inspect ... | head`): stop quietly.
        sys.stdout = open(os.devnull, "w")
        return 0
    except (UsageError, AmazeError, OSError) as error:
        message = str(error).splitlines()[0] if str(error) else type(error).__name__
        if isinstance(error, OSError) and error.filename is not None:
            message = f"{error.strerror}: {error.filename}"
        print(f"error: {message}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        return 130
    return 0


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    print(f"warning: {message}", file=sys.stderr)


def entry_point() -> NoReturn:
    sys.exit(main())


if __name__ == "__main__":
    entry_point()
