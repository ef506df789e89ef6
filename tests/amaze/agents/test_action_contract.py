"""The action contract of the Simulation and the batch engine (reference-behaviour §4.3, §4.4).

Finite accelerations outside [-1, 1] are clipped, NaN and infinities raise
``ActionError`` naming the agent and the value, wrong shapes and types raise
the same error; the compiled kernels never index outside their arrays, even
when given what the Python checks refuse. The crashes these tests protect
against were segmentation faults, which would kill the test process: the exact
reproductions run in a child process.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import amaze
from amaze.agents import engine as engine_module
from amaze.agents.engine import BatchEngine
from amaze.agents.simulation import Simulation
from amaze.errors import ActionError, AmazeError

MAZE = "M4_5x5_C1"
#: The root of the package under test, for child processes.
ROOT = Path(amaze.__file__).resolve().parents[1]

#: Any float, the extremes and subnormals included.
ANY_FLOAT = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True, allow_subnormal=True),
    st.sampled_from([1e308, -1e308, 5e-324, -5e-324, 1.0 + 2**-52, -1.0 - 2**-52, 0.0, -0.0]),
)


def run_child(code: str) -> subprocess.CompletedProcess:
    """Run ``code`` in a fresh interpreter on the package under test."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)],
        capture_output=True,
        text=True,
        env=env,
        cwd=ROOT,
        timeout=600,
    )


def inside(positions: np.ndarray, width: int, height: int) -> bool:
    x, y = positions[..., 0], positions[..., 1]
    return bool(np.all((x > 0) & (x < width) & (y > 0) & (y < height)))


# -- the reported crashes, in child processes -------------------------------------------


def test_infinite_continuous_action_is_refused_not_a_crash() -> None:
    result = run_child(
        """
        import numpy as np
        from amaze.agents.engine import BatchEngine
        from amaze.errors import ActionError
        engine = BatchEngine(['M4_5x5_C1'], 'CC15', 1)
        try:
            engine.step(np.array([[np.inf, 0.0]]))
        except ActionError as error:
            print('refused:', error)
        """
    )
    assert result.returncode >= 0, f"killed by signal {-result.returncode}"
    assert result.returncode == 0, result.stderr
    assert "refused:" in result.stdout and "agents [0]" in result.stdout
    assert "inf" in result.stdout


def test_huge_continuous_actions_in_the_vector_env_are_clipped_not_a_crash() -> None:
    result = run_child(
        """
        import gymnasium, numpy as np
        import amaze
        env = gymnasium.make_vec(
            "AMaze-v0", num_envs=4, vectorization_mode="vector_entry_point",
            maze="M4_5x5_C1", robot="CC15",
        )
        env.reset(seed=0)
        for _ in range(30):
            env.step(np.full((4, 2), 1e6))
        x, y = env.unwrapped.engine.positions.T
        assert ((0 < x) & (x < 5) & (0 < y) & (y < 5)).all(), (x, y)
        print("ok")
        """
    )
    assert result.returncode >= 0, f"killed by signal {-result.returncode}"
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "ok"


# -- clipping ---------------------------------------------------------------------------


@pytest.mark.parametrize("scale", [1.0 + 2**-52, 2.0, 1e6, 1e308])
def test_out_of_range_accelerations_are_clipped_like_the_box_edge(scale: float) -> None:
    """Any finite value is a legal action, the same as its clipped value, in both."""
    rng = np.random.default_rng(1)
    directions = rng.choice([-1.0, 1.0], size=(120, 2)) * rng.integers(0, 2, size=(120, 2))
    big = BatchEngine([MAZE], "CC11", 1, deadline_factor=10)
    edge = BatchEngine([MAZE], "CC11", 1, deadline_factor=10)
    simulation = Simulation(MAZE, "CC11", deadline_factor=10, record_trajectory=True)
    for t, direction in enumerate(directions):
        a, b = big.step(direction[None] * scale), edge.step(direction[None])
        np.testing.assert_array_equal(a.observations, b.observations)
        np.testing.assert_array_equal(a.rewards, b.rewards)
        reward = simulation.step(direction * scale)
        assert reward == pytest.approx(a.rewards[0], abs=1e-12), t
        np.testing.assert_allclose(big.positions[0], simulation.position, rtol=0, atol=1e-12)
        assert simulation.trajectory.actions[-1] == tuple(direction)  # the action applied
    assert inside(big.positions, 5, 5)


def test_full_speed_against_the_border_stays_in_the_maze() -> None:
    """A robot held at full speed against the north border lands on it (0.1 * v rounds).

    The reference (and this Simulation before) then indexed row ``h`` of the
    walls: ``IndexError``; the engine read outside its tables.
    """
    simulation = Simulation("M0_3x3_U", "CC5", deadline_factor=1000)
    engine = BatchEngine(["M0_3x3_U"], "CC5", 1, deadline_factor=1000, auto_reset=False)
    for t in range(800):
        reward = simulation.step((0.0, 1.0))
        result = engine.step(np.array([[0.0, 1.0]]))
        assert result.rewards[0] == pytest.approx(reward, abs=1e-12), t
        np.testing.assert_allclose(engine.positions[0], simulation.position, rtol=0, atol=1e-12)
        assert 0 < simulation.position[1] < 3, t
    assert simulation.position[1] == pytest.approx(2.9)
    assert simulation.velocity[1] > 0.99  # full speed, pressed against the border


# -- refusals ---------------------------------------------------------------------------


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_accelerations_are_refused_naming_agent_and_value(bad: float) -> None:
    engine = BatchEngine([MAZE], "CC11", 3)
    before = engine.positions, engine.timesteps
    actions = np.zeros((3, 2))
    actions[2, 1] = bad
    with pytest.raises(ActionError, match=rf"agents \[2\] got \[\[0\.0, {bad}\]\]"):
        engine.step(actions)
    np.testing.assert_array_equal(engine.positions, before[0])  # nothing moved
    np.testing.assert_array_equal(engine.timesteps, before[1])
    simulation = Simulation(MAZE, "CC11")
    with pytest.raises(ActionError, match=rf"\(0\.0, {bad}\) is not finite"):
        simulation.step((0.0, bad))
    assert simulation.timestep == 0 and simulation.position == (0.5, 0.5)


@pytest.mark.parametrize(
    "actions",
    [
        np.zeros(3),
        np.zeros((3, 3)),
        np.zeros((2, 2)),
        np.full((3, 2), "x"),
        np.zeros((3, 2), dtype=bool),
        np.zeros((3, 2), dtype=complex),
        [[0.0, 1.0], [0.0], [1.0, 1.0]],
        None,
    ],
)
def test_malformed_continuous_actions_raise_action_error(actions: object) -> None:
    engine = BatchEngine([MAZE], "CC11", 3)
    with pytest.raises(ActionError, match="continuous actions must be 3 accelerations"):
        engine.step(actions)


@pytest.mark.parametrize("action", [(0.5,), ((0.5, 0.5),), "xy", (True, False), (1j, 0), None])
def test_malformed_continuous_action_of_a_simulation_raises_action_error(action: object) -> None:
    with pytest.raises(ActionError, match="is not an acceleration"):
        Simulation(MAZE, "CC11").step(action)


def test_bad_discrete_actions_raise_action_error_in_both() -> None:
    """Discrete behaviour is unchanged (0..3 only), under the same error class."""
    engine = BatchEngine([MAZE], "H5", 2)
    for actions, named in [
        (np.array([0, 4]), r"agents \[1\] got \[4\]"),
        (np.array([0.0, 1.0]), "integers"),
        (np.array([[0, 1]]), "integers"),
    ]:
        with pytest.raises(ActionError, match=named):
            engine.step(actions)
    for action in (4, -1, 1.0, True, None):
        with pytest.raises(ActionError, match="discrete action"):
            Simulation(MAZE, "H5").step(action)
    assert issubclass(ActionError, AmazeError) and issubclass(ActionError, ValueError)


# -- the compiled kernels, whatever reaches them ----------------------------------------


def test_kernels_stay_in_bounds_when_the_checks_are_bypassed() -> None:
    """Defence in depth: the kernels clip, zero non-finite values and clamp cell indices."""
    engine = BatchEngine([MAZE, "M2_3x3_U"], "CC7", 2, deadline_factor=1000)
    ist, fst, mint, mflt = engine._ist, engine._fst, engine._mint, engine._mflt
    walls = engine.tables.walls
    rewards, term, trunc = np.zeros(2), np.zeros(2, bool), np.zeros(2, bool)
    for value in (1e308, -1e308, math.inf, -math.inf, math.nan, 5e-324):
        for _ in range(40):
            for k in range(2):
                engine_module._continuous_step(
                    k, value, -value, ist, fst, mint, mflt, walls, rewards, term, trunc
                )
        assert np.isfinite(fst).all()
        assert inside(engine.positions[:1], 5, 5) and inside(engine.positions[1:], 3, 3)
    # positions corrupted behind the engine's back: observing and stepping stay in bounds
    for x, y in [(math.nan, math.nan), (-1e9, 1e9), (1e300, -1e300), (5.0, 5.0), (-0.5, 2.5)]:
        fst[:, 0], fst[:, 1] = x, y
        observations = engine.observe()
        assert observations.shape == (2, 7, 7)
        engine.step(np.zeros((2, 2)))
    engine.reset()
    assert engine.step(np.zeros((2, 2))).rewards.tolist() == [-0.1, -0.1]


# -- property: any float either steps or raises the documented error ---------------------


@settings(
    max_examples=60,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
@given(actions=st.lists(st.tuples(ANY_FLOAT, ANY_FLOAT), min_size=1, max_size=12))
@pytest.mark.parametrize("robot", ["CC5", "CC7"])
def test_any_float_acceleration_steps_or_is_refused(
    robot: str, actions: list[tuple[float, float]]
) -> None:
    engine = BatchEngine(["M1_3x3_C1", "M2_4x3_U"], robot, 2, deadline_factor=2)
    simulations = [Simulation(maze, robot, deadline_factor=2) for maze in engine.mazes]
    for ax, ay in actions:
        batch = np.array([[ax, ay], [ay, ax]])
        if not np.isfinite(batch).all():
            with pytest.raises(ActionError, match="must be finite"):
                engine.step(batch)
            with pytest.raises(ActionError, match="is not finite"):
                simulations[0].step((ax, ay))
            continue
        result = engine.step(batch)
        for k, simulation in enumerate(simulations):
            reward = simulation.step(batch[k])
            assert result.rewards[k] == pytest.approx(reward, abs=1e-12)
            if simulation.done():
                simulation.reset()
            else:
                np.testing.assert_allclose(
                    engine.positions[k], simulation.position, rtol=0, atol=1e-12
                )
        assert np.isfinite(result.rewards).all()
        assert inside(engine.positions[:1], 3, 3) and inside(engine.positions[1:], 4, 3)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    floats=st.lists(ANY_FLOAT, min_size=2, max_size=2),
    integers=st.lists(st.integers(-(2**63), 2**63 - 1), min_size=2, max_size=2),
)
def test_hybrid_robots_refuse_any_float_and_any_integer_outside_0_to_3(
    floats: list[float], integers: list[int]
) -> None:
    engine = BatchEngine(["M1_3x3_C1"], "H5", 2, deadline_factor=2)
    simulation = Simulation("M1_3x3_C1", "H5", deadline_factor=2)
    with pytest.raises(ActionError, match="integers"):
        engine.step(np.array(floats))
    for value in floats:
        with pytest.raises(ActionError, match="discrete action"):
            simulation.step(value)
    actions = np.array(integers, dtype=np.int64)
    if ((actions >= 0) & (actions <= 3)).all():
        assert engine.step(actions).observations.shape == (2, 5, 5)
    else:
        with pytest.raises(ActionError, match=r"0\.\.3"):
            engine.step(actions)
