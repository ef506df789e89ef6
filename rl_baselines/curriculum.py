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
from amaze.curriculum.learner import branch_seed
from amaze.curriculum.regimes import MAX_OPEN_STAGES
from amaze.runs.curriculum import CurriculumRun
from rl_baselines.agent import SB3Agent
from rl_baselines.config import TrainConfig, fitted_hyperparameters
from rl_baselines.learner import SB3Learner, load_sb3_learner, new_sb3_model
from rl_baselines.vec_env import SB3VecEnv

__all__ = ["JaxCurriculumRun", "SB3CurriculumRun"]


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
        }

    def start(self) -> None:
        """The curator (:meth:`CurriculumRun.start`), once a model can be built.

        A throwaway model is built from the hyperparameters, so that bad ones
        fail here, before anything is written.
        """
        self.new_learner(0).model.env.close()
        super().start()


class JaxCurriculumRun(SB3CurriculumRun):
    """The curriculum loop with ``--framework jax``: a JAX learner in every branch.

    The same loop, folder and fitted rollouts as :class:`SB3CurriculumRun`,
    with a :class:`~rl_baselines.jax_learner.JaxLearner` as the learner;
    each branch's learner is a JAX trainer (``agent/`` and ``checkpoint/``
    hold ``trainer/`` and ``learner.json``; agents are saved as SB3 zips). A
    resumed run ends bit for bit as an uninterrupted one on one machine. No
    TensorBoard logs.
    """

    outputs: ClassVar[tuple[str, ...]] = ("agent.zip", *CurriculumRun.outputs)

    def _tensorboard_dir(self) -> str | None:
        return None

    def new_learner(self, seed: int) -> Any:
        from rl_baselines.jax.trainer import JaxTrainer
        from rl_baselines.jax_learner import JaxLearner

        c = self.config
        trainer = JaxTrainer(
            c.algo, c.robot, [c.target], self.hyperparameters, seed=seed, n_envs=c.n_envs
        )
        return JaxLearner(trainer, seed=seed, eval_every=c.eval_every)

    def load_learner(self, folder: Path) -> Any:
        from rl_baselines.jax_learner import load_jax_learner

        c = self.config
        return load_jax_learner(folder, algo=c.algo, robot=c.robot, n_envs=c.n_envs)

    def learner_figures(self) -> dict[str, Any]:
        return {**super().learner_figures(), "framework": "jax"}

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
