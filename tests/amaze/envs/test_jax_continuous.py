"""The continuous JAX environment plays the batch engine's episodes (float64: bit for bit).

Robots in mazes of several classes and sizes (padded into one batch), in their
rotations, are driven by a mix of the oracle (``OracleController``, which
reaches goals) and seeded random accelerations held for a few steps (which
run into walls and corners, go back and run out of time), some beyond [-1, 1]
(clipped). The engine's actions are recorded and replayed in JAX with one
``lax.scan``. In float64 every step must be the engine's exactly: position,
velocity, reward, ``terminated``, ``truncated`` and the window; at every
episode end the counters exactly and the scores to rounding. In float32 the
same actions give the same steps until rounding parts them.
"""

from __future__ import annotations

import os
import platform
import subprocess
import sys
from functools import partial
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from amaze.agents.engine import BatchEngine
from amaze.envs.jax.continuous import (
    ContinuousParams,
    JaxContinuousEnv,
    compile_continuous_params,
    make_continuous,
)
from amaze.errors import OptionError
from amaze.evaluation.controllers import OracleController
from amaze.maze.maze import as_mazes

MAZES = [
    "M1_4x4_U",
    "M3_6x6_C1_l.25_L.25_t.5_T.5",
    "M2_5x7_U_l.3_L.2",
    "M5_7x5_C1_l.5_L.25",
    "M7_8x8_C1_t.5_T.5_R",
    "M11_3x3_U",
]
ROBOT = "CC7"
N_AGENTS = 4 * len(MAZES)
STEPS = 900


def engine_run(seed: int = 0) -> dict[str, np.ndarray]:
    """The engine's run: actions, and after each step states, rewards, flags and windows."""
    engine = BatchEngine(MAZES, ROBOT, N_AGENTS, deadline_factor=1.5)
    oracle = OracleController(ROBOT, gain=2, damping=0)
    oracle.bind(engine)
    rng = np.random.default_rng(seed)
    share = np.linspace(0.0, 1.0, N_AGENTS)  # pure random to pure oracle
    held = rng.uniform(-1.5, 1.5, (N_AGENTS, 2))
    observations = engine.reset()
    record: dict[str, list] = {key: [] for key in ("actions", "x", "v", "reward", "term",
                                                   "trunc", "obs", "ended")}  # fmt: skip
    first = observations.copy()
    for t in range(STEPS):
        if t % 7 == 0:
            held = rng.uniform(-1.5, 1.5, (N_AGENTS, 2))
        guided = rng.random(N_AGENTS) < share
        actions = np.where(guided[:, None], oracle(observations), held)
        result = engine.step(actions)
        observations = result.observations
        record["actions"].append(actions)
        record["x"].append(engine.positions.copy())
        record["v"].append(engine.velocities.copy())
        record["reward"].append(result.rewards)
        record["term"].append(result.terminated)
        record["trunc"].append(result.truncated)
        record["obs"].append(observations.copy())
        record["ended"].append((result.episodes, result.final_observations.copy()))
    stacked = {key: value if key == "ended" else np.stack(value) for key, value in record.items()}
    return {**stacked, "first": first}


@partial(jax.jit, static_argnums=0)
def jax_run(env: JaxContinuousEnv, params: ContinuousParams, actions: jax.Array) -> tuple:
    """The same actions in JAX: one scan of ``vmap(env.step)``."""
    obs, state = jax.vmap(env.reset, in_axes=(None, 0))(jax.random.key(0), params)
    step = jax.vmap(env.step, in_axes=(None, 0, 0, 0))

    def body(state, action):
        obs, state, reward, term, trunc, info = step(jax.random.key(0), state, action, params)
        return state, (obs, state, reward, term, trunc, info)

    return obs, jax.lax.scan(body, state, actions)[1]


def compare_float64() -> None:
    """Every step of the float64 environment is the engine's, bit for bit.

    Run in a process of its own (:func:`test_float64_steps_are_the_engines_bit_for_bit`):
    it needs JAX's 64-bit mode and XLA's CPU code without fused multiply-adds.
    """
    ran = engine_run()
    env, params = make_continuous(MAZES, ROBOT, num_envs=N_AGENTS, deadline_factor=1.5,
                                  dtype=jnp.float64)  # fmt: skip
    first, (obs, state, reward, term, trunc, info) = jax_run(
        env, params, jnp.asarray(ran["actions"])
    )
    np.testing.assert_array_equal(np.asarray(first)[:, 0], ran["first"])
    # every step: the same floats, the same windows
    np.testing.assert_array_equal(np.stack([state.x, state.y], -1), ran["x"])
    np.testing.assert_array_equal(np.stack([state.vx, state.vy], -1), ran["v"])
    np.testing.assert_array_equal(np.asarray(reward), ran["reward"])
    np.testing.assert_array_equal(np.asarray(term), ran["term"])
    np.testing.assert_array_equal(np.asarray(trunc), ran["trunc"])
    np.testing.assert_array_equal(np.asarray(obs)[:, :, 0], ran["obs"])
    # the runs did what they are meant to exercise
    assert ran["term"].sum() >= N_AGENTS // 2 and ran["trunc"].sum() >= N_AGENTS // 2
    assert (np.asarray(reward) < -0.25).any()  # a collision, or a step back (-0.1 - 0.1 - ...)
    # every episode end: counters exactly, scores to rounding
    ends = 0
    for t, (episodes, final_observations) in enumerate(ran["ended"]):
        for k, agent in enumerate(episodes.agents):
            assert info["success"][t, agent] == episodes.success[k]
            for name in ("steps", "collisions", "backsteps"):
                assert int(info[name][t, agent]) == int(getattr(episodes, name)[k]), name
            np.testing.assert_allclose(
                info["cumulative_reward"][t, agent], episodes.cumulative_reward[k], atol=1e-9
            )
            assert info["normalized_reward"][t, agent] == episodes.normalized_rewards()[k]
            np.testing.assert_allclose(
                info["pretty_reward"][t, agent], episodes.pretty_rewards()[k], atol=1.001e-3
            )
            np.testing.assert_array_equal(
                info["final_observation"][t, agent, 0], final_observations[k]
            )
            ends += 1
    assert ends == int(ran["term"].sum() + (ran["trunc"] & ~ran["term"]).sum())
    assert info["collisions"].max() > 0 and info["backsteps"].max() > 0


@pytest.mark.skipif(
    platform.machine().lower() not in ("x86_64", "amd64"),
    reason="XLA's --xla_cpu_max_isa=AVX (no fused multiply-add) is an x86 setting",
)
def test_float64_steps_are_the_engines_bit_for_bit() -> None:
    """XLA fuses ``a * b + c * d`` into a fused multiply-add (one rounding, the engine's
    numba code two); without FMA instructions, float64 steps must be the engine's exactly."""
    env = {**os.environ, "JAX_ENABLE_X64": "1", "XLA_FLAGS": "--xla_cpu_max_isa=AVX"}
    code = "from tests.amaze.envs.test_jax_continuous import compare_float64; compare_float64()"
    root = Path(__file__).resolve().parents[3]
    done = subprocess.run(
        [sys.executable, "-c", code], cwd=root, env=env, capture_output=True, text=True,
        check=False,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-4000:]


def test_float32_steps_follow_the_engine_until_rounding_parts_them() -> None:
    ran = engine_run(seed=1)
    env, params = make_continuous(MAZES, ROBOT, num_envs=N_AGENTS, deadline_factor=1.5)
    _, (obs, state, reward, *_) = jax_run(env, params, jnp.asarray(ran["actions"], jnp.float32))
    assert state.x.dtype == jnp.float32 and reward.dtype == jnp.float32
    positions = np.stack([state.x, state.y], -1)
    np.testing.assert_allclose(positions[:20], ran["x"][:20], atol=1e-5)
    np.testing.assert_allclose(np.asarray(reward)[:20], ran["reward"][:20], atol=1e-6)
    same_window = (np.asarray(obs)[:, :, 0] == ran["obs"]).all(axis=(2, 3))
    assert same_window[:20].all() and same_window.mean() > 0.5


def test_params_pad_mazes_and_refuse_what_does_not_fit() -> None:
    params = compile_continuous_params(MAZES[:2], "CC5", max_side=9)
    assert params.canvas.shape == (2, 11 * 5, 11 * 5) and params.walls.shape == (2, 81)
    with pytest.raises(OptionError, match="max_side 5 must hold the largest maze"):
        compile_continuous_params(MAZES, "CC5", max_side=5)
    with pytest.raises(OptionError, match="robot H7"):
        JaxContinuousEnv("H7")
    with pytest.raises(OptionError, match="64-bit mode"):
        JaxContinuousEnv("CC7", jnp.float64)
    with pytest.raises(OptionError, match="dtype"):
        JaxContinuousEnv("CC7", jnp.int32)
    env = JaxContinuousEnv("CC7")
    with pytest.raises(OptionError, match=r"jax\.vmap"):
        env.reset(jax.random.key(0), compile_continuous_params(MAZES[:2], "CC7"))
    for side in (4, 5):  # a CC5 canvas of 7 x 5 = 35 pixels a side is a multiple of 7 too
        one = jax.tree.map(
            lambda a: a[0], compile_continuous_params(MAZES[:1], "CC5", max_side=side)
        )
        with pytest.raises(OptionError, match="not made for robot CC7"):
            env.reset(jax.random.key(0), one)


def test_progress_reward_pays_each_new_share_of_the_solution_once() -> None:
    """With ``progress_reward = k`` the robots move as without it; each episode gains
    ``k`` times its path progress (1 on success) times its maze's finish reward, never
    for going back and forth."""
    ran = engine_run(seed=2)
    actions = jnp.asarray(ran["actions"], jnp.float32)
    paper, params = make_continuous(MAZES, ROBOT, num_envs=N_AGENTS, deadline_factor=1.5)
    k = 0.5
    shaped = JaxContinuousEnv(ROBOT, progress_reward=k)
    assert shaped != paper and hash(shaped) != hash(paper)
    _, (_, state0, reward0, _, _, info0) = jax_run(paper, params, actions)
    _, (_, state, reward, term, trunc, info) = jax_run(shaped, params, actions)
    np.testing.assert_array_equal(np.asarray(state.x), np.asarray(state0.x))
    np.testing.assert_array_equal(info["cumulative_reward"], info0["cumulative_reward"])
    gained = np.asarray(reward, np.float64) - np.asarray(reward0, np.float64)
    assert gained.min() > -1e-6
    done = np.asarray(term | trunc)
    ci, cj, progress = (np.asarray(a) for a in (state.ci, state.cj, info["path_progress"]))
    mazes = as_mazes(MAZES)
    partial_episodes = 0
    for agent in range(N_AGENTS):
        solution = [tuple(cell) for cell in mazes[agent % len(MAZES)].solution]
        share = {cell: i / (len(solution) - 1) for i, cell in enumerate(solution)}
        total, furthest = 0.0, 0.0
        for t in range(STEPS):
            total += gained[t, agent]
            if not done[t, agent]:
                furthest = max(furthest, share.get((int(ci[t, agent]), int(cj[t, agent])), 0.0))
                continue
            finish = float(params.finish[agent])
            np.testing.assert_allclose(total, k * finish * progress[t, agent], rtol=1e-5)
            if term[t, agent]:
                assert progress[t, agent] == 1.0
            else:  # the last step may have reached one more cell of the solution
                step = 1 / (len(solution) - 1)
                assert furthest - 1e-6 <= progress[t, agent] <= furthest + step + 1e-6
                partial_episodes += 0 < progress[t, agent] < 1
            total, furthest = 0.0, 0.0
    assert np.asarray(term).sum() >= N_AGENTS // 2 and partial_episodes >= 4
    with pytest.raises(OptionError, match="progress_reward -1"):
        JaxContinuousEnv(ROBOT, progress_reward=-1)
