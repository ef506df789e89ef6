"""The NEAT configuration: JSON round trip and the values it refuses."""

from __future__ import annotations

import json

import numpy as np
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


@pytest.mark.parametrize(
    ("key", "value", "expected"),
    [
        ("image_connection_fraction", 0.0, "in (0, 1]"),
        ("target_species", -1, "non-negative integer"),
        ("weight_max", float("inf"), "finite"),
        ("tournament_size", 2.0, "positive integer"),
        ("symmetry", "mirror", "none, rotations"),
    ],
)
def test_bad_values_are_named_with_what_was_expected(key, value, expected):
    with pytest.raises(EvolutionConfigError, match=f"'{key}'") as caught:
        NeatConfig.from_dict({key: value})
    assert repr(value) in str(caught.value) and expected in str(caught.value)


def test_bounds_are_inclusive_where_they_should_be_and_numbers_normalised():
    config = NeatConfig(
        population_size=np.int64(2),
        image_connection_fraction=1,
        crossover_rate=np.float32(0.0),
        target_species=0,
        elitism=0,
    )
    assert type(config.population_size) is int and config.population_size == 2
    assert type(config.image_connection_fraction) is float
    assert type(config.crossover_rate) is float and config.crossover_rate == 0.0
