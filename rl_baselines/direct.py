"""The direct regime of ``amaze-train``, whatever framework trains: what both runs share.

:class:`DirectRun` is the part of a direct RL run that does not depend on
what learns (SB3, :class:`rl_baselines.train.SB3Run`, or the JAX learners,
:class:`rl_baselines.jax.run.JaxRun`): the evaluations on ``eval_mazes``
every ``eval_every`` env steps (the champion, convergence, ``progress.csv``),
the training clock and seconds budget, the checkpoint's ``state.json``
(checked on resume), the agent rule and the summary's figures. A subclass
says how many env steps it has trained (:attr:`DirectRun.steps`), how big a
rollout is, how it trains, checkpoints and restores its model, and which
agent it holds now (:meth:`DirectRun.current_model_agent`). Both write the
same run folder (see :mod:`rl_baselines.train`).
"""

from __future__ import annotations

import os
import time
from abc import abstractmethod
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from amaze.curriculum.learner import EVALUATION_RULES, evaluation_score
from amaze.evaluation.protocol import EvaluationReport, Evaluator
from amaze.maze import rotations
from amaze.runs.anytime import Spent
from amaze.runs.config import read_json_object
from amaze.runs.lifecycle import Run
from amaze.validation import check_integer, check_number
from rl_baselines import RLConfigError
from rl_baselines.agent import SB3Agent
from rl_baselines.config import TrainConfig
from rl_baselines.learner import OPTIMAL

__all__ = ["LATEST_FOLDER", "PROGRESS_FIELDS", "DirectRun", "checked_state"]

#: The folder of ``checkpoints/`` that holds the latest model and its state.
LATEST_FOLDER = "latest"

PROGRESS_FIELDS = ("steps", "seconds", "eval_success_rate", "eval_normalized_reward")


def checked_state(state: dict[str, Any]) -> dict[str, Any]:
    """``checkpoints/latest/state.json``'s content with every field checked (types and ranges)."""

    def integer(name: str, minimum: int) -> int:
        return check_integer(
            f"checkpoint state {name}", state.get(name), minimum=minimum, error=RLConfigError
        )

    best = state.get("best")
    if best is not None and not (
        isinstance(best, list)
        and len(best) in (1, 2)
        and all(isinstance(v, int | float) and not isinstance(v, bool) for v in best)
    ):
        raise RLConfigError(f"checkpoint state best {best!r} is not null or one or two numbers")
    if not isinstance(state.get("converged"), bool):
        raise RLConfigError(f"checkpoint state converged {state.get('converged')!r} is not a bool")
    seconds = check_number(
        "checkpoint state seconds", state.get("seconds"), minimum=0, error=RLConfigError
    )
    return {
        "num_timesteps": integer("num_timesteps", 0),
        "seconds": seconds,
        "best": best,
        "converged": state["converged"],
        "last_eval_steps": integer("last_eval_steps", -1),
        # absent in run folders written before agent rules: the evaluation at step 0 is unknown
        "best_steps": integer("best_steps", 0) if "best_steps" in state else 0,
    }


class DirectRun(Run):
    """A direct RL run, evaluated every ``eval_every`` steps (see the module docstring)."""

    config_class = TrainConfig
    progress_fields = PROGRESS_FIELDS
    position_field = "steps"
    agent_file = "agent.zip"
    config: TrainConfig

    def __init__(self, out: str | os.PathLike, config: TrainConfig) -> None:
        super().__init__(out, config)
        self.seconds_before = 0.0
        #: The champion's score (:func:`~amaze.curriculum.learner.evaluation_score`).
        self.best: tuple[float, ...] | None = None
        #: Env steps at which the best evaluated model was evaluated.
        self.best_steps = 0
        self.converged = False
        self.last_eval_steps = -1
        self.started = time.monotonic()

    # -- what the framework says ------------------------------------------------------

    @property
    @abstractmethod
    def steps(self) -> int:
        """Env steps trained on so far (the model's ``num_timesteps``)."""

    @property
    @abstractmethod
    def rollout(self) -> int:
        """Env steps of one rollout (``n_steps x n_envs``): the smallest unit of training."""

    @abstractmethod
    def current_model_agent(self) -> Any:
        """The model as it is now, acting deterministically (an agent with ``save(path)``)."""

    # -- the clock ------------------------------------------------------------------

    def seconds(self) -> float:
        """Wall-clock seconds of training, over every resumed part of the run."""
        return self.seconds_before + (time.monotonic() - self.started)

    def out_of_time(self) -> bool:
        """True once the run's seconds reach ``budget_seconds`` (never without one)."""
        budget = self.config.budget_seconds
        return budget is not None and self.seconds() >= budget

    # -- evaluations ------------------------------------------------------------------

    @property
    def champion_file(self) -> Path:
        """The best evaluated model so far (``champion.zip`` at the top in older run folders)."""
        legacy = self.out / "champion.zip"
        return legacy if legacy.exists() else self.checkpoints / "champion.zip"

    def evaluator(self) -> Evaluator:
        """The evaluation of every ``eval_every`` steps: the 4 rotations of each evaluation maze."""
        c = self.config
        mazes = [rotated for maze in c.eval_mazes for rotated in rotations(maze)]
        return Evaluator(c.robot, mazes=mazes, inputs=False)

    def record_evaluation(self, agent: Any, report: EvaluationReport) -> tuple[float, float]:
        """Keep an evaluation of ``agent`` (the model now): champion, convergence, progress row.

        Returns its score, ``(success rate, R̄)``; the caller checkpoints after it.
        """
        steps = self.steps
        summary = report.summary()
        score = (float(summary["success_rate"]), float(summary["normalized_reward"]))
        rule = self.champion_rule
        ranked = tuple(evaluation_score(rule, summary))
        # SB3's EvalCallback (best-eval-reward) first evaluates after training has begun
        candidate = rule != "best-eval-reward" or steps > 0
        if candidate and (self.best is None or ranked > self.best):
            self.best, self.best_steps = ranked, steps
            agent.save(self.champion_file)
        self.converged = all(e.normalized_reward >= OPTIMAL for e in report.episodes)
        self.last_eval_steps = steps
        self.progress.append(
            {
                "steps": steps,
                "seconds": round(self.seconds(), 3),
                "eval_success_rate": score[0],
                "eval_normalized_reward": score[1],
            }
        )
        return score

    @property
    def champion_rule(self) -> str:
        """How evaluations rank the champion: the agent rule's, else ``best-eval``."""
        rule = self.config.agent_rule
        return rule if rule in EVALUATION_RULES else "best-eval"

    def best_shown(self) -> dict[str, str]:
        """The champion's score as a progress line shows it (success rate, or R̄ alone)."""
        if self.champion_rule == "best-eval-reward":
            return {"best_eval_reward": "n/a" if self.best is None else f"{self.best[0]:.2f}"}
        return {"best_eval_success": "n/a" if self.best is None else f"{self.best[0]:.2f}"}

    # -- checkpoints ------------------------------------------------------------------

    def checkpoint_state(self) -> dict[str, Any]:
        """``state.json`` of a checkpoint: steps, seconds, evaluation state, config digest."""
        return {
            "num_timesteps": self.steps,
            "seconds": self.seconds(),
            "best": list(self.best) if self.best is not None else None,
            "best_steps": self.best_steps,
            "converged": self.converged,
            "last_eval_steps": self.last_eval_steps,
            "config_sha256": self.config_digest,
        }

    def restore_state(self, state_file: Path) -> int:
        """Read a checkpoint's ``state.json`` (checked) and the champion; its ``num_timesteps``.

        Sets the evaluation state and restarts the clock; the model is the
        subclass's to restore.
        """
        data = read_json_object(state_file, RLConfigError, "checkpoint file")
        try:
            state = checked_state(data)
        except RLConfigError as problem:
            raise RLConfigError(f"checkpoint file {str(state_file)!r}: {problem}") from None
        self.check_config_digest(data.get("config_sha256"), f"checkpoint file {str(state_file)!r}")
        champion = [self.champion_file, self.champion_file.with_suffix(".json")]
        if any(f.exists() or f.is_symlink() for f in champion):
            self.load_agent(champion[0])  # a damaged champion is refused here, by name
        self.seconds_before = state["seconds"]
        self.best = tuple(state["best"]) if state["best"] is not None else None
        self.best_steps = state["best_steps"]
        self.converged = state["converged"]
        self.last_eval_steps = state["last_eval_steps"]
        self.started = time.monotonic()
        return int(state["num_timesteps"])

    # -- the lifecycle's hooks --------------------------------------------------------

    def spent(self) -> Spent:
        return Spent(self.steps, self.steps, self.seconds())

    def final_agent(self) -> Any:
        """The model when training stopped, or the best evaluated one (``agent_rule``).

        A run on seconds that ended before any evaluation after training
        began has no ``best-eval-reward`` champion: it hands over the model
        (``agent_figures`` says so).
        """
        if self.config.agent_rule in EVALUATION_RULES and self.best is not None:
            return self.load_agent(self.champion_file)
        return self.current_model_agent()

    def load_agent(self, path: Path) -> Any:
        """The agent saved at ``path`` (the champion), checked: an SB3 agent here."""
        return SB3Agent.load(path)

    def save_agent(self, agent: Any, path: Path) -> None:
        agent.save(path)

    def agent_figures(self) -> dict[str, Any]:
        c = self.config
        rule = c.agent_rule
        if rule in EVALUATION_RULES and self.best is None:
            rule = f"final ({rule} found no evaluated model after training began)"
        steps = self.best_steps if rule in EVALUATION_RULES else self.steps
        return {"agent_rule": rule, "agent_steps": steps, "agent_untrained": steps == 0}

    def stop_reason(self) -> str:
        c, steps = self.config, self.steps
        if self.converged:
            return f"converged: every evaluation episode optimal (R̄ = 1) at {steps:,} env steps"
        if c.budget_steps is not None and c.budget_steps - steps < self.rollout:
            return (
                f"the {c.budget_steps - steps:,} steps left cannot pay another rollout"
                f" ({self.rollout:,} steps)"
            )
        return ""

    def figures(self) -> dict[str, Any]:
        c = self.config
        return {
            "env_steps": self.steps,
            "seconds": round(self.seconds(), 3),
            "budget_steps": c.budget_steps,
            "budget_seconds": c.budget_seconds,
            "converged": self.converged,
            "algo": c.algo,
            "framework": c.framework,
            "regime": c.regime,
            "robot": c.robot,
            "seed": c.seed,
        }

    def trajectory_mazes(self) -> list[tuple[str, str]]:
        """The agent in the 4 rotations of the first evaluation maze."""
        mazes = rotations(self.config.eval_mazes[0])
        return [(f"evaluation-rotation-{index}", maze) for index, maze in enumerate(mazes)]

    @classmethod
    def headline(cls, summary: Mapping[str, Any]) -> str:
        regime = f"{summary['algo']} {summary['regime']}"
        if summary.get("framework", "sb3") != "sb3":
            regime += f" ({summary['framework']})"
        return f"{regime}, converged {summary['converged']}: {super().headline(summary)}"
