"""Convolutional networks for image robots: evolved 3x3 filters, then the dense layers.

The forward pass is checked against a plain float64 reference that slides
each filter over the image itself (and, with rotations, turns the image
itself with ``np.rot90``), so the turned-filter gather of the kernel is
checked against the definition, not against its own formula.
"""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest

from evolution import EvolutionConfigError
from evolution.cmaes import CMAESAlgorithm
from evolution.networks import NetworkSpec
from tests.evolution.test_networks import ACTIVATIONS, random_observations, turned


def reference_features(spec: NetworkSpec, vector: np.ndarray, images: np.ndarray) -> np.ndarray:
    """``(n, filters x grid^2)``: each filter slid over each image, plainly, in float64."""
    weights, biases = spec.filter_params(vector)
    n, v, s, g = images.shape[0], images.shape[-1], spec.stride, spec.grid
    pixels = images.reshape(n, v, v).astype(np.float64) / 255.0
    maps = np.zeros((n, spec.filters, g, g))
    for f, i, j in itertools.product(range(spec.filters), range(g), range(g)):
        patch = pixels[:, i * s : i * s + 3, j * s : j * s + 3]
        maps[:, f, i, j] = (patch * weights[f]).sum(axis=(1, 2)) + biases[f]
    return ACTIVATIONS[spec.activation](maps).reshape(n, -1)


def reference_outputs(spec: NetworkSpec, params: np.ndarray, observations: np.ndarray):
    """The output layer of each agent (one per direction with rotations), in float64."""
    p_count = params.shape[0]
    m = observations.shape[0] // p_count
    turns = range(4) if spec.copies > 1 else [None]
    outputs = []
    for p in range(p_count):
        vector = params[p].astype(np.float32).astype(np.float64)
        rows = observations[p * m : (p + 1) * m]
        columns = []
        for d in turns:
            x = reference_features(spec, vector, rows if d is None else turned("H", rows, d))
            for k, (w, b) in enumerate(spec.unflatten(vector)):
                x = x @ w + b
                if k < len(spec.layer_shapes) - 1:
                    x = ACTIVATIONS[spec.activation](x)
            columns.append(x)
        outputs.append(np.concatenate(columns, axis=1))
    return np.concatenate(outputs)


CASES = [
    ("H15", 3, (8,), "tanh", "none"),
    ("H15", 2, (6,), "relu", "rotations"),
    ("H11", 2, (), "tanh", "rotations"),
    ("H11", 1, (5, 4), "sigmoid", "none"),
    ("CD7", 3, (4,), "identity", "none"),
    ("CC15", 2, (4,), "tanh", "none"),
]


@pytest.mark.parametrize(("robot", "filters", "hidden", "activation", "symmetry"), CASES)
@pytest.mark.parametrize(("p_count", "m"), [(3, 70), (66, 3)])
def test_forward_pass_matches_filters_slid_over_the_image(
    robot, filters, hidden, activation, symmetry, p_count, m
):
    rng = np.random.default_rng(filters + len(hidden) + p_count)
    spec = NetworkSpec(robot, hidden, activation, symmetry=symmetry, filters=filters)
    params = spec.initial_params(rng, p_count) + rng.normal(0, 0.3, (p_count, spec.n_params))
    observations = random_observations(spec.robot, p_count * m, rng)
    expected = reference_outputs(spec, params, observations)
    for parallel in (False, True):
        population = spec.population(params, parallel=parallel)
        values = population.forward(observations)
        assert values.shape == expected.shape and values.dtype == np.float32
        np.testing.assert_allclose(values, expected, rtol=1e-4, atol=1e-4)
        if spec.robot_info.discrete_outputs:
            ranked = np.sort(expected, axis=1)
            clear = ranked[:, -1] - ranked[:, -2] > 1e-3
            assert clear.mean() > 0.9
            actions = population(observations)
            np.testing.assert_array_equal(actions[clear], expected.argmax(axis=1)[clear])


@pytest.mark.parametrize("robot", ["H15", "H11"])
def test_convolutional_rotations_make_the_policy_equivariant(robot):
    rng = np.random.default_rng(4)
    spec = NetworkSpec(robot, (6,), symmetry="rotations", filters=3)
    population = spec.population(spec.initial_params(rng, 4) * 2)
    observations = random_observations(spec.robot, 4 * 50, rng)
    actions = population(observations)
    assert len(np.unique(actions)) == 4
    for turns in (1, 2, 3):
        np.testing.assert_array_equal(
            population(turned(robot, observations, -turns)), (actions + turns) % 4
        )


def test_an_individual_acts_alike_alone_in_a_population_and_with_retirements():
    rng = np.random.default_rng(9)
    spec = NetworkSpec("H15", (8,), symmetry="rotations", filters=2)
    params = spec.initial_params(rng, 3) * 2
    population = spec.population(params)
    observations = random_observations(spec.robot, 30, rng)
    full = population(observations)
    for p in range(3):
        rows = slice(10 * p, 10 * p + 10)
        np.testing.assert_array_equal(population.individual(p)(observations[rows]), full[rows])
    population.reset(30)
    population.retire(np.array([0, 11, 29]))
    keep = np.setdiff1d(np.arange(30), [0, 11, 29])
    np.testing.assert_array_equal(population(observations)[keep], full[keep])


def test_parameter_layout_counts_and_round_trip():
    spec = NetworkSpec("H15", (16,), filters=4)
    # 4 filters of 9 weights and a bias; 4 x 5 x 5 features into 16 units, 4 logits
    assert (spec.stride, spec.grid, spec.n_inputs) == (3, 5, 100)
    assert spec.n_params == 40 + 100 * 16 + 16 + 16 * 4 + 4
    assert NetworkSpec("H11", filters=2).stride == 2  # 11 - 3 = 8: strides 2 and 1 tile it
    assert NetworkSpec("H15", (16,), symmetry="rotations", filters=4).n_params == 40 + 1633
    vector = np.arange(spec.n_params, dtype=np.float64)
    weights, biases = spec.filter_params(vector)
    np.testing.assert_array_equal(weights.ravel(), np.arange(36))
    np.testing.assert_array_equal(biases, [36, 37, 38, 39])
    assert spec.unflatten(vector)[0][0][0, 0] == 40  # the dense layers follow the filters
    data = json.loads(json.dumps(spec.to_dict()))
    assert data["filters"] == 4 and data["stride"] == 3 and NetworkSpec.from_dict(data) == spec
    older = {"robot": "H15", "hidden": [4], "pool": 5}  # an agent file of before filters
    assert NetworkSpec.from_dict(older).filters == 0


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"robot": "DD", "filters": 2}, "robot DD has no image to convolve"),
        ({"robot": "H15", "filters": 2, "pool": 5}, "pools its image or convolves it"),
        ({"robot": "H15", "filters": 2, "stride": 4}, r"stride 4 is not an integer in \[1, 3\]"),
        ({"robot": "H11", "filters": 2, "stride": 3}, "does not tile a retina of 11 pixels"),
        ({"robot": "H15", "stride": 3}, "stride 3 without filters"),
        ({"robot": "H15", "filters": -1}, "filters -1"),
    ],
)
def test_bad_convolutions_are_refused(kwargs, message):
    with pytest.raises(EvolutionConfigError, match=message):
        NetworkSpec(**kwargs)


def test_cmaes_evolves_a_convolutional_network_and_checks_its_options():
    algorithm = CMAESAlgorithm(
        {"network": {"hidden": [4], "filters": 2, "symmetry": "rotations"}}, "H15", seed=1
    )
    assert algorithm.spec.filters == 2 and algorithm.spec.stride == 3
    candidates = algorithm.ask()
    policy = algorithm.population_policy(candidates)
    observations = random_observations("CD15", len(candidates) * 2, np.random.default_rng(0))
    assert policy(observations).shape == (len(candidates) * 2,)
    with pytest.raises(EvolutionConfigError, match="robot DD has no image to convolve"):
        CMAESAlgorithm({"network": {"filters": 2}}, "DD", seed=1)
    with pytest.raises(EvolutionConfigError, match="'network': filters"):
        CMAESAlgorithm({"network": {"filters": "many"}}, "H15", seed=1)
