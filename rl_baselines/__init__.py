"""Reinforcement-learning baselines: stable-baselines3 A2C/PPO on the AMaze batch engine.

``rl_baselines`` depends on :mod:`amaze` (never the reverse) and on torch and
stable-baselines3, which are imported here and nowhere in :mod:`amaze`.

* :mod:`rl_baselines.vec_env`: :class:`SB3VecEnv`, an SB3 ``VecEnv`` stepping all
  environments together on the batch engine;
* :mod:`rl_baselines.networks`: a small CNN features extractor for 15x15 images;
* :mod:`rl_baselines.agent`: :class:`SB3Agent`, a trained model as a policy of the
  shared protocol (``amaze.evaluation.policy``), with save/load; SB3 zips loaded
  as data (``load_sb3_model``: :mod:`rl_baselines.sb3_file` checks them without
  torch, :mod:`rl_baselines.agent_loader` is the commands' ``zip`` loader);
* :mod:`rl_baselines.config`: :class:`TrainConfig` (the run's config) and the rollouts
  fitted to a curriculum's small budgets;
* :mod:`rl_baselines.learner`: :class:`SB3Learner`, an SB3 model as a curriculum learner
  (training sessions, branches, save/load);
* :mod:`rl_baselines.train`: :class:`SB3Run`, the direct regime with run folders,
  checkpoints and resume, and ``train``/``resume`` for every regime;
* :mod:`rl_baselines.curriculum`: :class:`SB3CurriculumRun`, the interpolation and
  EDHuCAT regimes (the curriculum loop of :mod:`amaze.runs.curriculum`);
* :mod:`rl_baselines.cli`: the ``amaze-train`` command.
"""

from __future__ import annotations

from amaze.errors import AmazeError

__all__ = ["RLConfigError"]


class RLConfigError(AmazeError):
    """Bad user input to the RL baselines (algorithm, regime, budget, config key...)."""
