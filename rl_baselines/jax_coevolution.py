"""Deprecated: the old name of :mod:`rl_baselines.jax.coevolution`.

Importing it issues a :class:`DeprecationWarning` and gives the public names
of :mod:`rl_baselines.jax.coevolution`; the old name goes in the next release.
Checkpoints that name its classes are read as the new module's
(:data:`amaze.runs.state_document.RENAMED_MODULES`).
"""

from __future__ import annotations

import warnings

from rl_baselines.jax.coevolution import JaxCoevolutionRun

__all__ = ["JaxCoevolutionRun"]

warnings.warn(
    "rl_baselines.jax_coevolution is now rl_baselines.jax.coevolution; the old name goes in the"
    " next release",
    DeprecationWarning,
    stacklevel=2,
)
