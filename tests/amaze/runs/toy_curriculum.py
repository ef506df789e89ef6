"""A toy trainer for testing the curriculum loop without a real one.

:class:`ToyLearner` "trains" by counting the steps it is given, and plays a
random controller seeded by its branch: cheap, deterministic, and enough for
the loop's bookkeeping (decisions, budgets, stages, resume, replay) to be
checked. Real learners are tested in ``tests/evolution`` and ``tests/rl_baselines``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from amaze.curriculum.learner import TrainingOutcome
from amaze.evaluation.controllers import RandomController
from amaze.runs.config import option
from amaze.runs.curriculum import CurriculumRun
from amaze.runs.folder import write_json
from amaze.runs.regime import RegimeConfig


class ToyError(ValueError):
    pass


@dataclass
class ToyConfig(RegimeConfig):
    budget_steps: int = option(6000, "environment steps")


class ToyLearner:
    """Spends its budget in chunks of 500 steps, calling ``checkpoint`` after each."""

    def __init__(self, seed: int, trained: int = 0, session: dict | None = None) -> None:
        self.seed, self.trained, self.session = seed, trained, session

    def train(self, mazes, budget_steps, *, budget_seconds=None, checkpoint=None, progress=None):
        if not (self.session and self.session["mazes"] == list(mazes)):
            self.session = {"mazes": list(mazes), "budget": budget_steps, "spent": 0}
        self.budget_seconds = budget_seconds  # what the loop gave it, for the tests
        limit = 500 if budget_steps is None else budget_steps  # a time budget: one chunk
        while self.session["spent"] < limit:
            chunk = min(500, limit - self.session["spent"])
            self.session["spent"] += chunk
            self.trained += chunk
            if progress is not None:
                progress(self.session["spent"])
            if checkpoint is not None:
                checkpoint()
        spent, self.session = self.session["spent"], None
        return TrainingOutcome(spent, 0.0, False)

    def branch(self, seed):
        return ToyLearner(seed, self.trained)

    def agent(self):
        return RandomController("DD", seed=self.seed % 1000)

    def save(self, folder):
        data = {"seed": self.seed, "trained": self.trained, "session": self.session}
        data["budget_seconds"] = getattr(self, "budget_seconds", None)
        write_json(Path(folder) / "toy.json", data)


class ToyRun(CurriculumRun):
    config_class = ToyConfig
    agent_file = "agent.json"

    def save_agent(self, agent, path):
        write_json(path, {"controller": "random", "seed": agent.seed})

    def new_learner(self, seed):
        return ToyLearner(seed)

    def load_learner(self, folder):
        try:
            data = json.loads((Path(folder) / "toy.json").read_text())
            return ToyLearner(data["seed"], data["trained"], data["session"])
        except (OSError, ValueError, KeyError) as problem:
            raise ToyError(f"toy learner in {str(folder)!r}: {problem}") from None
