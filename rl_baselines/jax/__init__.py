"""SB3's A2C and PPO compiled with JAX: the same algorithms, trained at compiled speed.

The one part of :mod:`rl_baselines` that imports JAX (``import rl_baselines``
never loads it). Each definition matches one of stable-baselines3 2.x, cited
where it is written; tests compare both on the same parameters and data
(``tests/rl_baselines/jax/``)::

    from rl_baselines.jax import JaxTrainer
    trainer = JaxTrainer("ppo", "DD", rotations(PAPER_TRAINING_MAZE), {"n_steps": 2048}, seed=0)
    stats = trainer.learn(100_000)        # whole rollouts, compiled; per-rollout figures
    trainer.num_timesteps                 # 106_496: 13 rollouts of 2048 x 4
    trainer.save("run/trainer")           # trainer.json + state.npz ...
    trainer = JaxTrainer.load("run/trainer")  # ... and back: training goes on bit for bit
    report = Evaluator("DD", mazes)(trainer.policy())   # numpy argmax policy
    act = trainer.jax_policy()            # the same, as a jitted JAX function
    trainer.export_sb3("agent.zip")       # an SB3 zip that PPO.load and SB3Agent.load read

Modules:

* :mod:`~rl_baselines.jax.hyperparameters`: SB3's names and defaults, checked;
* :mod:`~rl_baselines.jax.spec`: the policy's architecture (no JAX);
* :mod:`~rl_baselines.jax.networks`: ``ActorCriticPolicy`` (MLP, SmallCNN) in JAX;
* :mod:`~rl_baselines.jax.optim`: torch's Adam, RMSprop and ``clip_grad_norm_``;
* :mod:`~rl_baselines.jax.rollout`: ``collect_rollouts`` as a ``lax.scan``;
* :mod:`~rl_baselines.jax.update`: GAE, PPO's and A2C's losses and updates;
* :mod:`~rl_baselines.jax.trainer`: the training state, K rollouts per call, :class:`JaxTrainer`;
* :mod:`~rl_baselines.jax.storage`: a trainer saved to a folder and loaded back;
* :mod:`~rl_baselines.jax.policy`: :class:`NumpyPolicy` for the evaluation protocol (no JAX);
* :mod:`~rl_baselines.jax.agent`: :class:`JaxAgent`, a run's agent (numpy, saved as SB3's);
* :mod:`~rl_baselines.jax.sb3_io`: SB3 zips out and in (imports torch and SB3);
* :mod:`~rl_baselines.jax.run`: :class:`~rl_baselines.jax.run.JaxRun`, the direct regime;
* :mod:`~rl_baselines.jax.learner`: :class:`~rl_baselines.jax.learner.JaxLearner` (curricula);
* :mod:`~rl_baselines.jax.coevolution`: :class:`~rl_baselines.jax.coevolution.JaxCoevolutionRun`.

The last three import the rest of :mod:`rl_baselines` (its config and runs),
which imports this package: they are imported by their module name, never
from here.

Names are loaded on first use, so ``from rl_baselines.jax.policy import
NumpyPolicy`` loads neither JAX nor torch.
"""

from __future__ import annotations

from importlib import import_module
from typing import Any

__all__ = [
    "Hyperparameters",
    "JaxAgent",
    "JaxTrainer",
    "NumpyPolicy",
    "PolicySpec",
    "RolloutStats",
    "TrainState",
    "checked_hyperparameters",
    "export_sb3",
    "import_sb3",
    "load_trainer",
]

_LAZY = {
    "Hyperparameters": "rl_baselines.jax.hyperparameters",
    "checked_hyperparameters": "rl_baselines.jax.hyperparameters",
    "JaxTrainer": "rl_baselines.jax.trainer",
    "JaxAgent": "rl_baselines.jax.agent",
    "RolloutStats": "rl_baselines.jax.trainer",
    "TrainState": "rl_baselines.jax.trainer",
    "NumpyPolicy": "rl_baselines.jax.policy",
    "PolicySpec": "rl_baselines.jax.spec",
    "export_sb3": "rl_baselines.jax.sb3_io",
    "import_sb3": "rl_baselines.jax.sb3_io",
    "load_trainer": "rl_baselines.jax.trainer",
}


def __getattr__(name: str) -> Any:
    """The package's names, each imported from its module on first use."""
    if name in _LAZY:
        return getattr(import_module(_LAZY[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
