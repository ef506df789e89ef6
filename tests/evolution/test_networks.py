"""Fixed-topology networks: spec validation, parameter layout, the batched forward pass."""

from __future__ import annotations

import itertools
import json
import pickle

import numpy as np
import pytest

from evolution import EvolutionConfigError
from evolution.networks import NetworkPopulation, NetworkSpec

#: Block edges of the pooled 5x5 grid, as documented in evolution.networks.
EDGES = {15: [0, 3, 6, 9, 12, 15], 11: [0, 2, 4, 7, 9, 11], 7: [0, 1, 3, 4, 6, 7]}
#: The same with a ring pooling: the outermost pixel on each side alone, the inside in 3.
RING_EDGES = {15: [0, 1, 5, 10, 14, 15], 11: [0, 1, 4, 7, 10, 11], 7: [0, 1, 3, 4, 6, 7]}

ACTIVATIONS = {
    "tanh": np.tanh,
    "relu": lambda x: np.maximum(x, 0.0),
    "sigmoid": lambda x: 1.0 / (1.0 + np.exp(-x)),
    "identity": lambda x: x,
}


def reference_inputs(robot: str, observations: np.ndarray, pooling: str = "mean") -> np.ndarray:
    """Network inputs of one batch, written out plainly: 8 floats, or pooled pixels / 255
    (each block's mean, or with ``pooling = "max"`` its brightest pixel; the ``-ring``
    poolings on the ring's blocks)."""
    n = observations.shape[0]
    if robot == "DD":
        return observations.astype(np.float64)
    v = observations.shape[-1]
    images = observations.reshape(n, v, v).astype(np.float64) / 255.0
    edges = RING_EDGES[v] if pooling.endswith("-ring") else EDGES[v]
    out = np.zeros((n, 5, 5))
    for r in range(5):
        for c in range(5):
            block = images[:, edges[r] : edges[r + 1], edges[c] : edges[c + 1]]
            if pooling.startswith("max"):
                out[:, r, c] = block.max(axis=(1, 2))
            else:
                out[:, r, c] = block.sum(axis=(1, 2)) / block[0].size
    return out.reshape(n, 25)


def reference_outputs(
    spec: NetworkSpec, params: np.ndarray, observations: np.ndarray, n_outputs: int | None = None
):
    """Output layer of each agent, individual by individual, in float64.

    ``n_outputs`` replaces the spec's (1 for the one network of rotations).
    """
    p_count = params.shape[0]
    m = observations.shape[0] // p_count
    sizes = [spec.n_inputs, *spec.hidden, n_outputs or spec.n_outputs]
    outputs = []
    for p in range(p_count):
        x = reference_inputs(spec.robot, observations[p * m : (p + 1) * m], spec.pooling)
        vector = params[p].astype(np.float32).astype(np.float64)
        offset = 0
        for layer, (d_in, d_out) in enumerate(itertools.pairwise(sizes)):
            weights = vector[offset : offset + d_in * d_out].reshape(d_in, d_out)
            offset += d_in * d_out
            bias = vector[offset : offset + d_out]
            offset += d_out
            x = x @ weights + bias
            if layer < len(sizes) - 2:
                x = ACTIVATIONS[spec.activation](x)
        assert offset == spec.n_params
        outputs.append(x)
    return np.concatenate(outputs)


def random_observations(robot: str, n: int, rng: np.random.Generator) -> np.ndarray:
    if robot == "DD":
        return rng.choice([0.0, 0.25, 0.5, 1.0], size=(n, 8)).astype(np.float32)
    v = int(robot[2:])
    return rng.integers(0, 256, size=(n, 1, v, v)).astype(np.uint8)


CASES = [
    ("DD", (), "tanh"),
    ("DD", (16,), "tanh"),
    ("DD", (7, 5), "relu"),
    ("DD", (9,), "sigmoid"),
    ("DD", (3,), "identity"),
    ("CD15", (16,), "tanh"),
    ("CD11", (), "tanh"),
    ("CD7", (6, 4), "relu"),
    ("CC15", (8,), "tanh"),
    ("CC11", (), "tanh"),
]


@pytest.mark.parametrize(("robot", "hidden", "activation"), CASES)
@pytest.mark.parametrize(("p_count", "m"), [(3, 70), (66, 3)])
def test_forward_pass_matches_a_plain_reference(robot, hidden, activation, p_count, m):
    # the kernel puts 64 agents side by side: of one individual (3 x 70: two blocks
    # each), or the same episode of 64 individuals (66 x 3: two blocks per episode)
    rng = np.random.default_rng(len(hidden) + len(robot))
    spec = NetworkSpec(robot, hidden, activation)
    params = spec.initial_params(rng, p_count) + rng.normal(0, 0.3, (p_count, spec.n_params))
    observations = random_observations(spec.robot, p_count * m, rng)
    expected = reference_outputs(spec, params, observations)
    for parallel in (False, True):
        population = spec.population(params, parallel=parallel)
        values = population.forward(observations)
        assert values.shape == (p_count * m, spec.n_outputs) and values.dtype == np.float32
        np.testing.assert_allclose(values, expected, rtol=1e-4, atol=1e-4)
        actions = population(observations)
        if spec.n_outputs == 4:
            assert actions.dtype == np.int64 and actions.shape == (p_count * m,)
            ranked = np.sort(expected, axis=1)
            clear = ranked[:, -1] - ranked[:, -2] > 1e-3
            assert clear.mean() > 0.9
            np.testing.assert_array_equal(actions[clear], expected.argmax(axis=1)[clear])
        else:
            assert actions.dtype == np.float64 and actions.shape == (p_count * m, 2)
            np.testing.assert_allclose(actions, np.tanh(expected), atol=1e-4)
            assert np.abs(actions).max() <= 1.0


@pytest.mark.parametrize("robot", ["CD15", "CD11", "CC7"])  # 11 and 7: blocks of unequal sizes
def test_max_pooling_reads_each_block_s_brightest_pixel(robot):
    rng = np.random.default_rng(21)
    spec = NetworkSpec(robot, (6,), pooling="max")
    assert spec.n_inputs == 25 and spec.to_dict()["pooling"] == "max"
    params = spec.initial_params(rng, 3) + rng.normal(0, 0.3, (3, spec.n_params))
    observations = random_observations(spec.robot, 3 * 70, rng)
    expected_inputs = reference_inputs(spec.robot, observations, "max")
    np.testing.assert_allclose(spec.encode(observations), expected_inputs, rtol=1e-6)
    mean_inputs = NetworkSpec(robot, (6,)).encode(observations)
    assert not np.allclose(mean_inputs, expected_inputs)  # the option is not a no-op
    expected = reference_outputs(spec, params, observations)
    for parallel in (False, True):
        values = spec.population(params, parallel=parallel).forward(observations)
        np.testing.assert_allclose(values, expected, rtol=1e-4, atol=1e-4)


@pytest.mark.parametrize("robot", ["CD15", "CD11"])
@pytest.mark.parametrize("pooling", ["mean-ring", "max-ring"])
def test_ring_pooling_keeps_the_outermost_pixels_in_blocks_of_their_own(robot, pooling):
    rng = np.random.default_rng(22)
    spec = NetworkSpec(robot, (6,), pooling=pooling)
    assert spec.n_inputs == 25 and NetworkSpec.from_dict(spec.to_dict()) == spec
    params = spec.initial_params(rng, 3) + rng.normal(0, 0.3, (3, spec.n_params))
    observations = random_observations(spec.robot, 3 * 70, rng)
    expected_inputs = reference_inputs(spec.robot, observations, pooling)
    np.testing.assert_allclose(spec.encode(observations), expected_inputs, rtol=1e-6)
    plain = NetworkSpec(robot, (6,), pooling=pooling.removesuffix("-ring"))
    assert not np.allclose(plain.encode(observations), expected_inputs)  # not a no-op
    expected = reference_outputs(spec, params, observations)
    for parallel in (False, True):
        values = spec.population(params, parallel=parallel).forward(observations)
        np.testing.assert_allclose(values, expected, rtol=1e-4, atol=1e-4)


def test_a_signs_edge_lights_no_wall_block_with_a_ring():
    # why the ring: a hybrid robot's sign fills pixels 1..13 of its 15 x 15 cell, walls
    # and the arrival marker are pixels 0 and 14; even blocks mix the two
    sign_edge = np.zeros((1, 15, 15), np.uint8)
    sign_edge[0, 7, 1] = 255  # the sign's westmost pixel, beside the west wall's
    wall = np.zeros((1, 15, 15), np.uint8)
    wall[0, :, 0] = 255
    west = 3 * 7 + 0  # the middle block of the 7 x 7 grid's west column
    for pooling, lit in (("max", True), ("max-ring", False)):
        spec = NetworkSpec("H15", pool=7, pooling=pooling)
        assert (spec.encode(sign_edge)[0, west] > 0) == lit
        assert spec.encode(wall)[0, west] == 1.0
    with pytest.raises(EvolutionConfigError, match="pool 2: the ring"):
        NetworkSpec("H15", pool=2, pooling="max-ring")


def test_max_pooling_sees_a_stroke_at_its_lightness_whatever_its_width():
    # why "max": a thin and a thick stroke of one gray level pool to one value,
    # while the block means differ by the width (and so mistake width for lightness)
    thin, thick = np.zeros((1, 15, 15), np.uint8), np.zeros((1, 15, 15), np.uint8)
    thin[0, 7, 3:12] = 128
    thick[0, 6:9, 3:12] = 128
    for pooling, same in (("max", True), ("mean", False)):
        spec = NetworkSpec("H15", pooling=pooling)
        a, b = spec.encode(thin), spec.encode(thick)
        assert np.array_equal(a, b) == same
    assert NetworkSpec("H15", pooling="max").encode(thin).max() == np.float32(128 / 255)


def test_population_equals_its_individuals_and_threads_do_not_matter():
    rng = np.random.default_rng(3)
    spec = NetworkSpec("DD", (16,))
    params = spec.initial_params(rng, 5)
    observations = random_observations("DD", 5 * 40, rng)
    serial = spec.population(params, parallel=False)
    threaded = spec.population(params, parallel=True)
    np.testing.assert_array_equal(serial.forward(observations), threaded.forward(observations))
    actions = serial(observations)
    np.testing.assert_array_equal(actions, threaded(observations))
    for p in range(5):
        alone = serial.individual(p)
        rows = slice(p * 40, (p + 1) * 40)
        np.testing.assert_array_equal(alone(observations[rows]), actions[rows])
        # a population of one plays any number of agents
        np.testing.assert_array_equal(alone(observations[rows][:7]), actions[rows][:7])
    np.testing.assert_array_equal(
        serial.subset([4, 1])(np.concatenate([observations[160:200], observations[40:80]])),
        np.concatenate([actions[160:200], actions[40:80]]),
    )


@pytest.mark.parametrize("robot", ["DD", "CC7"])
def test_both_kinds_of_blocks_give_identical_outputs(robot):
    rng = np.random.default_rng(12)
    spec = NetworkSpec(robot, (9, 5))
    params = spec.initial_params(rng, 66) * 2
    observations = random_observations(spec.robot, 66 * 3, rng)
    population = spec.population(params)  # 66 individuals x 3 episodes: by episode
    values = population.forward(observations)
    actions = population(observations)
    for p in (0, 63, 64, 65):  # one individual x 3 episodes: by individual
        alone = spec.population(params[p : p + 1])
        rows = slice(3 * p, 3 * p + 3)
        np.testing.assert_array_equal(alone.forward(observations[rows]), values[rows])
        np.testing.assert_array_equal(alone(observations[rows]), actions[rows])


def test_ties_pick_the_first_action():
    spec = NetworkSpec("DD")
    params = np.zeros((1, spec.n_params))
    params[0, -4:] = [0.0, 1.0, 1.0, 0.5]  # biases of N and W tie
    actions = spec.population(params)(np.zeros((3, 8), dtype=np.float32))
    np.testing.assert_array_equal(actions, [1, 1, 1])


def test_retired_agents_are_skipped_until_reset():
    rng = np.random.default_rng(4)
    spec = NetworkSpec("DD", (8,))
    population = spec.population(spec.initial_params(rng, 2) * 3)
    observations = random_observations("DD", 20, rng)
    full = population(observations)
    assert (full != 0).any()
    population.reset(20)
    population.retire(np.array([1, 2, 15]))
    partial = population(observations)
    keep = np.setdiff1d(np.arange(20), [1, 2, 15])
    np.testing.assert_array_equal(partial[keep], full[keep])
    np.testing.assert_array_equal(partial[[1, 2, 15]], 0)
    np.testing.assert_array_equal(population.forward(observations).argmax(axis=1), full)
    population.reset(20)
    np.testing.assert_array_equal(population(observations), full)
    population.retire(np.arange(10))
    population.retire(np.arange(10, 20))  # all retired: the run is over, all act again
    np.testing.assert_array_equal(population(observations), full)


@pytest.mark.parametrize(
    ("spec", "n_inputs", "n_outputs", "n_params"),
    [
        (NetworkSpec("DD"), 8, 4, 36),
        (NetworkSpec("DD", (16,)), 8, 4, 212),
        (NetworkSpec("DD", (32, 32)), 8, 4, 1476),
        (NetworkSpec("H15"), 25, 4, 104),
        (NetworkSpec("CD11", (16,)), 25, 4, 484),
        (NetworkSpec("C15", (16,)), 25, 2, 450),
        (NetworkSpec("CC11", (32, 32)), 25, 2, 1954),
        (NetworkSpec("H15", (), pool=3), 9, 4, 40),
        (NetworkSpec("H7", (), pool=7), 49, 4, 200),
    ],
)
def test_parameter_counts(spec, n_inputs, n_outputs, n_params):
    assert (spec.n_inputs, spec.n_outputs, spec.n_params) == (n_inputs, n_outputs, n_params)
    assert sum(a * b + b for a, b in spec.layer_shapes) == n_params
    assert spec.layer_shapes[0][0] == n_inputs and spec.layer_shapes[-1][1] == n_outputs
    vector = np.arange(n_params, dtype=np.float64)
    layers = spec.unflatten(vector)
    assert np.concatenate([np.concatenate([w.ravel(), b]) for w, b in layers]).tolist() == list(
        vector
    )


def test_spec_is_canonical_and_round_trips():
    spec = NetworkSpec("H15", [16, 8], "relu")
    assert spec.robot == "CD15" and spec.hidden == (16, 8) and spec.pool == 5
    assert NetworkSpec("D").robot == "DD" and NetworkSpec("DD").pool is None
    with pytest.raises(ValueError, match="takes no vision size"):
        NetworkSpec("D11")
    for item in (
        spec,
        NetworkSpec("DD"),
        NetworkSpec("CC11", (4,), "sigmoid", pool=3),
        NetworkSpec("H15", (8,), pooling="max"),
    ):
        data = json.loads(json.dumps(item.to_dict()))
        assert NetworkSpec.from_dict(data) == item
        assert NetworkSpec.from_dict({"type": "mlp", **data}) == item
    assert NetworkSpec.from_dict({"robot": "DD"}) == NetworkSpec("DD")


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"robot": "XX"}, "XX"),
        ({"robot": 3}, "3"),
        ({"hidden": (0,)}, "0"),
        ({"hidden": (16, -2)}, "-2"),
        ({"hidden": "16"}, "'16'"),
        ({"hidden": (True,)}, "True"),
        ({"hidden": (2.5,)}, "2.5"),
        ({"activation": "softmax"}, "softmax"),
        ({"robot": "H15", "pool": 0}, "0"),
        ({"robot": "H15", "pool": 16}, "16"),
        ({"robot": "DD", "pool": 5}, "pool 5"),
        ({"robot": "H15", "pooling": "median"}, "pooling 'median' is not one of mean, max"),
        ({"robot": "DD", "pooling": "max"}, "robot DD has no image to pool"),
        ({"robot": "H15", "filters": 2, "pooling": "max"}, "convolves its image"),
    ],
)
def test_bad_specs_are_refused(kwargs, message):
    with pytest.raises(EvolutionConfigError, match=message):
        NetworkSpec(**kwargs)


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"robot": "DD", "layers": 3}, "layers"),
        ({"type": "neat", "robot": "DD"}, "neat"),
        ({"hidden": [4]}, "robot"),
        ({"robot": "DD", "hidden": [4, "x"]}, "'x'"),
        ("DD", "DD"),
    ],
)
def test_bad_spec_dicts_are_refused(data, message):
    with pytest.raises(EvolutionConfigError, match=message):
        NetworkSpec.from_dict(data)


def test_initial_params_are_seeded_and_scaled():
    spec = NetworkSpec("DD", (64,))
    one = spec.initial_params(np.random.default_rng(0))
    assert one.shape == (spec.n_params,) and one.dtype == np.float64
    many = spec.initial_params(np.random.default_rng(0), 50)
    assert many.shape == (50, spec.n_params)
    np.testing.assert_array_equal(spec.initial_params(np.random.default_rng(0), 50), many)
    (_, b1), (_, b2) = spec.unflatten(many[7])
    assert not b1.any() and not b2.any()
    weights = np.stack([spec.unflatten(row)[0][0] for row in many])
    assert abs(weights.std() - 1 / np.sqrt(8)) < 0.02


def test_bad_parameters_and_batches_are_refused():
    spec = NetworkSpec("DD", (4,))
    with pytest.raises(EvolutionConfigError, match=str(spec.n_params)):
        spec.population(np.zeros((2, spec.n_params + 1)))
    with pytest.raises(EvolutionConfigError, match="finite"):
        spec.population(np.full((1, spec.n_params), np.nan))
    population = spec.population(np.zeros((3, spec.n_params)))
    with pytest.raises(EvolutionConfigError, match="10 agents cannot be shared by 3"):
        population.reset(10)
    with pytest.raises(EvolutionConfigError, match="cannot be shared"):
        population(np.zeros((10, 8), dtype=np.float32))
    with pytest.raises(EvolutionConfigError, match=r"shape \(n, 8\)"):
        population(np.zeros((3, 9), dtype=np.float32))
    image = NetworkSpec("H7").population(np.zeros((1, NetworkSpec("H7").n_params)))
    with pytest.raises(EvolutionConfigError, match="7x7"):
        image(np.zeros((2, 1, 9, 9), dtype=np.uint8))


def test_populations_pickle_as_spec_and_parameters():
    rng = np.random.default_rng(5)
    spec = NetworkSpec("CD11", (6,))
    population = spec.population(spec.initial_params(rng, 4), parallel=False)
    observations = random_observations("CD11", 4 * 9, rng)
    expected = population(observations)
    clone = pickle.loads(pickle.dumps(population))
    assert isinstance(clone, NetworkPopulation) and clone.spec == spec
    assert clone.n_policies == 4 and clone.parallel is False
    np.testing.assert_array_equal(clone(observations), expected)
    assert len(pickle.dumps(population)) < 4 * spec.n_params * 4 + 2000


# -- weights shared across the four directions ------------------------------------


def turned(robot: str, observations: np.ndarray, turns: int) -> np.ndarray:
    """The observations of the cell turned ``turns`` quarter-turns clockwise (side ``turns`` east).

    Written out plainly: the 4 walls and 4 signs of DD robots are rolled, images
    are turned with ``np.rot90`` (row 0 is north, the last column east).
    """
    if robot == "DD":
        walls, signs = observations[:, :4], observations[:, 4:]
        return np.concatenate([np.roll(walls, -turns, 1), np.roll(signs, -turns, 1)], axis=1)
    return np.ascontiguousarray(np.rot90(observations, -turns, axes=(2, 3)))


@pytest.mark.parametrize(("robot", "hidden"), [("DD", (16,)), ("DD", ()), ("CD15", (6, 5))])
@pytest.mark.parametrize(("p_count", "m"), [(3, 70), (66, 3)])
def test_rotations_score_each_direction_with_one_network(robot, hidden, p_count, m):
    # the logit of direction d is the one-output network on the cell turned so that d is east
    rng = np.random.default_rng(len(hidden) + p_count)
    spec = NetworkSpec(robot, hidden, symmetry="rotations")
    assert spec.layer_sizes == (NetworkSpec(robot).n_inputs, *hidden, 1) and spec.n_outputs == 4
    params = spec.initial_params(rng, p_count) + rng.normal(0, 0.3, (p_count, spec.n_params))
    observations = random_observations(robot, p_count * m, rng)
    expected = np.concatenate(
        [reference_outputs(spec, params, turned(robot, observations, d), 1) for d in range(4)],
        axis=1,
    )
    for parallel in (False, True):
        population = spec.population(params, parallel=parallel)
        logits = population.forward(observations)
        assert logits.shape == (p_count * m, 4) and logits.dtype == np.float32
        np.testing.assert_allclose(logits, expected, rtol=1e-4, atol=1e-4)
        ranked = np.sort(expected, axis=1)
        clear = ranked[:, -1] - ranked[:, -2] > 1e-3
        assert clear.mean() > 0.9
        np.testing.assert_array_equal(
            population(observations)[clear], expected.argmax(axis=1)[clear]
        )


@pytest.mark.parametrize("robot", ["DD", "CD15", "CD11"])
def test_rotations_make_the_policy_equivariant(robot):
    # turn the cell a quarter-turn counterclockwise (what lay east now lies north):
    # the action turns with it, for every input and every individual
    rng = np.random.default_rng(21)
    spec = NetworkSpec(robot, (8,), symmetry="rotations")
    population = spec.population(spec.initial_params(rng, 4) * 2)
    observations = random_observations(robot, 4 * 50, rng)
    actions = population(observations)
    assert len(np.unique(actions)) == 4
    for turns in (1, 2, 3):
        np.testing.assert_array_equal(
            population(turned(robot, observations, -turns)), (actions + turns) % 4
        )
    # the plain network has no such property
    plain = NetworkSpec(robot, (8,)).population(NetworkSpec(robot, (8,)).initial_params(rng, 4))
    moved = plain(turned(robot, observations, -1))
    assert (moved != (plain(observations) + 1) % 4).any()


def test_rotations_retire_agents_and_keep_individuals_alike():
    rng = np.random.default_rng(8)
    spec = NetworkSpec("DD", (8,), symmetry="rotations")
    params = spec.initial_params(rng, 3) * 3
    population = spec.population(params)
    observations = random_observations("DD", 30, rng)
    full = population(observations)
    population.reset(30)
    population.retire(np.array([0, 11, 29]))
    partial = population(observations)
    keep = np.setdiff1d(np.arange(30), [0, 11, 29])
    np.testing.assert_array_equal(partial[keep], full[keep])
    np.testing.assert_array_equal(partial[[0, 11, 29]], 0)
    for p in range(3):
        rows = slice(10 * p, 10 * p + 10)
        np.testing.assert_array_equal(population.individual(p)(observations[rows]), full[rows])


@pytest.mark.parametrize(
    ("spec", "n_params"),
    [
        (NetworkSpec("DD", symmetry="rotations"), 9),
        (NetworkSpec("DD", (16,), symmetry="rotations"), 161),
        (NetworkSpec("H15", symmetry="rotations"), 26),
        (NetworkSpec("H15", (16,), symmetry="rotations"), 433),
        (NetworkSpec("CC15", (16,), symmetry="rotations"), 433),
    ],
)
def test_rotations_parameter_counts(spec, n_params):
    assert spec.n_params == n_params and spec.copies == 4
    data = json.loads(json.dumps(spec.to_dict()))
    assert data["symmetry"] == "rotations" and NetworkSpec.from_dict(data) == spec


def test_symmetry_is_checked_and_older_specs_have_none():
    with pytest.raises(EvolutionConfigError, match="'mirror' is not one of none, rotations"):
        NetworkSpec("DD", symmetry="mirror")
    assert NetworkSpec.from_dict({"robot": "DD", "hidden": [4]}).symmetry == "none"


@pytest.mark.parametrize("robot", ["CC15", "CC7"])
def test_rotations_turn_the_accelerations_with_the_maze(robot):
    # continuous robots: the four directions' scores give (tanh(s_E - s_W), tanh(s_N - s_S));
    # turning the image a quarter-turn counterclockwise turns (ax, ay) into (-ay, ax)
    rng = np.random.default_rng(5)
    spec = NetworkSpec(robot, (8,), symmetry="rotations")
    assert spec.n_params == NetworkSpec("CD" + robot[2:], (8,), symmetry="rotations").n_params
    params = spec.initial_params(rng, 3) * 2
    population = spec.population(params)
    observations = random_observations(robot, 3 * 40, rng)
    accelerations = population(observations)
    assert accelerations.shape == (120, 2) and accelerations.dtype == np.float64
    scores = population.forward(observations).astype(np.float64)
    np.testing.assert_allclose(
        accelerations,
        np.tanh(np.stack([scores[:, 0] - scores[:, 2], scores[:, 1] - scores[:, 3]], 1)),
        atol=1e-6,
    )
    assert np.abs(accelerations).max() > 0.3  # not all near zero
    ax, ay = accelerations.T
    for turns, expected in [(1, (-ay, ax)), (2, (-ax, -ay)), (3, (ay, -ax))]:
        moved = population(turned(robot, observations, -turns))
        np.testing.assert_array_equal(moved, np.stack(expected, axis=1))
    for p in range(3):  # an individual alone accelerates as in the population, bit for bit
        rows = slice(40 * p, 40 * p + 40)
        alone = population.individual(p)(observations[rows])
        np.testing.assert_array_equal(alone, accelerations[rows])
