"""Deprecated: the old name of :mod:`rl_baselines.jax.run`.

Importing it issues a :class:`DeprecationWarning` and gives the public names
of :mod:`rl_baselines.jax.run`; the old name goes in the next release.
"""

from __future__ import annotations

import warnings

from rl_baselines.jax.run import TRAINER_FOLDER, JaxRun

__all__ = ["TRAINER_FOLDER", "JaxRun"]

warnings.warn(
    "rl_baselines.jax_run is now rl_baselines.jax.run; the old name goes in the next release",
    DeprecationWarning,
    stacklevel=2,
)
