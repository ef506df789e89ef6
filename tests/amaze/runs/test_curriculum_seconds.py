"""A branch's seconds: its training session's (as the learner reports them) plus the loop's own."""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest

from amaze.curriculum.learner import TrainingOutcome
from tests.amaze.runs.toy_curriculum import ToyLearner, ToyRun

SLEEP = 2.0


def test_the_training_session_is_counted_once(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def train(self, mazes, budget_steps, *, budget_seconds=None, checkpoint=None, progress=None):
        time.sleep(SLEEP)
        return TrainingOutcome(budget_steps, 0.0, False)  # reports none of it

    monkeypatch.setattr(ToyLearner, "train", train)
    config = {"regime": "edhucat", "curator": "random", "stages": 1, "branches": 1}
    ToyRun.fresh({**config, "budget_steps": 100}, tmp_path / "run")
    result = json.loads((tmp_path / "run/stages/stage-0/branch-0/result.json").read_text())
    assert result["seconds"] < SLEEP  # the loop's own time only: loading, evaluation, picture
