"""AMaze-v0 and its vector env under an adversarial user: actions and options.

The single environment and the vector one apply the Simulation's and the
engine's action contract (clip finite accelerations, refuse NaN and
infinities, refuse malformed actions: ``ActionError``) and check every option
before anything is generated or allocated (``OptionError`` naming the value).
"""

from __future__ import annotations

import math

import gymnasium
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import amaze  # noqa: F401  (registers AMaze-v0)
from amaze.envs.gym_env import MazeEnv
from amaze.envs.vector_env import MazeVectorEnv
from amaze.errors import ActionError, OptionError

MAZE = "M4_5x5_C1"


def make_vec(num_envs: int = 3, robot: str = "CC11", **kwargs):
    return gymnasium.make_vec(
        "AMaze-v0",
        num_envs=num_envs,
        vectorization_mode="vector_entry_point",
        maze=MAZE,
        robot=robot,
        **kwargs,
    )


# -- continuous actions -------------------------------------------------------------------


@pytest.mark.parametrize("scale", [1e6, 1e308])
def test_single_env_clips_huge_accelerations_like_the_box_edge(scale: float) -> None:
    big = gymnasium.make("AMaze-v0", maze=MAZE, robot="CC11")
    edge = gymnasium.make("AMaze-v0", maze=MAZE, robot="CC11")
    big.reset(seed=0)
    edge.reset(seed=0)
    rng = np.random.default_rng(2)
    for _ in range(150):
        direction = rng.choice([-1.0, 0.0, 1.0], size=2)
        a, b = big.step(direction * scale), edge.step(direction.astype(np.float32))
        np.testing.assert_array_equal(a[0], b[0])
        assert a[1:4] == b[1:4]
        if a[2] or a[3]:
            big.reset()
            edge.reset()
    x, y = big.unwrapped.position
    assert 0 < x < 5 and 0 < y < 5


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_single_env_refuses_non_finite_accelerations(bad: float) -> None:
    env = gymnasium.make("AMaze-v0", maze=MAZE, robot="CC11")
    env.reset(seed=0)
    with pytest.raises(ActionError, match=rf"\({bad}, 0\.0\) is not finite"):
        env.step(np.array([bad, 0.0], dtype=np.float32))
    assert env.unwrapped.simulation.timestep == 0


@pytest.mark.parametrize("action", [np.zeros(1), np.zeros((1, 2)), np.zeros(3), "xy", None])
def test_single_env_refuses_malformed_accelerations(action: object) -> None:
    env = gymnasium.make("AMaze-v0", maze=MAZE, robot="CC11")
    env.reset(seed=0)
    with pytest.raises(ActionError, match="is not an acceleration"):
        env.step(action)


def test_vector_env_clips_huge_and_refuses_non_finite_actions() -> None:
    big, edge = make_vec(), make_vec()
    big.reset(seed=0)
    edge.reset(seed=0)
    for _ in range(60):
        a, b = big.step(np.full((3, 2), 1e6)), edge.step(np.ones((3, 2), dtype=np.float32))
        np.testing.assert_array_equal(a[0], b[0])
        np.testing.assert_array_equal(a[1], b[1])
    actions = np.zeros((3, 2))
    actions[1, 0] = math.nan
    with pytest.raises(ActionError, match=r"agents \[1\] got \[\[nan, 0\.0\]\]"):
        big.step(actions)
    with pytest.raises(ActionError, match="3 accelerations"):
        big.step([[0.0, 0.0], [1.0], [0.0, 1.0]])


@settings(
    max_examples=40,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
@given(
    actions=st.lists(
        st.tuples(
            st.floats(allow_nan=True, allow_infinity=True, allow_subnormal=True),
            st.floats(allow_nan=True, allow_infinity=True, allow_subnormal=True),
        ),
        min_size=1,
        max_size=8,
    )
)
@pytest.mark.parametrize("robot", ["CC5", "CD5"])
def test_single_env_takes_any_float_or_refuses_it_cleanly(
    robot: str, actions: list[tuple[float, float]]
) -> None:
    env = MazeEnv(maze="M1_3x3_C1", robot=robot)
    env.reset(seed=0)
    for ax, ay in actions:
        if robot == "CD5":  # discrete actions: a float is never one
            with pytest.raises(ActionError, match="discrete action"):
                env.step(ax)
            continue
        if not (math.isfinite(ax) and math.isfinite(ay)):
            with pytest.raises(ActionError, match="is not finite"):
                env.step((ax, ay))
            continue
        observation, reward, terminated, truncated, _ = env.step((ax, ay))
        assert env.observation_space.contains(observation) and math.isfinite(reward)
        if terminated or truncated:
            env.reset()


# -- options ------------------------------------------------------------------------------


@pytest.mark.parametrize("factor", [math.inf, math.nan, 0, -1, 0.5, 1001, "4", None, True])
def test_deadline_factor_is_validated_by_both_envs(factor: object) -> None:
    with pytest.raises(OptionError, match="deadline_factor"):
        gymnasium.make("AMaze-v0", maze=MAZE, deadline_factor=factor)
    with pytest.raises(OptionError, match="deadline_factor"):
        make_vec(deadline_factor=factor)


def test_deadline_factor_zero_is_refused_and_one_is_the_smallest() -> None:
    """0 ended every episode before its first step (which then raised); 1 gives l steps."""
    with pytest.raises(OptionError, match=r"deadline_factor 0 is not a number in \[1\.0, 1000"):
        gymnasium.make("AMaze-v0", maze=MAZE, robot="DD", deadline_factor=0)
    env = gymnasium.make("AMaze-v0", maze=MAZE, robot="DD", deadline_factor=1)
    env.reset(seed=0)
    for _ in range(env.unwrapped.maze.path_length - 1):
        assert not any(env.step(0)[2:4])


def test_num_envs_is_bounded_before_allocating() -> None:
    with pytest.raises(OptionError, match=r"num_envs 1000000000000 is too many .* GiB"):
        make_vec(num_envs=10**12)
    for bad in (0, 1.5, "4", True):
        with pytest.raises(OptionError, match="num_envs"):
            make_vec(num_envs=bad)


def test_num_envs_limit_follows_the_engine_memory_estimate() -> None:
    from amaze.agents.engine import MAX_ENGINE_BYTES, agent_bytes, max_agents

    for robot in ("DD", "H15", "CC15", "CC65"):
        limit = max_agents(robot)
        assert limit * agent_bytes(robot) <= MAX_ENGINE_BYTES
        assert (limit + 1) * agent_bytes(robot) > MAX_ENGINE_BYTES
        with pytest.raises(OptionError, match=f"at most {limit:,} agents"):
            MazeVectorEnv(limit + 1, MAZE, robot)
    assert max_agents("DD") > 50_000_000 and max_agents("CC65") > 1_000_000


@pytest.mark.parametrize("options", ["x", 3, ["maze"], ("maze", MAZE)])
def test_reset_options_must_be_a_dict(options: object) -> None:
    env = gymnasium.make("AMaze-v0", maze=MAZE)
    with pytest.raises(OptionError, match="reset options must be a dict"):
        env.reset(options=options)
    with pytest.raises(OptionError, match="reset options must be a dict"):
        make_vec(robot="DD").reset(options=options)


def test_unknown_reset_options_are_named() -> None:
    env = gymnasium.make("AMaze-v0", maze=MAZE)
    with pytest.raises(OptionError, match=r"'mazes'.*accepted: 'maze'"):
        env.reset(options={"mazes": "M1_5x5"})
    env.reset(options={"maze": "M1_5x5"})  # the known one still works
    assert env.unwrapped.maze.to_string() == "M1_5x5"
    with pytest.raises(OptionError, match="'maze'"):
        make_vec(robot="DD").reset(options={"maze": "M1_5x5"})  # fixed mazes: no options
    make_vec(robot="DD").reset(options={})


def test_render_mode_is_validated_by_both_envs() -> None:
    with pytest.raises(OptionError, match="'video'"):
        MazeEnv(maze=MAZE, render_mode="video")
    with pytest.raises(OptionError, match="render_mode 'rgb_array'"):
        make_vec(render_mode="rgb_array")
    assert make_vec(render_mode=None).render_mode is None


def test_vision_is_bounded_before_drawing_images() -> None:
    for robot in ("H10001", "CC67", "CD99"):
        with pytest.raises(ValueError, match=r"vision \d+ must be odd and within \[5, 65\]"):
            gymnasium.make("AMaze-v0", maze=MAZE, robot=robot)
    env = gymnasium.make("AMaze-v0", maze=MAZE, robot="H65")
    assert env.observation_space.shape == (1, 65, 65)
