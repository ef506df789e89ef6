"""The gymnax and jaxued adapters: gymnax's wrappers and jaxued's level sampler run on AMaze."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from gymnax.environments.environment import Environment
from gymnax.wrappers.purerl import FlattenObservationWrapper, LogWrapper

from amaze.envs.jax import GymnaxMazeEnv, JaxMazeEnv, UEDMazeEnv, make_batch
from amaze.envs.jax.gymnax_env import make_gymnax

MAZES = ["M1_5x5_C1", "M2_12x9_SE_C1_l.25_L.25", "M3_7x3_U", "M4_4x4_C1_t.5_T.5"]
KEY = jax.random.key(0)


# -- gymnax ----------------------------------------------------------------------------------


@pytest.mark.parametrize("robot", ["DD", "H11"])
def test_gymnax_wrappers_run_in_a_jitted_scan(robot):
    """LogWrapper(FlattenObservationWrapper(env)), 256 envs, 400 steps in one compiled scan.

    The wrapper's returns (float32 sums of the rewards) match the environment's
    own episode returns, and its lengths the episodes' steps.
    """
    env, _ = make_gymnax(MAZES[0], robot)
    wrapped = LogWrapper(FlattenObservationWrapper(env))
    n = 256
    _, params = make_batch(MAZES, robot, num_envs=n)

    @jax.jit
    def run(key):
        obs, state = jax.vmap(wrapped.reset)(jax.random.split(key, n), params)

        def one_step(state, key):
            actions = jax.random.randint(key, (n,), 0, env.num_actions)
            obs, state, _, _, _, info = jax.vmap(wrapped.step)(
                jax.random.split(key, n), state, actions, params
            )
            return state, (obs, info)

        return obs, jax.lax.scan(one_step, state, jax.random.split(key, 400))[1]

    first, (obs, info) = run(KEY)
    size = int(np.prod(env.observation_space(params).shape))
    assert first.shape == (n, size) and obs.shape == (400, n, size)
    ended = np.asarray(info["returned_episode"])
    assert ended.sum() > n
    returns = np.asarray(info["returned_episode_returns"])[ended]
    np.testing.assert_allclose(returns, np.asarray(info["cumulative_reward"])[ended], atol=2e-3)
    lengths = np.asarray(info["returned_episode_lengths"])[ended]
    np.testing.assert_array_equal(lengths, np.asarray(info["steps"])[ended])
    assert np.asarray(info["final_observation"]).shape == (400, n, size)


def test_gymnax_base_step_and_the_fused_step_agree():
    """gymnax's own ``Environment.step`` (on our hooks) gives what the override gives."""
    env = GymnaxMazeEnv("H5", MAZES[1])
    params = env.default_params
    _, state = env.reset(KEY, params)
    rng = np.random.default_rng(0)
    ends = 0
    for t in range(250):
        action = int(rng.integers(4))
        key = jax.random.key(t)
        ours = env.step(key, state, action, params)
        base = Environment.step(env, key, state, action, params)
        assert jax.tree.structure(ours) == jax.tree.structure(base)
        for a, b in zip(jax.tree.leaves(ours), jax.tree.leaves(base), strict=True):
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
        state = ours[1]
        ends += bool(ours[3] | ours[4])
    assert ends > 0


def test_gymnax_spaces_and_defaults():
    env = GymnaxMazeEnv("DD")
    assert env.default_params.start.shape == ()  # AMaze-v0's default maze, M0_10x10_C1
    obs, state = env.reset(KEY)
    assert bool(env.observation_space(None).contains(obs))
    action = env.action_space(None).sample(KEY)
    assert bool(env.action_space(None).contains(action)) and env.num_actions == 4
    image = GymnaxMazeEnv("H15").observation_space(None)
    assert image.shape == (1, 15, 15) and image.dtype == jnp.uint8
    assert env.name == "AMaze-DD" and not bool(env.is_terminated(state, env.default_params))


# -- jaxued ----------------------------------------------------------------------------------


@pytest.fixture
def tree_map_alias(monkeypatch):
    """jaxued 0.0.1 calls ``jax.tree_map``, removed in JAX 0.6: give it the old name back."""
    monkeypatch.setattr(jax, "tree_map", jax.tree.map, raising=False)


def test_jaxued_level_sampler_cycles_over_amaze_levels(tree_map_alias):
    """Insert levels, sample replays, roll them out (AutoReplayWrapper), update scores."""
    from jaxued.level_sampler import LevelSampler
    from jaxued.wrappers.autoreplay import AutoReplayWrapper

    strings = [f"M{s}_{4 + s % 6}x{3 + s % 5}_C1_l.25_L.25" for s in range(24)]
    _, levels = make_batch(strings, "DD", max_cells=100, max_codes=64)
    env = AutoReplayWrapper(UEDMazeEnv("DD"))
    plain = JaxMazeEnv("DD")
    sampler = LevelSampler(capacity=8, replay_prob=0.5, minimum_fill_ratio=0.5)
    buffer = sampler.initialize(jax.tree.map(lambda x: x[0], levels), {"max_return": -jnp.inf})
    n, steps = 16, 150

    @jax.jit
    def evaluate(key, batch):
        """Mean R̄ of the ended episodes of each level, and each env's first observation."""
        obs, state = jax.vmap(env.reset_to_level, in_axes=(0, 0, None))(
            jax.random.split(key, n), batch, env.default_params
        )

        def one_step(state, key):
            actions = jax.random.randint(key, (n,), 0, 4)
            _, state, _, done, info = jax.vmap(env.step, in_axes=(0, 0, 0, None))(
                jax.random.split(key, n), state, actions, env.default_params
            )
            position = state.env_state.env_state.position  # after the replay's restart
            return state, (done, info["normalized_reward"], position)

        state, (done, rbar, positions) = jax.lax.scan(one_step, state, jax.random.split(key, steps))
        score = jnp.where(done, rbar, 0).sum(0) / jnp.maximum(done.sum(0), 1)
        return score, obs, done, positions

    key = KEY
    for cycle in range(3):
        key, k_new, k_eval, k_replay = jax.random.split(key, 4)
        new = slice(8 * cycle, 8 * cycle + 8)
        fresh = jax.tree.map(lambda x, new=new: x[new], levels)
        twice = jax.tree.map(lambda x: jnp.concatenate([x, x]), fresh)  # n = 16 envs
        score = evaluate(k_new, twice)[0][:8]
        buffer, _ = sampler.insert_batch(buffer, fresh, score, {"max_return": score})
        assert int(buffer["size"]) == min(8, 8 * (cycle + 1))
        buffer, (indices, replay) = sampler.sample_replay_levels(buffer, k_replay, n)
        assert (np.asarray(indices) < int(buffer["size"])).all()  # stored levels only
        score, obs, done, positions = evaluate(k_eval, replay)
        # each env played the level it was given, and AutoReplay kept it
        expected = jax.vmap(plain.reset, in_axes=(0, 0))(jax.random.split(k_eval, n), replay)[0]
        np.testing.assert_array_equal(np.asarray(obs), np.asarray(expected))
        done, positions = np.asarray(done), np.asarray(positions)
        starts = np.broadcast_to(np.asarray(replay.start), positions.shape)
        np.testing.assert_array_equal(positions[done], starts[done])  # restarted in its level
        assert done.sum() > 0
        buffer = sampler.update_batch(buffer, indices, score, {"max_return": score})
        stored = np.asarray(buffer["scores"])[np.asarray(indices)]
        assert np.isfinite(stored).all()
    weights = np.asarray(sampler.level_weights(buffer))
    assert weights.shape == (8,) and abs(weights.sum() - 1) < 1e-5


def test_a_maze_given_where_the_robot_goes_is_named_with_the_call_meant():
    """``make`` takes ``(maze, robot)``, ``GymnaxMazeEnv`` the robot first: a swap is named."""
    from amaze.envs.jax.gymnax_env import GymnaxMazeEnv
    from amaze.errors import OptionError

    with pytest.raises(OptionError, match=r"did you mean GymnaxMazeEnv\(robot='DD', maze='M1"):
        GymnaxMazeEnv("M1_5x5_U", "DD")
    assert GymnaxMazeEnv(robot="DD", maze="M1_5x5_U").maze_env.robot.to_string() == "DD"
