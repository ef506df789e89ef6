"""The NEAT configuration: JSON round trip and the values it refuses."""

from __future__ import annotations

import json

import pytest

from evolution import EvolutionConfigError
from evolution.neat import NeatConfig


def test_config_round_trip_and_validation():
    config = NeatConfig(population_size=40, activation="relu")
    assert NeatConfig.from_dict(json.loads(json.dumps(config.to_dict()))) == config
    assert NeatConfig.from_dict({}) == NeatConfig()
    with pytest.raises(EvolutionConfigError, match="'speciess'"):
        NeatConfig.from_dict({"speciess": 3})
    for key, value in [
        ("population_size", 1),
        ("population_size", "10"),
        ("crossover_rate", 1.5),
        ("activation", "softmax"),
        ("compatibility_threshold", 0.0),
        ("weight_mutate_power", float("nan")),
        ("stagnation", True),
    ]:
        with pytest.raises(EvolutionConfigError, match=f"'{key}'"):
            NeatConfig.from_dict({key: value})
