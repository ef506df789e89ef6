"""The JAX environment's interface: make, padding, recompilation, auto-reset, errors, imports.

Episodes themselves are compared with the batch engine's in
``test_jax_vs_engine.py``; here, what users and JAX code rely on around them.
"""

from __future__ import annotations

import importlib
import re
import subprocess
import sys
from functools import partial
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from amaze.agents.engine import BatchEngine
from amaze.agents.robot import RobotStringError
from amaze.envs.jax import JaxMazeEnv, make, make_batch, padded_size, stack_params
from amaze.errors import AmazeError, MazeStringError, OptionError
from amaze.evaluation.controllers import goal_directions
from amaze.maze.directions import OFFSETS
from amaze.maze.maze import Maze

MAZES = ["M1_5x5_C1", "M2_12x9_SE_C1_l.25_L.25", "M3_20x20_C1_t.5_T.5", "M4_2x2"]
KEY = jax.random.key(0)


@partial(jax.jit, static_argnums=(0, 3))
def rollout(env: JaxMazeEnv, params, key: jax.Array, steps: int):
    """Random moves in every environment of a params batch: rewards, ends, R̄, observations."""
    n = params.start.shape[0]
    _, state = jax.vmap(env.reset)(jax.random.split(key, n), params)

    def one_step(state, key):
        actions = jax.random.randint(key, (n,), 0, 4)
        obs, state, reward, terminated, truncated, info = jax.vmap(env.step)(
            jax.random.split(key, n), state, actions, params
        )
        return state, (obs, reward, terminated | truncated, info["normalized_reward"])

    return jax.lax.scan(one_step, state, jax.random.split(key, steps))[1]


# -- make ----------------------------------------------------------------------------------


@pytest.mark.parametrize("robot", ["DD", "H5", "H15", "CD11"])
def test_make_gives_the_engines_first_observation(robot):
    env, params = make("M4_10x10_C1", robot)
    obs, state = env.reset(KEY, params)
    assert obs.shape == env.observation_shape and obs.dtype == env.observation_dtype
    engine = BatchEngine(["M4_10x10_C1"], robot, 1)
    expected = engine.reset()[0]
    np.testing.assert_array_equal(np.asarray(obs).reshape(expected.shape), expected)
    assert int(state.time) == 0 and env.cells(state, params).tolist() == [0, 0]
    assert int(params.deadline) == 4 * 29  # l = 29 for M4_10x10_C1


def test_make_batch_assigns_maze_k_modulo_the_number_of_mazes():
    _, params = make_batch(MAZES, "DD", num_envs=10)
    assert params.start.shape == (10,)
    singles = [make(m, "DD")[1] for m in MAZES]
    for k in range(10):
        assert int(params.path_length[k]) == int(singles[k % 4].path_length)
        assert int(params.width[k]) == int(singles[k % 4].width)
    assert padded_size(params) == (400, 64)


def test_stack_params_pads_mazes_of_different_sizes():
    env = JaxMazeEnv("H11")
    singles = [make(m, "H11")[1] for m in MAZES]
    assert len({padded_size(p) for p in singles}) > 1
    stacked = stack_params(singles)
    _, batch = make_batch(MAZES, "H11")
    for a, b in zip(stacked, batch, strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    assert env.observation_shape == (1, 11, 11)


def test_padding_changes_no_episode():
    env, tight = make_batch(MAZES, "DD")
    _, loose = make_batch(MAZES, "DD", max_cells=900, max_codes=256)
    assert padded_size(loose) == (900, 256) and padded_size(tight) != padded_size(loose)
    a = rollout(env, tight, KEY, 300)
    b = rollout(env, loose, KEY, 300)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
    assert np.asarray(a[2]).sum() > 0  # episodes ended


def test_new_mazes_of_the_same_padded_size_do_not_recompile():
    env, first = make_batch(MAZES, "DD", max_cells=400, max_codes=64)
    others = ["M9_20x20_C1_l.25_L.25", "M8_3x17_U", "M7_10x10", "M6_4x4_C1"]
    _, second = make_batch(others, "DD", max_cells=400, max_codes=64)
    run = jax.jit(lambda env, params, key: rollout(env, params, key, 50), static_argnums=0)
    a = run(env, first, KEY)
    b = run(env, second, KEY)
    assert run._cache_size() == 1
    assert not np.array_equal(np.asarray(a[0]), np.asarray(b[0]))
    _, bigger = make_batch(MAZES, "DD", max_cells=401, max_codes=64)
    run(env, bigger, KEY)
    assert run._cache_size() == 2  # another padded size compiles again


def test_shared_params_broadcast_over_environments():
    env, params = make("M2_12x9_SE_C1_l.25_L.25", "DD")
    n = 6
    _, state = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(KEY, n), params)
    actions = jnp.arange(n) % 4
    out = jax.vmap(env.step, in_axes=(0, 0, 0, None))(
        jax.random.split(KEY, n), state, actions, params
    )
    _, batch = make_batch(["M2_12x9_SE_C1_l.25_L.25"], "DD", num_envs=n)
    ref = jax.vmap(env.step)(jax.random.split(KEY, n), state, actions, batch)
    for x, y in zip(jax.tree.leaves(out), jax.tree.leaves(ref), strict=True):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))


# -- steps ----------------------------------------------------------------------------------


def test_auto_reset_returns_the_next_episodes_first_observation():
    maze = Maze.from_string("M5_3x3_U")
    env, params = make(maze, "DD")
    field = goal_directions(maze)
    cell, path = maze.start, []
    while cell != maze.end:
        path.append(int(field[cell]))
        cell = tuple(int(c) for c in np.add(cell, OFFSETS[path[-1]]))
    obs0, state = env.reset(KEY, params)
    for a in path[:-1]:
        obs, state, _, terminated, truncated, _ = env.step(KEY, state, a, params)
        assert not (bool(terminated) or bool(truncated))
    obs, after, reward, terminated, truncated, info = env.step(KEY, state, path[-1], params)
    assert bool(terminated) and not bool(truncated)
    np.testing.assert_array_equal(np.asarray(obs), np.asarray(obs0))  # the next episode's
    assert int(after.time) == 0 and int(after.position) == int(params.start)
    final, ended, *_ = env.step_env(KEY, state, path[-1], params)  # the same step, no restart
    np.testing.assert_array_equal(np.asarray(info["final_observation"]), np.asarray(final))
    assert not np.array_equal(np.asarray(final), np.asarray(obs0))
    assert env.cells(ended, params).tolist() == list(maze.end)
    length = maze.path_length
    assert float(reward) == 2 * length - 2  # -1 + (2l - 1)
    assert float(info["cumulative_reward"]) == length  # the optimal return
    assert float(info["normalized_reward"]) == 1.0 and float(info["pretty_reward"]) == 1.0
    assert int(info["steps"]) == length - 1 and bool(info["success"])


def test_actions_are_taken_modulo_4():
    env, params = make("M2_12x9_SE_C1_l.25_L.25", "H5")
    n = 8
    _, state = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(KEY, n), params)
    step = jax.vmap(env.step, in_axes=(0, 0, 0, None))
    low = step(jax.random.split(KEY, n), state, jnp.arange(n) % 4, params)
    high = step(jax.random.split(KEY, n), state, jnp.arange(n) % 4 + 4, params)
    for x, y in zip(jax.tree.leaves(low), jax.tree.leaves(high), strict=True):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))


def test_a_rollout_ends_episodes_and_scores_them():
    env, params = make_batch(MAZES, "DD", num_envs=64)
    obs, reward, done, rbar = (np.asarray(x) for x in rollout(env, params, KEY, 400))
    assert obs.shape == (400, 64, 8) and reward.dtype == np.float32
    assert done.sum() > 64 and np.all(rbar[done] <= 1.0)
    assert set(np.unique(reward[~done]).tolist()) <= {-1.0, np.float32(-1.1), np.float32(-1.2)}


# -- bad input --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("call", "error", "named"),
    [
        (lambda: make("M4_10x10x", "DD"), MazeStringError, "10x10x"),
        (lambda: make("M4_10x10_C1", "X5"), RobotStringError, "X5"),
        (lambda: make("M4_10x10_C1", "CC15"), OptionError, "CC15"),
        (lambda: make("M4_10x10_C1", "C11"), OptionError, "C11"),
        (lambda: JaxMazeEnv("CC11"), OptionError, "CC11"),
        (lambda: make("M4_10x10_C1", "DD", deadline_factor=0), OptionError, "deadline_factor"),
        (lambda: make(["M4_10x10_C1"], "DD"), OptionError, "make_batch"),
        (lambda: make_batch([], "DD"), OptionError, "at least one maze"),
        (lambda: make_batch(MAZES, "DD", num_envs=0), OptionError, "num_envs"),
        (lambda: make_batch(MAZES, "DD", max_cells=100), OptionError, "max_cells 100"),
        (lambda: make_batch(MAZES, "DD", max_codes=3), OptionError, "max_codes 3"),
        (lambda: stack_params([]), OptionError, "at least one"),
        (
            lambda: stack_params([make("M1_5x5", "DD")[1], make("M1_5x5", "H5")[1]]),
            OptionError,
            "different robots",
        ),
    ],
)
def test_bad_input_raises_the_projects_errors(call, error, named):
    with pytest.raises(error, match=named) as caught:
        call()
    assert isinstance(caught.value, AmazeError)


def test_params_of_another_robot_are_refused():
    env = JaxMazeEnv("H11")
    _, params = make("M1_5x5", "H15")
    with pytest.raises(OptionError, match="robot CD11"):
        env.reset(KEY, params)


def test_a_batch_of_params_without_vmap_is_refused():
    env, params = make_batch(MAZES, "DD")
    with pytest.raises(OptionError, match=r"params of 4 mazes.*jax\.vmap"):
        env.reset(KEY, params)
    _, state = jax.vmap(env.reset)(jax.random.split(KEY, 4), params)
    with pytest.raises(OptionError, match="params of 4 mazes"):
        env.step(KEY, state, jnp.zeros(4, jnp.int32), params)


# -- imports --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "modules",
    [
        "amaze",
        "amaze, amaze.envs.vector_env, amaze.envs.gym_env",
        "amaze.agents.engine, amaze.evaluation.controllers, amaze.cli.main",
    ],
)
def test_importing_amaze_loads_no_jax(modules):
    code = (
        f"import sys, {modules}\n"
        "loaded = [m for m in ('jax', 'jaxlib', 'gymnax', 'jaxued', 'flax') if m in sys.modules]\n"
        "assert not loaded, loaded\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_the_check_of_imports_sees_jax():
    """The subprocess check above can fail: importing the JAX env does load JAX."""
    code = "import sys, amaze.envs.jax\nassert 'jax' in sys.modules\n"
    subprocess.run([sys.executable, "-c", code], check=True)


# -- documentation --------------------------------------------------------------------------


def test_spaces_without_gymnax():
    env, params = make("M4_10x10_C1", "H5")
    obs, _ = env.reset(KEY, params)
    space = env.observation_space(params)
    assert space.shape == (1, 5, 5) and bool(space.contains(obs))
    assert space.sample(KEY).shape == (1, 5, 5) and space.sample(KEY).dtype == jnp.uint8
    actions = env.action_space(params)
    assert actions.n == 4 and bool(actions.contains(actions.sample(KEY)))
    assert not bool(actions.contains(jnp.int32(4)))
    assert JaxMazeEnv("DD").observation_space().shape == (8,)


@pytest.mark.parametrize("module", ["amaze.envs.jax", "amaze.envs.jax.env"])
def test_the_old_name_maze_env_warns_and_gives_jax_maze_env(module: str) -> None:
    """``MazeEnv``, the JAX env's name until ``JaxMazeEnv``, for one more release."""
    imported = importlib.import_module(module)
    with pytest.warns(DeprecationWarning, match=rf"{re.escape(module)}\.MazeEnv is renamed"):
        old = imported.MazeEnv
    assert old is JaxMazeEnv
    with pytest.warns(DeprecationWarning, match="JaxMazeEnv"):
        exec(f"from {module} import MazeEnv as Old; assert Old is JaxMazeEnv", {"JaxMazeEnv": old})
    assert "MazeEnv" not in getattr(imported, "__all__", ())
    with pytest.raises(AttributeError, match="Nothing"):
        imported.Nothing  # noqa: B018


def test_the_documented_random_rollout_runs(capsys: pytest.CaptureFixture[str]) -> None:
    """The PureJaxRL-style rollout of ``docs/jax.md`` runs as written and ends episodes."""
    page = (Path(__file__).resolve().parents[3] / "docs" / "jax.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", page, re.DOTALL)
    rollout = next(block for block in blocks if "jax.lax.scan" in block)
    exec(compile(rollout, "docs/jax.md", "exec"), {})
    printed = capsys.readouterr().out
    ended = int(re.match(r"(\d+) episodes ended in 500 steps of 1024 environments", printed)[1])
    assert ended > 1024  # every environment ends at least one episode (5x5 mazes end fast)
