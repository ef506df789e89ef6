"""Deprecated: the old name of :mod:`rl_baselines.jax.learner`.

Importing it issues a :class:`DeprecationWarning` and gives the public names
of :mod:`rl_baselines.jax.learner`; the old name goes in the next release.
"""

from __future__ import annotations

import warnings

from rl_baselines.jax.learner import (
    LEARNER_FORMAT,
    TRAINER_FOLDER,
    JaxLearner,
    load_jax_learner,
)

__all__ = ["LEARNER_FORMAT", "TRAINER_FOLDER", "JaxLearner", "load_jax_learner"]

warnings.warn(
    "rl_baselines.jax_learner is now rl_baselines.jax.learner; the old name goes in the next"
    " release",
    DeprecationWarning,
    stacklevel=2,
)
