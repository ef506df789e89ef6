"""A small CNN features extractor for the hybrid robots' tiny images.

SB3's ``CnnPolicy`` (the Nature-DQN CNN with 8x8 stride-4 kernels) needs images
of at least 36x36; AMaze's hybrid robots see ``(1, v, v)`` with ``v`` around 15.
:class:`SmallCNN` keeps the spatial size: two 3x3 convolutions with padding 1
(16 then 32 channels, ReLU), a 2x2 max-pool, then a linear layer to
``features_dim`` (ReLU). Use it with ``policy="CnnPolicy"`` and
``policy_kwargs=small_cnn_kwargs()``.
"""

from __future__ import annotations

from typing import Any

import torch
from gymnasium import spaces
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from torch import nn

__all__ = ["SmallCNN", "small_cnn_kwargs"]


class SmallCNN(BaseFeaturesExtractor):
    """Two padded 3x3 convolutions, a 2x2 max-pool and a linear layer (see the module)."""

    def __init__(self, observation_space: spaces.Box, features_dim: int = 64) -> None:
        super().__init__(observation_space, features_dim)
        channels = int(observation_space.shape[0])
        self.cnn = nn.Sequential(
            nn.Conv2d(channels, 16, kernel_size=3, padding=1),
            nn.ReLU(),
            nn.Conv2d(16, 32, kernel_size=3, padding=1),
            nn.ReLU(),
            nn.MaxPool2d(2),
            nn.Flatten(),
        )
        with torch.no_grad():
            sample = torch.as_tensor(observation_space.sample()[None]).float()
            n_flat = int(self.cnn(sample).shape[1])
        self.linear = nn.Sequential(nn.Linear(n_flat, features_dim), nn.ReLU())

    def forward(self, observations: torch.Tensor) -> torch.Tensor:
        return self.linear(self.cnn(observations))


def small_cnn_kwargs(features_dim: int = 64) -> dict[str, Any]:
    """``policy_kwargs`` for an SB3 ``CnnPolicy`` using :class:`SmallCNN`."""
    return {
        "features_extractor_class": SmallCNN,
        "features_extractor_kwargs": {"features_dim": features_dim},
        "normalize_images": True,
    }
