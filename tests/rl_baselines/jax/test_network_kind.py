"""The RL learners' ``network`` kind: evolution's network spec, trained by A2C/PPO.

With ``symmetry = "rotations"`` turning the observation turns the action
distribution (the logits shift cyclically) and leaves the value unchanged; the
JAX forward pass, the numpy one and an evolved network of the same spec give
the same logits for the actor; bad specs are refused by name.
"""

from __future__ import annotations

import numpy as np
import pytest

jax = pytest.importorskip("jax")

from amaze.agents.network_inputs import rotation_index  # noqa: E402
from evolution.networks import NetworkSpec  # noqa: E402
from rl_baselines import RLConfigError  # noqa: E402
from rl_baselines.jax.networks import apply, init_params  # noqa: E402
from rl_baselines.jax.policy import NumpyPolicy  # noqa: E402
from rl_baselines.jax.spec import PolicySpec, accelerations, network_spec  # noqa: E402

NETWORKS = [
    ("DD", {"hidden": [16], "symmetry": "rotations"}),
    ("DD", {"hidden": [8, 8], "activation": "relu"}),
    ("H15", {"hidden": [16], "symmetry": "rotations"}),
    ("H15", {"hidden": [], "pool": 3, "activation": "sigmoid"}),
    ("H15", {"hidden": [16], "symmetry": "rotations", "pooling": "max"}),
    ("H11", {"hidden": [8], "pooling": "max"}),  # blocks of unequal sizes
    ("H15", {"hidden": [8], "symmetry": "rotations", "pooling": "max-ring", "pool": 7}),
    ("H11", {"hidden": [8], "pooling": "mean-ring"}),
    ("H15", {"hidden": [16], "filters": 4, "symmetry": "rotations"}),
    ("H11", {"hidden": [8], "filters": 3, "activation": "relu"}),
    ("H7", {"hidden": [], "filters": 2, "stride": 1, "symmetry": "rotations"}),
    ("CC15", {"hidden": [16], "symmetry": "rotations"}),
    ("CC7", {"hidden": [8], "pool": 3}),
    ("CC11", {"hidden": [8], "filters": 3, "symmetry": "rotations"}),
]


def _observations(robot: str, n: int = 64) -> np.ndarray:
    rng = np.random.default_rng(3)
    if robot == "DD":
        return rng.choice([0.0, 0.25, 0.5, 1.0], size=(n, 8)).astype(np.float32)
    v = int(robot.lstrip("CDH"))
    return rng.integers(0, 256, size=(n, 1, v, v)).astype(np.uint8)


def _params(spec, seed: int = 0) -> dict:
    params = init_params(spec, jax.random.key(seed))
    # SB3's action gain (0.01) makes tiny logits: scale every layer up to tell them apart
    rng = np.random.default_rng(seed)
    return {
        m: {k: np.asarray(v) + rng.normal(0, 0.3, v.shape).astype(np.float32) for k, v in p.items()}
        for m, p in params.items()
    }


@pytest.mark.parametrize(("robot", "filters"), [("DD", 0), ("H15", 0), ("H15", 4), ("H11", 3)])
def test_turning_the_inputs_turns_the_logits_and_keeps_the_value(robot: str, filters: int) -> None:
    network = {"hidden": [16], "symmetry": "rotations", **({"filters": filters} if filters else {})}
    spec = network_spec(robot, network)
    params = _params(spec)
    obs = _observations(robot)
    if robot == "DD":
        turned = obs[:, rotation_index(None)[1]]
    else:  # the image turned a quarter-turn clockwise, as rotation_index turns the grid
        turned = np.rot90(obs, -1, axes=(2, 3)).copy()
    logits, values = (np.asarray(a) for a in apply(spec, params, obs))
    turned_logits, turned_values = (np.asarray(a) for a in apply(spec, params, turned))
    np.testing.assert_allclose(turned_logits, np.roll(logits, -1, axis=1), rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(turned_values, values, rtol=1e-5, atol=1e-5)
    assert not np.allclose(logits, np.roll(logits, -1, axis=1))  # the turn is not trivial


@pytest.mark.parametrize("filters", [0, 3])
def test_turning_the_image_turns_a_continuous_robots_acceleration(filters: int) -> None:
    """The image turned a quarter-turn clockwise turns the mean acceleration ``(x, y)``
    to ``(y, -x)`` (north becomes east), and keeps the value."""
    network = {"hidden": [16], "symmetry": "rotations", **({"filters": filters} if filters else {})}
    spec = network_spec("CC11", network)
    params = _params(spec)
    obs = _observations("CC11")
    turned = np.rot90(obs, -1, axes=(2, 3)).copy()
    mean, values = (np.asarray(a) for a in apply(spec, params, obs))
    turned_mean, turned_values = (np.asarray(a) for a in apply(spec, params, turned))
    assert mean.shape == (len(obs), 2) and np.all(np.abs(mean) <= 1)
    np.testing.assert_allclose(turned_mean, np.stack([mean[:, 1], -mean[:, 0]], 1), atol=1e-5)
    np.testing.assert_allclose(turned_values, values, rtol=1e-5, atol=1e-5)
    assert np.abs(mean).max() > 0.1  # not a trivially zero acceleration


def test_a_continuous_robot_needs_a_network() -> None:
    with pytest.raises(RLConfigError, match="robot CC15 has continuous actions"):
        PolicySpec("CC15")


def test_without_symmetry_turning_the_inputs_changes_the_logits_otherwise() -> None:
    spec = network_spec("DD", {"hidden": [16]})
    params = _params(spec)
    obs = _observations("DD")
    logits = np.asarray(apply(spec, params, obs)[0])
    turned = np.asarray(apply(spec, params, obs[:, rotation_index(None)[1]])[0])
    assert not np.allclose(turned, np.roll(logits, -1, axis=1), atol=1e-3)


@pytest.mark.parametrize(("robot", "network"), NETWORKS)
def test_jax_numpy_and_an_evolved_network_agree(robot: str, network: dict) -> None:
    spec = network_spec(robot, network)
    params = _params(spec, seed=1)
    obs = _observations(robot)
    logits, values = (np.asarray(a) for a in apply(spec, params, obs))
    policy = NumpyPolicy(spec, params)
    numpy_logits, numpy_values = policy.logits_and_values(obs)
    numpy_outputs = accelerations(spec, numpy_logits, np) if spec.continuous else numpy_logits
    np.testing.assert_allclose(numpy_outputs, logits, rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(numpy_values, values, rtol=1e-5, atol=1e-5)
    evolved = NetworkSpec.from_dict(spec.architecture())
    vector = spec.actor_vector(params)
    assert vector.shape == (evolved.n_params,)
    population = evolved.population(vector[None])
    population.reset(len(obs))
    actions = population(obs)
    if spec.continuous:  # the mean accelerations; evolution's tanh is within 4e-7 of numpy's
        np.testing.assert_allclose(actions, policy(obs), rtol=0, atol=1e-5)
        np.testing.assert_allclose(actions, logits, rtol=0, atol=1e-5)
    else:
        np.testing.assert_array_equal(actions, policy(obs))
    # the vector read back is the same actor
    actor = spec.actor_from_vector(vector)
    again = NumpyPolicy(spec, actor, actor_only=True)
    np.testing.assert_array_equal(again.logits(obs), numpy_logits)


@pytest.mark.parametrize(
    ("robot", "network", "words"),
    [
        ("DD", {"hiden": [16]}, "'hiden' (did you mean 'hidden'?)"),
        ("DD", {"filters": 4}, "network filters 4: robot DD has no image to read"),
        ("H15", {"filters": 4, "pool": 3}, "pools its image or convolves it, not both"),
        ("H13", {"filters": 4, "stride": 3}, "stride 3 does not tile a retina of 13 pixels"),
        ("H15", {"stride": 3}, "stride 3 without filters"),
        ("H15", {"filters": 65}, "network filters"),
        ("H15", {"filtres": 4}, "'filtres' (did you mean 'filters'?)"),
        ("DD", {"pool": 3}, "network pool 3: robot DD has no image to read"),
        ("H15", {"pool": 16}, "network pool"),
        ("H15", {"pooling": "median"}, "network pooling 'median' is not one of mean, max"),
        ("DD", {"pooling": "max"}, "network pooling 'max': the network robot DD has no image"),
        ("H15", {"filters": 2, "pooling": "max"}, "the network convolves its image"),
        ("H15", {"pool": 2, "pooling": "max-ring"}, "pool 2: the ring takes"),
        ("DD", {"symmetry": "mirror"}, "network symmetry 'mirror'"),
        ("DD", {"activation": "gelu"}, "network activation 'gelu'"),
        ("DD", {"hidden": [0]}, "network hidden"),
        ("DD", [16], "is not a mapping"),
    ],
)
def test_a_bad_network_spec_is_refused_by_name(robot: str, network: object, words: str) -> None:
    with pytest.raises(RLConfigError) as caught:
        network_spec(robot, network)  # type: ignore[arg-type]
    assert words in str(caught.value)
