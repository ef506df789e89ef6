"""An SB3 A2C/PPO model as a curriculum learner (:class:`amaze.curriculum.learner.Learner`).

:class:`SB3Learner` trains its model in sessions (``train(mazes, budget_steps,
budget_seconds=...)``): the model's environment becomes an
:class:`~rl_baselines.vec_env.SB3VecEnv` over the session's mazes (environment
``k`` plays ``mazes[k % len(mazes)]``), and SB3 learns in whole rollouts
(``n_steps x n_envs`` steps): as many as fit in the steps budget, never a
rollout it cannot pay. A seconds budget (the session's training seconds over every resumed part
of it) ends the session at the first env step that finds it spent, the
rollout then in progress not learned from; with both budgets the session ends
at whichever comes first. Where a session on a seconds budget ends depends on
the machine's speed, so it does not replay, nor resume, bit-identically. At
the start of a rollout, when ``eval_every`` steps have passed since the last
evaluation (and at the session's start), the model is evaluated on the
session's mazes (the shared :class:`~amaze.evaluation.protocol.Evaluator`,
deterministic actions) and the session's ``checkpoint()`` is called; once
every episode is optimal (R̄ = 1) the session stops: it has converged. A
watched session (:class:`~amaze.curriculum.learner.SessionWatch`) is
evaluated on the watch's mazes instead, every ``watch.every`` steps (never at
its start), keeps its best agent through ``watch.keep_best()`` and converges
there; ``eval_every`` then plays no part.

Files (:meth:`SB3Learner.save`, each written atomically): ``model.zip``, SB3's
zip (weights and optimiser state), and ``learner.json``: the learner's own
settings and the session in progress, if any (mazes, budgets, steps, seconds,
evaluation state), so a learner saved from ``checkpoint()`` and loaded again
continues its session (one with the same mazes and budgets).
:func:`load_sb3_learner` reads them back without unpickling
(:func:`~rl_baselines.agent.load_sb3_model`), every field checked.
"""

from __future__ import annotations

import io
import os
import tempfile
import time
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback

from amaze.agents.robot import as_robot
from amaze.curriculum.learner import (
    EVALUATION_RULES,
    SessionWatch,
    TrainingOutcome,
    checked_session_budget,
    evaluation_score,
)
from amaze.evaluation.protocol import Evaluator
from amaze.maze.spec import MazeSpec
from amaze.runs.config import read_json_object
from amaze.runs.folder import write_json
from amaze.validation import check_integer, check_number
from rl_baselines import RLConfigError
from rl_baselines.agent import SB3Agent, algorithm_class, load_sb3_model
from rl_baselines.networks import small_cnn_kwargs
from rl_baselines.vec_env import SB3VecEnv

__all__ = [
    "LEARNER_FILE",
    "MODEL_FILE",
    "OPTIMAL",
    "SB3Learner",
    "checked_session",
    "load_sb3_learner",
]

MODEL_FILE = "model.zip"
LEARNER_FILE = "learner.json"
LEARNER_FORMAT = "sb3-learner"
#: R̄ at or above this counts as optimal (R̄ is 1 for a run in l-1 steps).
OPTIMAL = 1.0 - 1e-9
#: What a watched session's record says of its watch (its state besides: last, best, best_steps).
WATCH_KEYS = ("mazes", "every", "rule")
#: ``total_timesteps`` of a ``learn`` with no step limit (a seconds budget alone).
UNLIMITED_STEPS = 2**62


def new_sb3_model(
    algo: str,
    robot: str,
    env: Any,
    seed: int,
    hyperparameters: Mapping[str, Any],
    tensorboard_log: str | None = None,
) -> BaseAlgorithm:
    """A fresh SB3 model: MlpPolicy for discrete inputs, the small CNN otherwise.

    Bad hyperparameters raise :class:`RLConfigError`.
    """
    kwargs = dict(hyperparameters)
    kwargs.setdefault("tensorboard_log", tensorboard_log)
    if as_robot(robot).discrete_inputs:
        policy = "MlpPolicy"
    else:
        policy = "CnnPolicy"
        kwargs["policy_kwargs"] = {**small_cnn_kwargs(), **(kwargs.get("policy_kwargs") or {})}
    try:
        return algorithm_class(algo)(policy, env, seed=seed, device="cpu", verbose=0, **kwargs)
    except (TypeError, ValueError, AssertionError) as error:
        raise RLConfigError(f"bad hyperparameters for {algo}: {error}") from None


class _SessionCallback(BaseCallback):
    """At the start of a rollout: evaluate when due, then checkpoint.

    Stops learning (at the next step) once converged, and at the first step
    that finds the session's seconds spent.
    """

    def __init__(
        self,
        learner: SB3Learner,
        start: int,
        steps_before: int,
        progress: Callable[[int], None] | None = None,
    ) -> None:
        super().__init__(verbose=0)
        self.learner = learner
        self.start = start
        self.steps_before = steps_before
        self.progress = progress

    def _on_rollout_start(self) -> None:
        steps = self.steps_before + self.model.num_timesteps - self.start
        if self.progress is not None:
            self.progress(int(steps))
        if self.learner._out_of_time():
            return  # the session ends at the next step: no evaluation nor checkpoint
        self.learner._session_point(steps)

    def _on_step(self) -> bool:
        assert self.learner.session is not None
        return not self.learner.session["converged"] and not self.learner._out_of_time()


class Sessions(ABC):
    """What the two RL learners (SB3's and JAX's) share: a session's record, clock and budgets.

    A session is one call of ``train`` on a list of mazes: its ``session``
    record (mazes, budgets, steps, seconds, convergence, last evaluation) is
    saved with the learner, so a killed session continues where it was.
    """

    session: dict[str, Any] | None
    _clock: tuple[float, float]
    _checkpoint: Callable[[], None] | None
    _watch: SessionWatch | None = None
    _watch_evaluator: Evaluator | None = None

    def _open_session(
        self,
        mazes: list[str],
        budget_steps: int | None,
        budget_seconds: float | None,
        watch: SessionWatch | None = None,
    ) -> dict[str, Any]:
        """The saved session if it is this one (same mazes, budgets and watch), else a new one.

        A watched session evaluates on the watch's mazes (:meth:`_watch_point`)
        instead of its own; its record keeps the watch's evaluation state.
        """
        session = self.session
        watched = None
        if watch is not None:
            canonical = [MazeSpec.from_string(str(m)).to_string() for m in watch.mazes]
            watched = {"mazes": canonical, "every": watch.every, "rule": watch.rule}
            self._watch_evaluator = Evaluator(self.robot_name(), canonical, inputs=False)
        self._watch = watch
        saved = None if session is None else session.get("watch")
        if (
            session is None
            or session["mazes"] != mazes
            or session["budget"] != budget_steps
            or session.get("budget_seconds") != budget_seconds
            or (None if saved is None else {k: saved[k] for k in WATCH_KEYS}) != watched
        ):
            session = self.session = {
                "mazes": mazes,
                "budget": budget_steps,
                "budget_seconds": budget_seconds,
                "steps": 0,
                "seconds": 0.0,
                "converged": False,
                "last_eval": None,
            }
            if watched is not None:
                session["watch"] = {**watched, "last": 0, "best": None, "best_steps": None}
        self._clock = (time.monotonic(), float(session["seconds"]))
        return session

    @abstractmethod
    def robot_name(self) -> str:
        """The robot the learner trains (what its evaluations play)."""

    @abstractmethod
    def agent(self) -> Any:
        """The agent now, acting deterministically."""

    def _watch_point(self, steps: int) -> bool:
        """Evaluate on the watch's mazes if one is due at ``steps``; True if it evaluated.

        A strictly better score than the session's best calls the watch's
        ``keep_best()``; every episode optimal there ends the session.
        """
        session, watch = self.session, self._watch
        assert session is not None and watch is not None and self._watch_evaluator is not None
        state = session["watch"]
        if steps - state["last"] < watch.every:
            return False
        report = self._watch_evaluator.evaluate(self.agent())
        score = evaluation_score(watch.rule, report.summary())
        state["last"] = int(steps)
        if state["best"] is None or score > state["best"]:
            state["best"], state["best_steps"] = score, int(steps)
            if watch.keep_best is not None:
                watch.keep_best()
        session["converged"] = all(e.normalized_reward >= OPTIMAL for e in report.episodes)
        return True

    def _final_watch_point(self) -> None:
        """At a session's end: the evaluation due there, if the session still goes on."""
        session = self.session
        assert session is not None
        if self._watch is not None and not session["converged"] and not self._out_of_time():
            if self._watch_point(int(session["steps"])) and self._checkpoint is not None:
                self._checkpoint()

    def _close_session(self) -> TrainingOutcome:
        """The session's outcome; the learner is then between sessions."""
        session = self.session
        assert session is not None
        outcome = TrainingOutcome(
            env_steps=int(session["steps"]),
            seconds=self._seconds(),
            converged=bool(session["converged"]),
        )
        self.session = None
        self._checkpoint = None
        self._watch = None
        return outcome

    def _seconds(self) -> float:
        """Seconds of the session in progress, over every resumed part of it."""
        started, before = self._clock
        return before + (time.monotonic() - started)

    def _out_of_time(self) -> bool:
        """True once the session in progress has spent its seconds budget (if it has one)."""
        budget = self.session.get("budget_seconds") if self.session is not None else None
        return budget is not None and self._seconds() >= budget

    def _goes_on(self, target: int | None) -> bool:
        """The session in progress has budget left (steps and seconds) and has not converged."""
        session = self.session
        assert session is not None
        return (
            not session["converged"]
            and (target is None or session["steps"] < target)
            and not self._out_of_time()
        )


class SB3Learner(Sessions):
    """An SB3 model in training, as a curriculum drives it (see the module docstring).

    ``seed`` seeds the model's random streams (SB3's ``set_random_seed``)
    and the environments at the start of each session; ``log_name`` names
    its TensorBoard log (when the model has a ``tensorboard_log`` folder) and
    ``log_names`` those of its branches, by seed.
    """

    def __init__(
        self,
        model: BaseAlgorithm,
        *,
        algo: str,
        robot: str,
        seed: int,
        n_envs: int,
        eval_every: int,
        log_name: str = "curriculum",
        log_names: Mapping[int, str] | None = None,
        session: dict[str, Any] | None = None,
    ) -> None:
        self.model = model
        self.algo = algo
        self.robot = as_robot(robot).to_string()
        self.seed = int(seed)
        self.n_envs = int(n_envs)
        self.eval_every = int(eval_every)
        self.log_name = log_name
        self.log_names = dict(log_names or {})
        self.session: dict[str, Any] | None = session
        self._checkpoint: Callable[[], None] | None = None
        self._evaluator: Evaluator | None = None
        self._clock = (time.monotonic(), 0.0)

    @property
    def rollout(self) -> int:
        """Env steps of one rollout."""
        return int(self.model.n_steps) * self.n_envs

    def robot_name(self) -> str:
        """The robot the learner trains."""
        return self.robot

    def session_target(self, budget_steps: int | None) -> int | None:
        """The steps of a whole session: as many whole rollouts as the budget pays (maybe none).

        ``None`` without a steps budget (a session on seconds alone has no step limit).
        """
        if budget_steps is None:
            return None
        return budget_steps // self.rollout * self.rollout

    # -- the protocol -----------------------------------------------------------

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

        The budget is ``budget_steps`` env steps, spent in whole rollouts (none
        if a rollout does not fit), and/or ``budget_seconds`` seconds of the session (``None``:
        no limit of that kind, not both); the session ends at whichever comes
        first, or once converged (on ``watch``'s mazes when given). A saved
        session continues only when the mazes, both budgets and the watch are the same.
        """
        budget_steps, budget_seconds = checked_session_budget(
            budget_steps, budget_seconds, RLConfigError
        )
        mazes = [MazeSpec.from_string(str(m)).to_string() for m in mazes]
        session = self._open_session(mazes, budget_steps, budget_seconds, watch)
        self._checkpoint = checkpoint
        self._evaluator = Evaluator(self.robot, mazes, inputs=False)
        target = self.session_target(budget_steps)
        model = self.model
        model.set_env(SB3VecEnv(mazes, self.robot, self.n_envs, self.seed))
        # A session draws from the learner's seed (a continued one, from the seed and
        # the steps done), so its draws depend on nothing that ran before it.
        seed = self.seed
        if session["steps"]:
            seed = int(np.random.SeedSequence([seed, session["steps"]]).generate_state(1)[0])
        model.set_random_seed(seed & 0x7FFF_FFFF)
        if self._goes_on(target):
            self._session_point(session["steps"])
        if self._goes_on(target):
            start = int(model.num_timesteps)
            callback = _SessionCallback(self, start, session["steps"], progress)
            model.learn(
                total_timesteps=UNLIMITED_STEPS if target is None else target - session["steps"],
                callback=callback,
                reset_num_timesteps=False,
                tb_log_name=self.log_name,
            )
            session["steps"] = callback.steps_before + int(model.num_timesteps) - start
        self._final_watch_point()
        return self._close_session()

    def branch(self, seed: int) -> SB3Learner:
        """An independent copy (weights, optimiser state) whose sessions draw from ``seed``."""
        with tempfile.TemporaryDirectory(prefix="sb3-branch-") as folder:
            path = Path(folder) / MODEL_FILE
            buffer = io.BytesIO()
            self.model.save(buffer)
            path.write_bytes(buffer.getvalue())
            model = load_sb3_model(
                path, self.algo, self.robot, tensorboard_log=self.model.tensorboard_log
            )
        return SB3Learner(
            model,
            algo=self.algo,
            robot=self.robot,
            seed=int(seed),
            n_envs=self.n_envs,
            eval_every=self.eval_every,
            log_name=self.log_names.get(int(seed), f"seed-{int(seed)}"),
            log_names=self.log_names,
        )

    def agent(self) -> SB3Agent:
        """The model, acting deterministically."""
        return SB3Agent(self.model, self.robot, self.algo)

    def save(self, folder: Path) -> None:
        """``model.zip`` and ``learner.json`` in ``folder``, each written atomically."""
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        if self.session is not None:
            self.session["seconds"] = self._seconds()
        tmp = folder / f".{MODEL_FILE}.tmp.zip"
        self.model.save(tmp)
        os.replace(tmp, folder / MODEL_FILE)
        write_json(folder / LEARNER_FILE, self.state())

    def state(self) -> dict[str, Any]:
        """The content of ``learner.json``."""
        return {
            "format": LEARNER_FORMAT,
            "algo": self.algo,
            "robot": self.robot,
            "seed": self.seed,
            "n_envs": self.n_envs,
            "eval_every": self.eval_every,
            "log_name": self.log_name,
            "num_timesteps": int(self.model.num_timesteps),
            "session": self.session,
        }

    # -- the session's own --------------------------------------------------------

    def _session_point(self, steps: int, logger: Any = None) -> None:
        """A rollout starts at ``steps`` of the session: evaluate if due, then checkpoint."""
        session = self.session
        assert session is not None and self._evaluator is not None
        session["steps"] = int(steps)
        if self._watch is not None:
            if self._watch_point(int(steps)) and self._checkpoint is not None:
                self._checkpoint()
            return
        last = session["last_eval"]
        if last is not None and steps - last < self.eval_every:
            return
        report = self._evaluator.evaluate(self.agent())
        session["converged"] = all(e.normalized_reward >= OPTIMAL for e in report.episodes)
        session["last_eval"] = int(steps)
        if logger is not None:  # inside SB3's learn: the session's TensorBoard log
            summary = report.summary()
            logger.record("eval/success_rate", float(summary["success_rate"]))
            logger.record("eval/normalized_reward", float(summary["normalized_reward"]))
            logger.dump(int(self.model.num_timesteps))
        if self._checkpoint is not None:
            self._checkpoint()


def checked_session(data: Any, source: str) -> dict[str, Any] | None:
    """The session of ``learner.json``, every field checked."""
    if data is None:
        return None
    if not isinstance(data, dict):
        raise RLConfigError(f"{source}: session {data!r} is not null or a JSON object")
    mazes = _checked_mazes(data.get("mazes"), f"{source}: session mazes")

    def integer(name: str, minimum: int) -> int:
        return check_integer(
            f"{source}: session {name}", data.get(name), minimum=minimum, error=RLConfigError
        )

    if not isinstance(data.get("converged"), bool):
        raise RLConfigError(f"{source}: session converged {data.get('converged')!r} is not a bool")
    last = data.get("last_eval")
    # A session saved before seconds budgets existed has no budget_seconds: steps alone.
    budget = None if data.get("budget") is None else integer("budget", 0)
    seconds = data.get("budget_seconds")
    if seconds is not None:
        seconds = check_number(
            f"{source}: session budget_seconds", seconds, minimum=0, error=RLConfigError
        )
    if budget is None and seconds is None:
        raise RLConfigError(f"{source}: session has no budget (budget and budget_seconds null)")
    return {
        "mazes": mazes,
        "budget": budget,
        "budget_seconds": seconds,
        "steps": integer("steps", 0),
        "seconds": check_number(
            f"{source}: session seconds", data.get("seconds"), minimum=0, error=RLConfigError
        ),
        "converged": data["converged"],
        "last_eval": None if last is None else integer("last_eval", 0),
        **({} if data.get("watch") is None else {"watch": _checked_watch(data["watch"], source)}),
    }


def _checked_mazes(mazes: Any, what: str) -> list[str]:
    """A saved list of maze strings, each checked, as canonical strings."""
    if not isinstance(mazes, list) or not mazes or not all(isinstance(m, str) for m in mazes):
        raise RLConfigError(f"{what} {mazes!r} is not a list of mazes")
    try:
        return [MazeSpec.from_string(m).to_string() for m in mazes]
    except ValueError as problem:
        raise RLConfigError(f"{what}: {problem}") from None


def _checked_watch(data: Any, source: str) -> dict[str, Any]:
    """The watch of a saved session (:meth:`Sessions._open_session`), every field checked."""
    what = f"{source}: session watch"
    if not isinstance(data, dict):
        raise RLConfigError(f"{what} {data!r} is not a JSON object")
    mazes = _checked_mazes(data.get("mazes"), f"{what} mazes")
    if data.get("rule") not in EVALUATION_RULES:
        raise RLConfigError(f"{what} rule {data.get('rule')!r} is not one of {EVALUATION_RULES}")
    best = data.get("best")
    size = len(evaluation_score(data["rule"], {"normalized_reward": 0, "success_rate": 0}))
    if best is not None and not (
        isinstance(best, list)
        and len(best) == size
        and all(isinstance(v, int | float) and not isinstance(v, bool) for v in best)
    ):
        raise RLConfigError(f"{what} best {best!r} is not null or {size} numbers")

    def integer(name: str, minimum: int) -> int:
        return check_integer(f"{what} {name}", data.get(name), minimum=minimum, error=RLConfigError)

    best_steps = data.get("best_steps")
    return {
        "mazes": mazes,
        "every": integer("every", 1),
        "rule": data["rule"],
        "last": integer("last", 0),
        "best": None if best is None else [float(v) for v in best],
        "best_steps": None if best_steps is None else integer("best_steps", 0),
    }


def load_sb3_learner(
    folder: str | os.PathLike,
    *,
    algo: str,
    robot: str,
    n_envs: int,
    tensorboard_log: str | None = None,
    log_names: Mapping[int, str] | None = None,
) -> SB3Learner:
    """The learner saved in ``folder`` by :meth:`SB3Learner.save`, checked against the run.

    ``algo``, ``robot`` and ``n_envs`` are the run's: a learner saved with
    others is refused. Any missing, damaged or inconsistent file raises
    :class:`RLConfigError` naming it; nothing is unpickled.
    """
    folder = Path(folder)
    path = folder / LEARNER_FILE
    source = f"learner file {str(path)!r}"
    data = read_json_object(path, RLConfigError, "learner file")
    robot = as_robot(robot).to_string()
    expected = {"format": LEARNER_FORMAT, "algo": algo, "robot": robot, "n_envs": n_envs}
    for key, value in expected.items():
        if data.get(key) != value:
            raise RLConfigError(f"{source}: {key} {data.get(key)!r} is not {value!r}")
    seed = check_integer(f"{source}: seed", data.get("seed"), minimum=0, error=RLConfigError)
    eval_every = check_integer(
        f"{source}: eval_every", data.get("eval_every"), minimum=1, error=RLConfigError
    )
    steps = check_integer(
        f"{source}: num_timesteps", data.get("num_timesteps"), minimum=0, error=RLConfigError
    )
    log_name = data.get("log_name")
    if not isinstance(log_name, str) or not log_name or "/" in log_name or "\\" in log_name:
        raise RLConfigError(f"{source}: log_name {log_name!r} is not a plain name")
    session = checked_session(data.get("session"), source)
    model_path = folder / MODEL_FILE
    if not (model_path.exists() or model_path.is_symlink()):
        raise RLConfigError(f"model file {str(model_path)!r} is missing")
    model = load_sb3_model(model_path, algo, robot, tensorboard_log=tensorboard_log)
    if int(model.num_timesteps) != steps:
        raise RLConfigError(
            f"{source}: num_timesteps {steps} is not the {int(model.num_timesteps)} of"
            f" {str(model_path)!r} (the two files are of different saves)"
        )
    return SB3Learner(
        model,
        algo=algo,
        robot=robot,
        seed=seed,
        n_envs=n_envs,
        eval_every=eval_every,
        log_name=log_name,
        log_names=log_names,
        session=session,
    )
