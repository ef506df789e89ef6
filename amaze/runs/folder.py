"""Run folders: the files every training command writes, written safely.

A run folder (``docs/architecture.md`` §5.4) holds ``config.json``,
``progress.csv``, ``checkpoints/``, the champion agent and ``summary.json``.
Both trainers (``rl_baselines`` and ``evolution``) write them through these
helpers so that a run killed at any moment leaves readable files behind:

* :func:`write_json` and :func:`write_bytes` write a temporary file and rename
  it over the old one (atomic on POSIX): a reader sees the old or the new file,
  never half of one;
* :func:`write_folder` does the same for a folder of several files (a
  learner's checkpoint): it is read whole, old or new, never a mix of both;
* :class:`ProgressLog` appends one CSV row per evaluation or generation and,
  on resume, drops the rows written after the checkpoint being resumed, so the
  log of a resumed run reads as that of an uninterrupted one;
* :func:`write_folder` and the checkpoints (:mod:`amaze.runs.checkpoint`) are
  written with Ctrl-C and SIGTERM held back (:func:`amaze.signals.signals_deferred`,
  re-exported here), so that a stop lands before or after the write, never
  inside a library's writer (whose half-closed objects would print tracebacks
  at exit).
"""

from __future__ import annotations

import csv
import io
import json
import os
import shutil
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from amaze.signals import signals_deferred

__all__ = [
    "OLD_COLUMNS",
    "ProgressLog",
    "read_text",
    "settled_folder",
    "signals_deferred",
    "write_bytes",
    "write_folder",
    "write_json",
    "write_rows",
]

#: Columns of ``progress.csv`` files written before R̄ and the success rate had one
#: name everywhere, and their names now: such a log is read as if written today
#: (and rewritten so by a resume).
OLD_COLUMNS = {
    "rbar": "normalized_reward",
    "success": "success_rate",
    "eval_rbar": "eval_normalized_reward",
    "eval_success": "eval_success_rate",
    "batch_success": "batch_success_rate",
    "validation_success": "validation_success_rate",
    "champion_success": "champion_success_rate",
}


def write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (temporary file in the same folder, then rename)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    with open(tmp, "wb") as stream:
        stream.write(data)
        stream.flush()
        os.fsync(stream.fileno())
    os.replace(tmp, path)
    return path


def write_json(path: str | os.PathLike, data: Any) -> Path:
    """Write ``data`` as indented, key-sorted JSON, atomically."""
    text = json.dumps(data, indent=2, sort_keys=True) + "\n"
    return write_bytes(path, text.encode("utf-8"))


def write_rows(path: str | os.PathLike, rows: Sequence[Mapping[str, Any]]) -> Path:
    """Write ``rows`` (at least one; the first one's keys are the columns) as CSV, atomically."""
    stream = io.StringIO(newline="")
    writer = csv.DictWriter(stream, fieldnames=list(rows[0]))
    writer.writeheader()
    writer.writerows(rows)
    return write_bytes(path, stream.getvalue().encode("utf-8"))


def write_folder(path: str | os.PathLike, fill: Callable[[Path], None]) -> Path:
    """Fill the folder ``path`` by ``fill(folder)`` atomically: old or new, never a mix.

    ``fill`` writes into a fresh sibling ``.<name>.tmp``; once it is complete,
    the old folder is renamed aside (``.<name>.old``), the new one into place,
    and the old one removed. A kill between the two renames leaves no ``path``
    but a complete ``.tmp``, which :func:`settled_folder` puts in place. (A
    learner writes two files; written in place, a kill between them left a
    checkpoint whose files disagreed, or one without its learner.) Ctrl-C and
    SIGTERM wait for it (:func:`signals_deferred`).
    """
    path = Path(path)
    tmp, old = _aside(path, "tmp"), _aside(path, "old")
    with signals_deferred():  # a stop waits for the folder: fill's writers are never cut
        shutil.rmtree(tmp, ignore_errors=True)
        tmp.mkdir(parents=True)
        fill(tmp)
        shutil.rmtree(old, ignore_errors=True)
        if path.exists():
            os.replace(path, old)
        os.replace(tmp, path)
        shutil.rmtree(old, ignore_errors=True)
    return path


def settled_folder(path: str | os.PathLike) -> Path:
    """``path`` once what a killed :func:`write_folder` left is put right.

    If the kill came between its two renames, the new folder (complete) takes
    its place; a half-written ``.tmp`` or a left-over ``.old`` is removed.
    """
    path = Path(path)
    tmp, old = _aside(path, "tmp"), _aside(path, "old")
    if not path.exists() and old.exists() and tmp.exists():
        os.replace(tmp, path)
    shutil.rmtree(tmp, ignore_errors=True)
    shutil.rmtree(old, ignore_errors=True)
    return path


def _aside(path: Path, kind: str) -> Path:
    """The sibling :func:`write_folder` writes through."""
    return path.with_name(f".{path.name}.{kind}")


def read_text(path: Path, error: type[ValueError], what: str) -> str:
    """The UTF-8 text of the file ``path``; ``error`` names it (as ``what``) otherwise."""
    try:
        return path.read_bytes().decode("utf-8")
    except IsADirectoryError:
        raise error(f"{what} {str(path)!r} is a directory") from None
    except UnicodeDecodeError:
        raise error(f"{what} {str(path)!r} is not text") from None


class ProgressLog:
    """``progress.csv``: one row per evaluation (or generation), with fixed columns."""

    def __init__(
        self, path: str | os.PathLike, fields: Sequence[str], text_fields: Sequence[str] = ()
    ) -> None:
        self.path = Path(path)
        self.fields = tuple(fields)
        #: The columns that hold text; every other one holds numbers.
        self.text_fields = frozenset(text_fields)

    def append(self, row: Mapping[str, Any]) -> None:
        """Add one row (the header first, if the file is new)."""
        new = not self.path.exists()
        with self.path.open("a", newline="") as stream:
            writer = csv.DictWriter(stream, fieldnames=self.fields)
            if new:
                writer.writeheader()
            writer.writerow(row)

    def rows(self) -> list[dict[str, str]]:
        """Every row, as strings (empty if the file does not exist)."""
        if not self.path.exists():
            return []
        with self.path.open(newline="") as stream:
            return [
                {OLD_COLUMNS.get(key, key): value for key, value in row.items()}
                for row in csv.DictReader(stream)
            ]

    def checked_rows(self, position_field: str, error: type[ValueError]) -> list[dict[str, str]]:
        """Every row, after checking the file is this log; raise ``error`` naming it otherwise.

        The header must be :attr:`fields`, every row must have one value per
        column, a number in every column but the text ones, and an integer
        ``position_field`` that never decreases. A last
        line without its newline is a row torn by a kill during the write: it
        is left out (it was written after the last checkpoint).
        """
        where = repr(str(self.path))
        if not self.path.exists():
            return []
        text = read_text(self.path, error, "progress log")
        lines = text.splitlines(keepends=True)
        if lines and not lines[-1].endswith("\n"):
            lines.pop()
        records = list(csv.reader(lines))
        if records:
            records[0] = [OLD_COLUMNS.get(name, name) for name in records[0]]
        if not records or tuple(records[0]) != self.fields:
            raise error(
                f"progress log {where} does not start with the header {','.join(self.fields)}"
            )
        rows, last = [], None
        for number, values in enumerate(records[1:], start=2):
            if len(values) != len(self.fields):
                raise error(
                    f"progress log {where}, line {number}:"
                    f" {len(values)} values, not {len(self.fields)}"
                )
            row = dict(zip(self.fields, values, strict=True))
            try:
                position = int(row[position_field])
            except ValueError:
                raise error(
                    f"progress log {where}, line {number}: {position_field} {row[position_field]!r}"
                    " is not an integer"
                ) from None
            for name, value in row.items():
                if name not in self.text_fields and name != position_field:
                    try:
                        float(value)
                    except ValueError:
                        raise error(
                            f"progress log {where}, line {number}: {name} {value!r} is not a number"
                        ) from None
            if last is not None and position < last:
                raise error(f"progress log {where}, line {number}: {position_field} goes back")
            rows.append(row)
            last = position
        return rows

    def keep(self, predicate: Callable[[dict[str, str]], bool]) -> None:
        """Rewrite the log (atomically) with only the rows ``predicate`` accepts."""
        if not self.path.exists():
            return
        rows = [row for row in self.rows() if predicate(row)]
        tmp = self.path.with_name(f".{self.path.name}.tmp")
        with tmp.open("w", newline="") as stream:
            writer = csv.DictWriter(stream, fieldnames=self.fields)
            writer.writeheader()
            writer.writerows(rows)
        os.replace(tmp, self.path)
