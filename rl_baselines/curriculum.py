"""SB3 A2C/PPO in the curriculum regimes: the curriculum loop with an SB3 learner.

:class:`SB3CurriculumRun` is :class:`amaze.runs.curriculum.CurriculumRun`
(EDHuCAT, paper Algorithm 1; the interpolation regime is the same loop with
the ``interpolation`` curator and one branch) whose learner is an
:class:`~rl_baselines.learner.SB3Learner`: each branch copies the selected
agent's model (weights and optimiser state) and trains it on its maze's 4
rotations for its allowance, in whole rollouts, evaluated (and checkpointed)
every ``eval_every`` steps and stopped early once every training episode is
optimal. The allowance is env steps and/or seconds: a ``budget_seconds`` is
shared between stages and branches like steps
(:func:`~amaze.curriculum.regimes.branch_seconds`), and a branch on seconds
stops at the step that spends them; such a run depends on the machine's
speed, so it neither replays nor resumes bit-identically.

Rollouts are fitted to small budgets (see :func:`rl_baselines.config.fitted_hyperparameters`);
``summary.json`` records them (``hyperparameters_used``). TensorBoard logs
(with ``--tensorboard``, the default) go to ``OUT/tensorboard/``, one log per
branch (``stage-<s>-branch-<b>_0``), with the evaluations (``eval/success_rate``,
``eval/normalized_reward``) besides SB3's own figures.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, ClassVar

import torch

from amaze.agents.robot import as_robot
from amaze.curriculum.interpolation import curriculum
from amaze.curriculum.learner import EVALUATION_RULES, Learner, SessionWatch, branch_seed
from amaze.curriculum.regimes import MAX_OPEN_STAGES
from amaze.maze import rotations
from amaze.runs.config import read_json_object
from amaze.runs.curriculum import CurriculumRun
from amaze.runs.folder import settled_folder, write_folder
from rl_baselines.agent import SB3Agent
from rl_baselines.config import TrainConfig, fitted_hyperparameters
from rl_baselines.jax.agent import NetworkRunFiles
from rl_baselines.learner import (
    LEARNER_FILE,
    SB3Learner,
    checked_session,
    load_sb3_learner,
    new_sb3_model,
)
from rl_baselines.vec_env import SB3VecEnv

__all__ = ["BEST_FOLDER", "JaxCurriculumRun", "SB3CurriculumRun"]

#: The folder of a branch that holds its best learner on its evaluation series.
BEST_FOLDER = "best"


class SB3CurriculumRun(CurriculumRun):
    """The curriculum loop of the RL trainer (see the module docstring)."""

    config_class = TrainConfig
    agent_file = "agent.zip"
    outputs: ClassVar[tuple[str, ...]] = ("agent.zip", *CurriculumRun.outputs, "tensorboard/")
    config: TrainConfig

    def __init__(self, out: Any, config: TrainConfig) -> None:
        super().__init__(out, config)
        torch.set_num_threads(1)
        self.hyperparameters = fitted_hyperparameters(config)
        c = config
        assert c.stages is not None and c.branches is not None
        stages = MAX_OPEN_STAGES if c.open_ended else c.stages
        branches = [1, *[c.branches] * (stages - 1)]
        self.log_names = {
            branch_seed(c.seed, stage, branch): f"stage-{stage}-branch-{branch}"
            for stage, count in enumerate(branches)
            for branch in range(count)
        }

    def _tensorboard_dir(self) -> str | None:
        return str(self.out / "tensorboard") if self.config.tensorboard else None

    # -- an interpolation's evaluation series (stage_eval_target) ----------------------

    def evaluation_series(self) -> list[str]:
        """The stages of ``stage_eval_target``'s interpolation (none without one)."""
        c = self.config
        if c.stage_eval_target is None:
            return []
        assert c.stages is not None
        return [maze.to_string() for maze in curriculum(c.stage_eval_target, c.stages)]

    def session_watch(
        self,
        stage: int,
        folder: Path,
        learner: Learner,
        allowance: tuple[int | None, float | None],
    ) -> SessionWatch | None:
        """A stage judged on the same stage of the evaluation series, its best agent kept.

        Every ``allowance / stage_evaluations`` steps, on the 4 rotations of
        the series' maze; the best (by ``agent_rule``'s ranking,
        ``best-eval-reward`` when the rule is ``final``) is written to the
        branch's ``best/`` folder. The final training (past the last stage)
        is not watched.
        """
        c = self.config
        series = self.evaluation_series()
        if stage >= len(series):
            return None
        assert allowance[0] is not None and c.stage_evaluations is not None
        rule = c.agent_rule if c.agent_rule in EVALUATION_RULES else "best-eval-reward"

        def keep_best() -> None:
            write_folder(folder / BEST_FOLDER, learner.save)

        every = max(1, allowance[0] // c.stage_evaluations)
        return SessionWatch(tuple(rotations(series[stage])), every, rule, keep_best)

    def _best_of(self, stage: int, branch: int = 0) -> Path | None:
        """The branch's ``best/`` folder, if the branch kept one."""
        folder = settled_folder(self._branch_folder(stage, branch) / BEST_FOLDER)
        return folder if (folder / LEARNER_FILE).exists() else None

    def _best_watch(self, folder: Path) -> dict[str, Any]:
        """The watch record (best score, its steps) of a ``best/`` folder's learner, checked."""
        source = f"learner file {str(folder / LEARNER_FILE)!r}"
        data = read_json_object(folder / LEARNER_FILE, self.config.error, "learner file")
        session = checked_session(data.get("session"), source)
        if session is None or "watch" not in session:
            raise self.config.error(f"{source} holds no watched session")
        return session["watch"]

    def _handed_best(self) -> Path | None:
        """The last stage's ``best/`` folder when ``agent_rule`` hands it over."""
        c = self.config
        if c.stage_eval_target is None or c.agent_rule not in EVALUATION_RULES:
            return None
        assert self.final is not None
        return self._best_of(self.final.stage, self.final.branch)

    def final_agent(self) -> Any:
        """The last stage's best on its evaluation series (``agent_rule``), else the choice."""
        best = self._handed_best()
        if best is None:
            return super().final_agent()
        if self._loaded[0] != best:
            self._loaded = (best, self.load_learner(best).agent())
        return self._loaded[1]

    def agent_figures(self) -> dict[str, Any]:
        figures = super().agent_figures()
        best = self._handed_best()
        c = self.config
        if best is None:
            if c.stage_eval_target is not None and c.agent_rule in EVALUATION_RULES:
                figures["agent_rule"] = (
                    f"{figures['agent_rule']}: the last stage kept no best on its evaluation series"
                )
            return figures
        final = self.final
        assert final is not None
        before = sum(
            k.env_steps
            for record in self.records
            for k in record.candidates
            if (k.stage, k.branch) < (final.stage, final.branch)
        )
        found = before + int(self._best_watch(best)["best_steps"])
        rule = f"{c.agent_rule}: the last stage's best on its evaluation series"
        return {"agent_rule": rule, "agent_steps": found, "agent_untrained": found == 0}

    def stage_evaluation_figures(self) -> dict[str, Any]:
        """Each stage's evaluation-series maze, its best score there and when (summary.json)."""
        c = self.config
        if c.stage_eval_target is None:
            return {}
        series = self.evaluation_series()
        stages = []
        for record in self.records:
            for k in record.candidates:
                best = self._best_of(k.stage, k.branch)
                watch = None if best is None else self._best_watch(best)
                stages.append(
                    {
                        "stage": k.stage,
                        "branch": k.branch,
                        "maze": series[k.stage] if k.stage < len(series) else None,
                        "best": None if watch is None else watch["best"],
                        "best_steps": None if watch is None else watch["best_steps"],
                        "converged": k.converged,
                    }
                )
        return {
            "stage_evaluation": {
                "target": c.stage_eval_target,
                "evaluations": c.stage_evaluations,
                "rule": c.agent_rule if c.agent_rule in EVALUATION_RULES else "best-eval-reward",
                "stages": stages,
            }
        }

    def new_learner(self, seed: int) -> SB3Learner:
        c = self.config
        env = SB3VecEnv([c.target], c.robot, c.n_envs, seed)
        model = new_sb3_model(
            c.algo, c.robot, env, seed, self.hyperparameters, self._tensorboard_dir()
        )
        return SB3Learner(
            model,
            algo=c.algo,
            robot=c.robot,
            seed=seed,
            n_envs=c.n_envs,
            eval_every=c.eval_every,
            log_name=self.log_names.get(seed, f"seed-{seed}"),
            log_names=self.log_names,
        )

    def load_learner(self, folder: Path) -> SB3Learner:
        c = self.config
        return load_sb3_learner(
            folder,
            algo=c.algo,
            robot=c.robot,
            n_envs=c.n_envs,
            tensorboard_log=self._tensorboard_dir(),
            log_names=self.log_names,
        )

    def smallest_unit(self) -> tuple[int, str]:
        """One rollout: ``n_steps x n_envs`` env steps."""
        n_steps, n_envs = int(self.hyperparameters["n_steps"]), self.config.n_envs
        return n_steps * n_envs, f"one rollout (n_steps {n_steps} x n_envs {n_envs})"

    def save_agent(self, agent: SB3Agent, path: Path) -> None:
        agent.save(path)

    def learner_figures(self) -> dict[str, Any]:
        c = self.config
        return {
            "algo": c.algo,
            "n_envs": c.n_envs,
            "eval_every": c.eval_every,
            "hyperparameters_used": dict(self.hyperparameters),
            **self.stage_evaluation_figures(),
        }

    def start(self) -> None:
        """The curator (:meth:`CurriculumRun.start`), once a model can be built.

        A throwaway model is built from the hyperparameters, so that bad ones
        fail here, before anything is written.
        """
        self.new_learner(0).model.env.close()
        super().start()


class JaxCurriculumRun(NetworkRunFiles, SB3CurriculumRun):
    """The curriculum loop with ``--framework jax``: a JAX learner in every branch.

    The same loop, folder and fitted rollouts as :class:`SB3CurriculumRun`,
    with a :class:`~rl_baselines.jax.learner.JaxLearner` as the learner;
    each branch's learner is a JAX trainer (``agent/`` and ``checkpoint/``
    hold ``trainer/`` and ``learner.json``; agents are saved as SB3 zips). A
    resumed run ends bit for bit as an uninterrupted one on one machine. No
    TensorBoard logs.
    """

    outputs: ClassVar[tuple[str, ...]] = ("agent.zip", "agent.npz", *CurriculumRun.outputs)

    def _tensorboard_dir(self) -> str | None:
        return None

    def new_learner(self, seed: int) -> Any:
        from rl_baselines.jax.learner import JaxLearner
        from rl_baselines.jax.trainer import JaxTrainer

        c = self.config
        trainer = JaxTrainer(
            c.algo,
            c.robot,
            [c.target],
            self.hyperparameters,
            seed=seed,
            n_envs=c.n_envs,
            network=c.network,
            progress_reward=c.progress_reward,
        )
        return JaxLearner(trainer, seed=seed, eval_every=c.eval_every)

    def load_learner(self, folder: Path) -> Any:
        from rl_baselines.jax.learner import load_jax_learner

        c = self.config
        return load_jax_learner(folder, algo=c.algo, robot=c.robot, n_envs=c.n_envs)

    def learner_figures(self) -> dict[str, Any]:
        return {**super().learner_figures(), "framework": "jax", **self.network_figures()}

    def start(self) -> None:
        """The curator (:meth:`CurriculumRun.start`); bad hyperparameters fail first."""
        from rl_baselines.jax.hyperparameters import checked_hyperparameters
        from rl_baselines.jax.trainer import JaxTrainer  # noqa: F401 (JAX loads here, once)

        c = self.config
        checked_hyperparameters(
            c.algo, self.hyperparameters, robot_images=not as_robot(c.robot).discrete_inputs,
            n_envs=c.n_envs,
        )  # fmt: skip
        CurriculumRun.start(self)
