"""Training SB3 A2C/PPO agents in the paper's regimes, with run folders and resume.

The **direct** regime (paper §4): the agent trains on
:data:`~amaze.evaluation.suite.PAPER_TRAINING_MAZE` in its 4 rotations (environment ``k``
plays rotation ``k % 4``; ``n_envs`` is a multiple of 4) and is evaluated every
``eval_every`` env steps on :data:`~amaze.evaluation.suite.PAPER_EVALUATION_MAZE`'s 4
rotations. Training stops when the budget (``budget_steps`` env steps) is spent
or when all 4 evaluation episodes are optimal (paper reward R̄ = 1).

The **interpolation** regime (paper §4): the 10 stages of
``amaze.curriculum.interpolation.curriculum(PAPER_TRAINING_MAZE)``, from a trivial 5x5 maze
to the training maze. Stage ``k`` trains on stage maze ``k`` in its 4 rotations
and is evaluated on them; it gets an equal share of the budget that is left
(``remaining // stages_left``), so a stage that converges early hands its unused
steps to the later ones. The last stage runs until the whole budget is spent.

Budgets are counted in env steps and spent in whole rollouts
(``n_steps x n_envs``), so a stage (or the run) may end up to one rollout past
its share; ``summary.json`` reports the steps actually taken.

Run folder (``out``):

* ``config.json``: the :class:`TrainConfig` (enough to resume);
* ``progress.csv``: one row per evaluation: ``steps, seconds, eval_success, eval_rbar``
  (and ``stage``, always 0 in the direct regime);
* ``checkpoints/model.zip`` + ``checkpoints/state.json``: the latest model and the
  step counter, time spent and evaluation state, each written atomically;
* ``champion.zip`` + ``champion.json``: the best agent on the evaluation mazes
  (of the last stage reached, in the interpolation regime);
* ``summary.json``: the final agent on the standard evaluation suite
  (``success_rate``, ``normalized_reward``, ``input_recognition``...) and the
  budget spent (``env_steps``, ``seconds``);
* ``trajectories/``: PNGs of the final agent in the 4 evaluation rotations;
* ``tensorboard/``: SB3's TensorBoard logs (losses, episode returns) and the
  evaluations (``eval/success_rate``, ``eval/rbar``, ``eval/stage``), one log
  per stage (``direct_0`` or ``stage-<k>_0``); ``tensorboard --logdir OUT/tensorboard``.

Evaluations (and checkpoints) happen at the first rollout boundary at least
``eval_every`` steps after the previous one, and once more at the end.
Checkpoints are taken at the start of a rollout (after the previous one has
been trained on), so a resumed run continues with exactly the steps already
learned from; the unfinished rollout of a killed run is redone. SB3 does not
save its random generators' states nor the rollout in progress, so a resumed
run is a faithful continuation, not a bit-identical replay.
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import torch
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback

from amaze.agents.robot import as_robot
from amaze.agents.trajectories import save_trajectory_png
from amaze.evaluation.policy import record_episode
from amaze.evaluation.protocol import Evaluator
from amaze.evaluation.suite import PAPER_EVALUATION_MAZE, PAPER_TRAINING_MAZE, rotations
from amaze.runs.folder import ProgressLog, config_from_dict, write_json
from rl_baselines import RLConfigError
from rl_baselines.agent import SB3Agent, algorithm_class
from rl_baselines.networks import small_cnn_kwargs
from rl_baselines.vec_env import MazeVecEnv

__all__ = ["REGIMES", "TrainConfig", "TrainResult", "resume", "stage_end", "train"]

REGIMES = ("direct", "interpolation")
PROGRESS_FIELDS = ("steps", "seconds", "eval_success", "eval_rbar", "stage")
#: R̄ at or above this counts as optimal (R̄ is 1 for a run in l-1 steps).
OPTIMAL = 1.0 - 1e-9


@dataclass
class TrainConfig:
    """Everything that defines a training run (stored as ``config.json``)."""

    algo: str = "ppo"
    regime: str = "direct"
    robot: str = "DD"
    budget_steps: int = 3_000_000
    seed: int = 0
    eval_every: int = 50_000
    n_envs: int = 4
    tensorboard: bool = True
    hyperparameters: dict[str, Any] = field(default_factory=dict)

    def validate(self) -> TrainConfig:
        """Check every field; raise :class:`RLConfigError` naming the bad value."""
        algorithm_class(self.algo)
        self.algo = self.algo.lower()
        if self.regime not in REGIMES:
            raise RLConfigError(
                f"unknown regime {self.regime!r} (choose from {', '.join(REGIMES)})"
            )
        try:
            self.robot = as_robot(self.robot).to_string()
        except ValueError as error:
            raise RLConfigError(f"robot {self.robot!r}: {error}") from None
        for name in ("budget_steps", "eval_every", "n_envs"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise RLConfigError(f"{name} {value!r} is not a positive integer")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise RLConfigError(f"seed {self.seed!r} is not a non-negative integer")
        if not isinstance(self.tensorboard, bool):
            raise RLConfigError(f"tensorboard {self.tensorboard!r} is not true or false")
        if self.n_envs % 4:
            raise RLConfigError(f"n_envs {self.n_envs} is not a multiple of 4 (one per rotation)")
        if not isinstance(self.hyperparameters, dict):
            raise RLConfigError(f"hyperparameters {self.hyperparameters!r} is not a JSON object")
        for reserved in ("env", "seed", "policy"):
            if reserved in self.hyperparameters:
                raise RLConfigError(f"hyperparameter {reserved!r} is set by the trainer")
        return self

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> TrainConfig:
        """A config from a JSON object; unknown keys are errors."""
        return config_from_dict(cls, data, RLConfigError).validate()

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass
class TrainResult:
    """What :func:`train` returns: the final agent and the run's figures."""

    agent: SB3Agent
    env_steps: int
    seconds: float
    converged: bool
    summary: dict[str, Any]


def _tensorboard_dir(config: TrainConfig, out: Path) -> str | None:
    return str(out / "tensorboard") if config.tensorboard else None


def _make_model(config: TrainConfig, env: MazeVecEnv, out: Path) -> BaseAlgorithm:
    """A fresh SB3 model: default hyperparameters unless the config overrides them."""
    cls = algorithm_class(config.algo)
    kwargs = dict(config.hyperparameters)
    kwargs.setdefault("tensorboard_log", _tensorboard_dir(config, out))
    if as_robot(config.robot).discrete_inputs:
        policy = "MlpPolicy"
    else:
        policy = "CnnPolicy"
        kwargs["policy_kwargs"] = {**small_cnn_kwargs(), **kwargs.get("policy_kwargs", {})}
    try:
        return cls(policy, env, seed=config.seed, device="cpu", verbose=0, **kwargs)
    except TypeError as error:
        raise RLConfigError(f"bad hyperparameters for {config.algo}: {error}") from None


def _score(report_summary: dict[str, Any]) -> tuple[float, float]:
    return (float(report_summary["success_rate"]), float(report_summary["normalized_reward"]))


class _RunState:
    """The run folder's files and the evaluation state carried across resumes."""

    def __init__(self, out: Path, config: TrainConfig) -> None:
        self.out = out
        self.config = config
        self.checkpoints = out / "checkpoints"
        self.progress = ProgressLog(out / "progress.csv", PROGRESS_FIELDS)
        self.seconds_before = 0.0
        self.best: tuple[float, float] | None = None
        self.converged = False
        self.last_eval_steps = -1
        self.stage = 0
        self.stage_end: int | None = None
        self.started = time.monotonic()

    def seconds(self) -> float:
        return self.seconds_before + (time.monotonic() - self.started)

    def append_progress(self, row: dict[str, Any]) -> None:
        self.progress.append(row)

    def trim_progress(self, steps: int) -> None:
        """Drop progress rows written after the checkpoint being resumed."""
        self.progress.keep(lambda row: int(row["steps"]) <= steps)

    def save_checkpoint(self, model: BaseAlgorithm) -> None:
        self.checkpoints.mkdir(parents=True, exist_ok=True)
        tmp = self.checkpoints / ".model.tmp.zip"
        model.save(tmp)
        os.replace(tmp, self.checkpoints / "model.zip")
        write_json(
            self.checkpoints / "state.json",
            {
                "num_timesteps": int(model.num_timesteps),
                "seconds": self.seconds(),
                "best": list(self.best) if self.best is not None else None,
                "converged": self.converged,
                "last_eval_steps": self.last_eval_steps,
                "stage": self.stage,
                "stage_end": self.stage_end,
            },
        )

    def load_state(self) -> dict[str, Any]:
        state = json.loads((self.checkpoints / "state.json").read_text())
        self.seconds_before = float(state["seconds"])
        self.best = tuple(state["best"]) if state["best"] is not None else None
        self.converged = bool(state["converged"])
        self.last_eval_steps = int(state["last_eval_steps"])
        self.stage = int(state["stage"])
        self.stage_end = state["stage_end"]
        self.started = time.monotonic()
        return state


class _EvaluationCallback(BaseCallback):
    """Every ``eval_every`` steps, at the start of a rollout: evaluate, log, checkpoint.

    Stops training (at the next step) once every evaluation episode is optimal.
    """

    def __init__(self, run: _RunState, evaluator: Evaluator | None, robot: str) -> None:
        super().__init__(verbose=0)
        self.run = run
        self.evaluator = evaluator
        self.robot = robot

    def evaluate_now(self) -> None:
        """Evaluate the current model, update the champion, log and checkpoint."""
        run, model = self.run, self.model
        steps = int(model.num_timesteps)
        agent = SB3Agent(model, self.robot, run.config.algo)
        assert self.evaluator is not None
        report = self.evaluator.evaluate(agent)
        summary = report.summary()
        score = _score(summary)
        if run.best is None or score > run.best:
            run.best = score
            agent.save(run.out / "champion.zip")
        run.converged = all(e.paper_reward >= OPTIMAL for e in report.episodes)
        run.last_eval_steps = steps
        self.logger.record("eval/success_rate", score[0])
        self.logger.record("eval/rbar", score[1])
        self.logger.record("eval/stage", run.stage)
        self.logger.dump(steps)
        run.append_progress(
            {
                "steps": steps,
                "seconds": round(run.seconds(), 3),
                "eval_success": score[0],
                "eval_rbar": score[1],
                "stage": run.stage,
            }
        )
        run.save_checkpoint(model)

    def _on_rollout_start(self) -> None:
        steps = int(self.model.num_timesteps)
        if steps == 0 or steps - self.run.last_eval_steps >= self.run.config.eval_every:
            self.evaluate_now()

    def _on_step(self) -> bool:
        return not self.run.converged


def _final_outputs(run: _RunState, agent: SB3Agent, env_steps: int) -> dict[str, Any]:
    """The standard-suite evaluation, trajectory PNGs and ``summary.json``."""
    report = Evaluator(run.config.robot).evaluate(agent)
    summary = report.summary()
    for index, maze in enumerate(rotations(PAPER_EVALUATION_MAZE)):
        _, trajectory = record_episode(maze, run.config.robot, agent)
        save_trajectory_png(
            maze,
            trajectory,
            run.out / "trajectories" / f"evaluation-rotation-{index}.png",
            robot=run.config.robot,
            caption=True,
        )
    summary.update(
        {
            "env_steps": int(env_steps),
            "seconds": round(run.seconds(), 3),
            "budget_steps": run.config.budget_steps,
            "converged": run.converged,
            "algo": run.config.algo,
            "regime": run.config.regime,
            "robot": run.config.robot,
            "seed": run.config.seed,
        }
    )
    write_json(run.out / "summary.json", summary)
    return summary


def _stages(config: TrainConfig) -> list[tuple[list[str], list[str]]]:
    """(training mazes, evaluation mazes) of every stage of the regime."""
    if config.regime == "direct":
        return [(rotations(PAPER_TRAINING_MAZE), rotations(PAPER_EVALUATION_MAZE))]
    try:
        from amaze.curriculum.interpolation import curriculum
    except ImportError:
        raise RLConfigError(
            "regime 'interpolation' is not available: amaze.curriculum.interpolation is missing"
        ) from None
    stages = [rotations(spec.to_string()) for spec in curriculum(PAPER_TRAINING_MAZE)]
    return [(mazes, mazes) for mazes in stages]


def stage_end(budget: int, used: int, stages_left: int) -> int:
    """Where the current stage stops: an equal share of what is left (all of it at the end).

    Steps that earlier stages did not use (they converged early) are shared among
    the stages still to come.
    """
    if stages_left <= 1:
        return budget
    return used + max(budget - used, 0) // stages_left


def _env(config: TrainConfig, stages: list[tuple[list[str], list[str]]], stage: int) -> MazeVecEnv:
    """The training environments of ``stage`` (one rotation per environment)."""
    return MazeVecEnv(stages[stage][0], config.robot, config.n_envs, config.seed)


def _tb_log_name(config: TrainConfig, stage: int) -> str:
    return "direct" if config.regime == "direct" else f"stage-{stage}"


def _run(run: _RunState, model: BaseAlgorithm, progress_bar: bool = False) -> TrainResult:
    """Train stage after stage from ``run.stage`` on, then write the final outputs.

    ``model`` already has the environments of stage ``run.stage``.
    """
    config = run.config
    stages = _stages(config)
    callback = _EvaluationCallback(run, None, config.robot)
    while True:
        eval_mazes = stages[run.stage][1]
        used = int(model.num_timesteps)
        if run.stage_end is None:
            run.stage_end = stage_end(config.budget_steps, used, len(stages) - run.stage)
        callback.evaluator = Evaluator(config.robot, mazes=eval_mazes, inputs=False)
        remaining = run.stage_end - used
        if remaining > 0 and not run.converged:
            model.learn(
                total_timesteps=remaining,
                callback=callback,
                reset_num_timesteps=False,
                tb_log_name=_tb_log_name(config, run.stage),
                progress_bar=progress_bar,
            )
        # A converged stage stopped one step after its last evaluation, before any
        # training on it: the model evaluated is the final one, so no second row.
        if run.last_eval_steps != int(model.num_timesteps) and not run.converged:
            callback.init_callback(model)
            callback.evaluate_now()
        if run.stage + 1 == len(stages):
            break
        run.stage += 1
        run.stage_end = None
        run.converged = False
        run.best = None
        model.set_env(_env(config, stages, run.stage))
        run.save_checkpoint(model)
    agent = SB3Agent(model, config.robot, config.algo)
    summary = _final_outputs(run, agent, int(model.num_timesteps))
    return TrainResult(agent, int(model.num_timesteps), run.seconds(), run.converged, summary)


def train(
    config: TrainConfig | dict[str, Any], out: str | os.PathLike, *, progress_bar: bool = False
) -> TrainResult:
    """Train a fresh agent as ``config`` says and write the run folder ``out``.

    ``progress_bar`` shows SB3's progress bar (one per stage).
    """
    if isinstance(config, dict):
        config = TrainConfig.from_dict(config)
    config.validate()
    stages = _stages(config)
    torch.set_num_threads(1)
    path = Path(out)
    if (path / "config.json").exists():
        raise RLConfigError(f"{str(path)!r} already holds a run (use resume)")
    model = _make_model(config, _env(config, stages, 0), path)  # bad hyperparameters fail here
    path.mkdir(parents=True, exist_ok=True)
    write_json(path / "config.json", config.to_dict())
    return _run(_RunState(path, config), model, progress_bar)


def resume(out: str | os.PathLike, *, progress_bar: bool = False) -> TrainResult:
    """Continue the run in ``out`` from its latest checkpoint (same config, remaining budget)."""
    path = Path(out)
    config_path = path / "config.json"
    if not config_path.exists():
        raise RLConfigError(f"{str(path)!r} holds no run (no config.json)")
    config = TrainConfig.from_dict(json.loads(config_path.read_text()))
    stages = _stages(config)
    torch.set_num_threads(1)
    run = _RunState(path, config)
    if (run.checkpoints / "model.zip").exists() and (run.checkpoints / "state.json").exists():
        state = run.load_state()
        model = algorithm_class(config.algo).load(
            run.checkpoints / "model.zip",
            env=_env(config, stages, run.stage),
            device="cpu",
            tensorboard_log=_tensorboard_dir(config, path),
        )
        model.num_timesteps = int(state["num_timesteps"])
        run.trim_progress(model.num_timesteps)
    else:
        (path / "progress.csv").unlink(missing_ok=True)
        model = _make_model(config, _env(config, stages, 0), path)
    return _run(run, model, progress_bar)
