"""Named settings of the JAX learners: ``preset: fast``, fixed by a documented sweep.

A preset fills the options it names that a config leaves unset (given ones
win, a given ``hyperparameters`` key included); ``config.json`` records every
value. ``fast`` is the throughput setting of the JAX PPO and A2C: the shared
network (16 hidden units, one body for the four directions), many
environments, short rollouts, large minibatches, few epochs, as PureJaxRL's and
CleanRL's JAX PPO run. Its values won the ``rl-fast-sweep`` study (five
settings, 300 s on co-evolved mazes, 2 seeds, judged on the validation mazes
alone, by median success then median R̄: ``ppo-s4``,
``experiments/results/rl-fast-sweep/``). SB3's defaults stay the paper's
baseline (no preset).
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from typing import Any

__all__ = ["PRESETS", "preset_values"]

#: The network every preset trains (evolution's coevolution network: 16 units, symmetric).
FAST_NETWORK = {"hidden": [16], "symmetry": "rotations"}
#: The named presets: the config fields each fills (``hyperparameters`` key by key).
PRESETS: dict[str, dict[str, Any]] = {
    "fast": {
        "framework": "jax",
        "n_envs": 256,
        "network": FAST_NETWORK,
        "hyperparameters": {
            "n_steps": 32,
            "batch_size": 2048,
            "n_epochs": 4,
            "learning_rate": 1e-3,
        },
    },
}
#: Hyperparameters PPO has and A2C does not (A2C's preset leaves them out).
_PPO_ONLY = ("batch_size", "n_epochs")


def preset_values(
    preset: str, algo: str, given: Collection[str], hyperparameters: Mapping[str, Any]
) -> dict[str, Any]:
    """The fields ``preset`` sets for ``algo``, leaving out those in ``given``.

    ``hyperparameters`` (the config's) is returned whole, the preset's keys
    added where it lacks them. Raises ``ValueError`` for an unknown preset.
    """
    if preset not in PRESETS:
        raise ValueError(f"unknown preset {preset!r} (choose from {', '.join(PRESETS)})")
    values = {k: v for k, v in PRESETS[preset].items() if k != "hyperparameters"}
    values = {name: value for name, value in values.items() if name not in given}
    filled = {
        name: value
        for name, value in PRESETS[preset]["hyperparameters"].items()
        if not (algo == "a2c" and name in _PPO_ONLY)
    }
    values["hyperparameters"] = {**filled, **hyperparameters}
    return values
