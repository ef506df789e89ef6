"""What ``amaze-curate --resume`` checks before it serves the page.

A resumed session runs the curriculum loop in a worker thread, once the page
is served: a bad file found there would end the session on a failed page
while the command goes on serving it. :func:`check_resume` runs, before
that, what :meth:`~amaze.runs.lifecycle.Run.resume` checks (the config, the
progress log, and :meth:`~amaze.runs.curriculum.CurriculumRun.restore`: the
decisions, every branch's result against them, every learner the loop will
load) by running the lifecycle up to the start of training, with the
progress log left untouched.

Anything wrong raises the trainer's error (or an ``OSError``) naming the file
or the value, which the command prints as its one ``error: ...`` line.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from amaze.runs.curriculum import CurriculumRun
from amaze.runs.folder import ProgressLog

__all__ = ["check_resume"]


class _Checked(Exception):
    """Raised where the checking run would start training: every check has passed."""


class _UnchangedLog(ProgressLog):
    """A progress log that :meth:`keep` leaves as it is (a resume drops rows; a check does not)."""

    def keep(self, predicate: Callable[[dict[str, str]], bool]) -> None:
        """Nothing: the folder stays as it was."""


def check_resume(base: type[CurriculumRun], out: Path) -> None:
    """Check the session in ``out`` (a run of ``base``) as its resume will read it.

    Raises the config's error or an ``OSError`` naming the first bad file.
    """

    class CheckingRun(base):  # type: ignore[misc, valid-type]
        def __init__(self, out: Any, config: Any) -> None:
            super().__init__(out, config)
            log = self.progress
            self.progress = _UnchangedLog(log.path, log.fields, log.text_fields)

        def train(self, progress: str) -> None:
            raise _Checked

    try:
        CheckingRun.resume(out)
    except _Checked:
        return
