"""The architecture of an SB3 actor-critic policy for an AMaze robot, without JAX.

:class:`PolicySpec` says which modules a policy has and their shapes (torch's
layout, SB3's names); :mod:`rl_baselines.jax.networks` builds and runs them in
JAX, :mod:`rl_baselines.jax.policy` in numpy. It imports no JAX, so that a
trained policy can be evaluated without loading JAX.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from amaze.agents.robot import Robot, as_robot

__all__ = ["CONV1", "CONV2", "LINEAR", "N_ACTIONS", "PolicySpec"]

#: Discrete actions of AMaze's robots: E, N, W, S.
N_ACTIONS = 4
#: SB3's initialisation gains (``ActorCriticPolicy._build``).
GAIN_HIDDEN = float(np.sqrt(2))
GAIN_ACTION = 0.01
GAIN_VALUE = 1.0
#: The modules of SmallCNN (``rl_baselines/networks.py``) by their SB3 names.
CONV1, CONV2, LINEAR = (
    "features_extractor.cnn.0",
    "features_extractor.cnn.2",
    "features_extractor.linear.0",
)


@dataclass(frozen=True)
class PolicySpec:
    """The architecture of one policy: robot, MLP layers, CNN features (hashable, static).

    ``robot`` is a robot string with discrete actions (``DD`` or ``H<v>``);
    ``net_pi`` / ``net_vf`` the hidden widths of the policy and value MLPs;
    ``features_dim`` the CNN's output width (hybrid robots).
    """

    robot: str = "DD"
    net_pi: tuple[int, ...] = (64, 64)
    net_vf: tuple[int, ...] = (64, 64)
    features_dim: int = 64

    @property
    def parsed_robot(self) -> Robot:
        return as_robot(self.robot)

    @property
    def images(self) -> bool:
        """Whether the robot sees images (a CNN features extractor)."""
        return not self.parsed_robot.discrete_inputs

    @property
    def observation_shape(self) -> tuple[int, ...]:
        if not self.images:
            return (8,)
        v = int(self.parsed_robot.vision)
        return (1, v, v)

    def layer_shapes(self) -> dict[str, tuple[int, ...]]:
        """The weight shape (torch layout) of every module, in SB3's parameter order."""
        shapes: dict[str, tuple[int, ...]] = {}
        width = 8
        if self.images:
            v = self.observation_shape[-1]
            shapes[CONV1] = (16, 1, 3, 3)
            shapes[CONV2] = (32, 16, 3, 3)
            shapes[LINEAR] = (self.features_dim, 32 * (v // 2) * (v // 2))
            width = self.features_dim
        for net, layers in (("policy_net", self.net_pi), ("value_net", self.net_vf)):
            previous = width
            for i, size in enumerate(layers):
                shapes[f"mlp_extractor.{net}.{2 * i}"] = (size, previous)
                previous = size
        shapes["action_net"] = (N_ACTIONS, self.net_pi[-1] if self.net_pi else width)
        shapes["value_net"] = (1, self.net_vf[-1] if self.net_vf else width)
        return shapes

    def gain(self, module: str) -> float:
        """The orthogonal gain SB3 gives ``module`` (``ActorCriticPolicy._build``)."""
        if module == "action_net":
            return GAIN_ACTION
        if module == "value_net":
            return GAIN_VALUE
        return GAIN_HIDDEN
