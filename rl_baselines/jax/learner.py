"""A JAX trainer as a curriculum learner: :class:`~rl_baselines.learner.SB3Learner`'s behaviour.

:class:`JaxLearner` drives a :class:`~rl_baselines.jax.trainer.JaxTrainer`
through the learner protocol (:class:`amaze.curriculum.learner.Learner`) as
:class:`~rl_baselines.learner.SB3Learner` drives an SB3 model: sessions on
the given mazes (environment ``k`` plays ``mazes[k % len(mazes)]``), spent in
whole rollouts, never one the steps budget cannot pay; evaluated on the
session's mazes every ``eval_every`` steps at a rollout boundary (and at the
session's start), ``checkpoint()`` after each evaluation, stopped once every
episode is optimal. A new session resets the environments into its mazes and
draws from the learner's seed (:meth:`JaxTrainer.reseed`), so its draws
depend on nothing that ran before; :meth:`JaxLearner.branch` copies the
parameters and optimizer state under another seed.

Differences from SB3's, by design: a session continued from a checkpoint
goes on with the saved random key and environments (the whole state is
saved), so a resumed curriculum ends bit for bit as an uninterrupted one on
one machine; a converged session stops at the rollout boundary (SB3 takes one
more env step); a seconds budget is checked between compiled blocks of at
most ``chunk`` rollouts; there is no TensorBoard log.

Files (:meth:`JaxLearner.save`): ``trainer/`` (:mod:`rl_baselines.jax.storage`)
and ``learner.json`` (seed, ``eval_every``, the session in progress), read
back by :func:`load_jax_learner`, every field checked.
"""

from __future__ import annotations

import copy
import os
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from amaze.curriculum.learner import SessionWatch, TrainingOutcome, checked_session_budget
from amaze.evaluation.protocol import Evaluator
from amaze.maze.spec import MazeSpec
from amaze.runs.config import read_json_object
from amaze.runs.folder import write_json
from amaze.validation import check_integer
from rl_baselines import RLConfigError
from rl_baselines.jax.agent import JaxAgent
from rl_baselines.jax.storage import save_trainer
from rl_baselines.jax.trainer import JaxTrainer
from rl_baselines.learner import LEARNER_FILE, OPTIMAL, Sessions, checked_session

__all__ = ["LEARNER_FORMAT", "TRAINER_FOLDER", "JaxLearner", "load_jax_learner"]

LEARNER_FORMAT = "jax-learner"
TRAINER_FOLDER = "trainer"


class JaxLearner(Sessions):
    """A JAX trainer in training, as a curriculum drives it (see the module docstring)."""

    def __init__(
        self,
        trainer: JaxTrainer,
        *,
        seed: int,
        eval_every: int,
        session: dict[str, Any] | None = None,
    ) -> None:
        self.trainer = trainer
        self.seed = int(seed)
        self.eval_every = int(eval_every)
        self.session: dict[str, Any] | None = session
        self._checkpoint: Callable[[], None] | None = None
        self._evaluator: Evaluator | None = None
        self._clock = (time.monotonic(), 0.0)

    @property
    def rollout(self) -> int:
        """Env steps of one rollout."""
        return self.trainer.hyperparameters.rollout_size

    def robot_name(self) -> str:
        """The robot the learner trains."""
        return self.trainer.static.env.robot.to_string()

    # -- the protocol -----------------------------------------------------------------

    def train(
        self,
        mazes: Sequence[str],
        budget_steps: int | None,
        *,
        budget_seconds: float | None = None,
        checkpoint: Callable[[], None] | None = None,
        progress: Callable[[int], None] | None = None,
        watch: SessionWatch | None = None,
    ) -> TrainingOutcome:
        """One session on ``mazes`` (continued if this learner was saved inside it).

        As :meth:`rl_baselines.learner.SB3Learner.train`: whole rollouts within
        ``budget_steps``, and/or ``budget_seconds``, judged on ``watch``'s mazes
        when given; a saved session goes on only with the same mazes, budgets and watch.
        """
        budget_steps, budget_seconds = checked_session_budget(
            budget_steps, budget_seconds, RLConfigError
        )
        mazes = [MazeSpec.from_string(str(m)).to_string() for m in mazes]
        session = self._open_session(mazes, budget_steps, budget_seconds, watch)
        if session["steps"] == 0 and session["last_eval"] is None:
            self.trainer.set_mazes(mazes)  # a new session: its environments, its draws
            self.trainer.reseed(self.seed)
        elif self.trainer.mazes != mazes:
            raise RLConfigError("a continued session's trainer plays other mazes than it")
        self._checkpoint = checkpoint
        self._evaluator = Evaluator(self.robot_name(), mazes, inputs=False)
        target = None if budget_steps is None else budget_steps // self.rollout * self.rollout
        while self._goes_on(target):
            self._session_point()
            if session["converged"]:
                break
            count = self._block(target)
            self.trainer.run(count)
            session["steps"] += count * self.rollout
            if progress is not None:
                progress(int(session["steps"]))
        self._final_watch_point()
        return self._close_session()

    def branch(self, seed: int) -> JaxLearner:
        """An independent copy (parameters, optimizer state) whose sessions draw from ``seed``."""
        trainer = copy.copy(self.trainer)  # its state is immutable arrays: shared safely
        trainer.reseed(int(seed))
        return JaxLearner(trainer, seed=int(seed), eval_every=self.eval_every)

    def agent(self) -> JaxAgent:
        """The policy now, acting deterministically (saved as an SB3 agent)."""
        return JaxAgent(self.trainer)

    def save(self, folder: Path) -> None:
        """``trainer/`` and ``learner.json`` in ``folder`` (a curriculum writes it whole)."""
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        if self.session is not None:
            self.session["seconds"] = self._seconds()
        save_trainer(self.trainer, folder / TRAINER_FOLDER)
        write_json(folder / LEARNER_FILE, self.state())

    def state(self) -> dict[str, Any]:
        """The content of ``learner.json``."""
        return {
            "format": LEARNER_FORMAT,
            "seed": self.seed,
            "eval_every": self.eval_every,
            "num_timesteps": self.trainer.num_timesteps,
            "session": self.session,
        }

    # -- the session's own --------------------------------------------------------------

    def _block(self, target: int | None) -> int:
        """Rollouts up to the next evaluation due, the session's end or (seconds) one chunk."""
        session = self.session
        assert session is not None
        steps = int(session["steps"])
        limit = 2**31 if target is None else (target - steps) // self.rollout
        if session.get("budget_seconds") is not None:
            limit = min(limit, self.trainer.chunk)
        if self._watch is not None:
            due = int(session["watch"]["last"]) + self._watch.every - steps
        else:
            due = int(session["last_eval"]) + self.eval_every - steps
        return max(1, min(limit, -(-due // self.rollout)))

    def _session_point(self) -> None:
        """A rollout starts: evaluate if due, then checkpoint (as SB3Learner's)."""
        session = self.session
        assert session is not None and self._evaluator is not None
        steps, last = int(session["steps"]), session["last_eval"]
        if self._watch is not None:
            if self._watch_point(steps) and self._checkpoint is not None:
                self._checkpoint()
            return
        if last is not None and steps - last < self.eval_every:
            return
        report = self._evaluator.evaluate(self.agent())
        session["converged"] = all(e.normalized_reward >= OPTIMAL for e in report.episodes)
        session["last_eval"] = steps
        if self._checkpoint is not None:
            self._checkpoint()


def load_jax_learner(
    folder: str | os.PathLike, *, algo: str, robot: str, n_envs: int
) -> JaxLearner:
    """The learner saved in ``folder`` by :meth:`JaxLearner.save`, checked against the run.

    A learner of another algorithm, robot or ``n_envs``, or any missing or
    damaged file, raises :class:`RLConfigError` naming it.
    """
    folder = Path(folder)
    path = folder / LEARNER_FILE
    source = f"learner file {str(path)!r}"
    data = read_json_object(path, RLConfigError, "learner file")
    if data.get("format") != LEARNER_FORMAT:
        raise RLConfigError(f"{source}: format {data.get('format')!r} is not {LEARNER_FORMAT!r}")
    seed = check_integer(f"{source}: seed", data.get("seed"), minimum=0, error=RLConfigError)
    eval_every = check_integer(
        f"{source}: eval_every", data.get("eval_every"), minimum=1, error=RLConfigError
    )
    steps = check_integer(
        f"{source}: num_timesteps", data.get("num_timesteps"), minimum=0, error=RLConfigError
    )
    session = checked_session(data.get("session"), source)
    trainer = JaxTrainer.load(folder / TRAINER_FOLDER)
    trainer.check_settings({"algo": algo, "robot": robot, "n_envs": n_envs}, source)
    if trainer.num_timesteps != steps:
        raise RLConfigError(
            f"{source}: num_timesteps {steps} is not the {trainer.num_timesteps} of its"
            " trainer (the two are of different saves)"
        )
    return JaxLearner(trainer, seed=seed, eval_every=eval_every, session=session)
