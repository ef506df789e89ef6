"""The batch engine against the reference's recorded runs, and batch consistency.

Golden data: ``reference_fixtures.json`` (optimal, random and deadline runs in
discrete mode, image runs in hybrid mode, one continuous run) plus, for the
continuous sub-cell window, digests of longer continuous runs recorded with
amaze-benchmarker 1.0 (``CONTINUOUS_DIGESTS``, actions from ``_lcg_actions``).
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
from typing import Any

import numba
import numpy as np
import pytest

from amaze.agents.engine import BatchEngine, EpisodeEndedError
from amaze.agents.kernel_choice import KernelChoice
from amaze.agents.tables import compile_mazes
from amaze.maze.maze import Maze

ACTION_INDEX = {(1, 0): 0, (0, 1): 1, (-1, 0): 2, (0, -1): 3}

SIGNED = "M10_10x10_C1_l.2_L.25_t.5_T.5"
MULTI = "M9_12x7_NE_C1_Cpoint-.5_l.5_L.25_Lwarning-.3_t.5_T.5_Tforbidden-.75"


def _indices(vectors: list[list[float]]) -> np.ndarray:
    return np.array([ACTION_INDEX[(int(a), int(b))] for a, b in vectors], dtype=np.int64)


def _fixture_maze(reference: dict[str, Any], text: str) -> dict[str, Any]:
    return next(m for m in reference["mazes"] if m["input"] == text)


def _step1(engine: BatchEngine, action: Any):
    """Step a one-agent engine."""
    return engine.step(np.array([action]))


# -----------------------------------------------------------------------------
# Discrete robots


def test_optimal_runs_dd(reference: dict[str, Any]) -> None:
    for record in reference["mazes"]:
        run = record["optimal_run_DD"]
        engine = BatchEngine([record["input"]], "DD", 1, auto_reset=False)
        obs = engine.reset()
        assert obs.dtype == np.float32 and obs.shape == (1, 8)
        np.testing.assert_array_equal(obs[0], np.float32(run["observations"][0]))
        actions = _indices(run["actions"])
        for t, action in enumerate(actions):
            assert not engine._ended.any()
            result = _step1(engine, action)
            np.testing.assert_array_equal(
                result.observations[0], np.float32(run["observations"][t + 1]), err_msg=f"t={t}"
            )
            assert result.rewards[0] == run["rewards"][t], (record["input"], t)
        assert result.terminated[0] and not result.truncated[0]
        episodes = result.episodes
        assert episodes.agents.tolist() == [0]
        assert episodes.cumulative_reward[0] == run["cumulative_reward"]
        infos = run["infos"]
        assert episodes.steps[0] == infos["steps"]
        assert episodes.collisions[0] == infos["collisions"]
        assert episodes.backsteps[0] == infos["backsteps"]
        assert episodes.success[0] and episodes.path_length[0] == infos["len"]
        assert episodes.pretty_rewards()[0] == run["normalized_reward"] == 1.0
        assert episodes.normalized_rewards()[0] == pytest.approx(1.0)
        np.testing.assert_array_equal(result.final_observations[0], result.observations[0])


@pytest.mark.parametrize("name", ["M4_10x10_C1", SIGNED])
def test_random_runs_dd(reference: dict[str, Any], name: str) -> None:
    run = reference["random_runs_DD_seed0"][name]
    engine = BatchEngine([name], "DD", 1)
    actions = _indices(run["actions"])
    for t, action in enumerate(actions):
        result = _step1(engine, action)
        assert result.rewards[0] == run["rewards"][t], t
        assert result.truncated[0] == (t == len(actions) - 1)
        assert not result.terminated[0]
    episodes = result.episodes
    infos = run["infos"]
    assert episodes.cumulative_reward[0] == run["cumulative_reward"]
    assert (episodes.steps[0], episodes.collisions[0], episodes.backsteps[0]) == (
        infos["steps"],
        infos["collisions"],
        infos["backsteps"],
    )
    assert not episodes.success[0]
    assert episodes.pretty_rewards()[0] == run["normalized_reward"]
    # auto-reset: the agent is back at the start with a fresh deadline
    assert engine.timesteps[0] == 0
    assert tuple(engine.cells[0]) == Maze.from_string(name).start


def test_deadline_run_and_no_step_after_end(reference: dict[str, Any]) -> None:
    record = reference["deadline_run_M4_10x10_U"]
    maze = Maze.from_string("M4_10x10_U")
    bump = int(np.flatnonzero(maze.walls[maze.start])[0])
    engine = BatchEngine([maze], "DD", 1, auto_reset=False)
    for t in range(int(record["deadline"])):
        result = _step1(engine, bump)
        assert result.rewards[0] == -1.2
        assert result.truncated[0] == (t == record["steps"] - 1)
    assert result.episodes.collisions[0] == record["steps"]
    with pytest.raises(EpisodeEndedError):
        _step1(engine, bump)
    engine.reset(np.array([0]))
    assert _step1(engine, bump).rewards[0] == -1.2


# -----------------------------------------------------------------------------
# Hybrid robots


@pytest.mark.parametrize("robot", ["H15", "H11"])
def test_image_runs_hybrid(reference: dict[str, Any], robot: str) -> None:
    run = reference["image_runs"][f"{SIGNED}|{robot}"]
    engine = BatchEngine([SIGNED], robot, 1, auto_reset=False)
    obs = engine.reset()
    expected = np.array(run["observations_u8"], dtype=np.uint8)
    assert obs.dtype == np.uint8 and obs.shape == (1, *expected.shape[1:])
    np.testing.assert_array_equal(obs[0], expected[0])
    for t, action in enumerate(_indices(run["actions"])):
        result = _step1(engine, action)
        np.testing.assert_array_equal(result.observations[0], expected[t + 1], err_msg=f"t={t}")
        assert result.rewards[0] == run["rewards"][t]
    assert result.terminated[0]
    assert result.episodes.cumulative_reward[0] == run["cumulative_reward"]
    assert result.episodes.pretty_rewards()[0] == run["normalized_reward"]


def test_hybrid_tiles_hold_signs() -> None:
    tables = compile_mazes([SIGNED], "H15")
    maze = Maze.from_string(SIGNED)
    assert tables.tiles.shape == (maze.width * maze.height, 15, 15)
    for placed in maze.signs:
        i, j = placed.cell
        assert tables.tiles[i * maze.height + j, 1:-1, 1:-1].any()


# -----------------------------------------------------------------------------
# Continuous robots


def test_continuous_fixture_run(reference: dict[str, Any]) -> None:
    run = reference["continuous_run_M4_5x5_U_CC"]
    engine = BatchEngine(["M4_5x5_U"], run["robot"], 1, auto_reset=False)
    observations = [engine.reset()[0]]
    np.testing.assert_array_equal(engine.positions[0], run["positions"][0])
    for t, action in enumerate(run["actions"]):
        result = _step1(engine, action)
        observations.append(result.observations[0])
        assert result.rewards[0] == run["rewards"][t], t
        assert tuple(engine.positions[0]) == tuple(run["positions"][t + 1]), t
    # the fixture holds the first observations (the initial one included)
    for t, expected in enumerate(run["observations_u8"]):
        np.testing.assert_array_equal(observations[t], np.array(expected, dtype=np.uint8))
    assert result.terminated[0]
    episodes = result.episodes
    assert episodes.cumulative_reward[0] == run["cumulative_reward"]
    assert episodes.steps[0] == run["infos"]["steps"] == len(run["actions"])
    assert episodes.pretty_rewards()[0] == run["normalized_reward"]


def _lcg_actions(n: int, seed: int) -> np.ndarray:
    """Piecewise-constant accelerations in [-1, 1]^2 (exact decimals), new every 15 steps."""
    s, out = seed, []
    ax = ay = 0.0
    for t in range(n):
        if t % 15 == 0:
            s = (s * 1103515245 + 12345) % 2**31
            ax = (s % 2001 - 1000) / 1000
            s = (s * 1103515245 + 12345) % 2**31
            ay = (s % 2001 - 1000) / 1000
        out.append((ax, ay))
    return np.array(out, dtype=np.float64)


#: Recorded with amaze-benchmarker 1.0: SHA-256 of the uint8 observations
#: (round(255 x), the initial one first) and of the float64 positions after
#: each step, for ``_lcg_actions(800, seed)`` until the episode ends.
CONTINUOUS_DIGESTS = {
    (SIGNED, "CC11", 1): (
        800,
        "611a0cc98f541f82e2557d83b19c1e139847045c320b9b75c28cf87b777385ab",
        "7bb90c4bb4f287faea3381696d360ff8d6207776499a7d33b2551f8e4b362c76",
        (443, 6, False),
    ),
    ("M4_5x5_U", "CC15", 7): (
        440,
        "c5ca2bf7c8d489ecb3ae4fc3449431ef3f15b1c899e914bca4361cf0b5d73b9a",
        "13a89fb118f3e7868527b45f160a3881568c02cbbb19f2cc8cca6e8aae066e7b",
        (265, 2, True),
    ),
    (MULTI, "CC9", 3): (
        800,
        "08861cf22e54c8b1eef51c18502167fd954e167999249ff4f9821a66db0031c3",
        "e246576f2aeed44af976385befe4cd6a2bc865b6c82741f62e3734898c5a0b85",
        (269, 8, False),
    ),
}


@pytest.mark.parametrize("key", list(CONTINUOUS_DIGESTS))
def test_continuous_windows_match_reference(key: tuple[str, str, int]) -> None:
    maze, robot, seed = key
    steps, obs_digest, pos_digest, (collisions, backsteps, ended) = CONTINUOUS_DIGESTS[key]
    engine = BatchEngine([maze], robot, 1, auto_reset=False)
    h_obs, h_pos = hashlib.sha256(engine.reset()[0].tobytes()), hashlib.sha256()
    for t, action in enumerate(_lcg_actions(steps, seed)):
        result = _step1(engine, action)
        h_obs.update(result.observations[0].tobytes())
        h_pos.update(engine.positions[0].tobytes())
        assert result.done[0] == (ended and t == steps - 1)
    assert h_pos.hexdigest() == pos_digest
    assert h_obs.hexdigest() == obs_digest
    if ended:
        stats = result.episodes
        assert (stats.collisions[0], stats.backsteps[0]) == (collisions, backsteps)
        assert result.truncated[0]


# -----------------------------------------------------------------------------
# Batches


BATCH_MAZES = ["M4_5x5_U", SIGNED, "M3_7x4_C1", MULTI]


def _random_actions(robot: str, steps: int, n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    if robot.startswith("C"):
        return rng.uniform(-1, 1, size=(steps, n, 2))
    # biased towards one direction per agent, so that some reach the goal
    return rng.integers(0, 4, size=(steps, n))


@pytest.mark.parametrize("robot", ["DD", "H11", "CC11"])
def test_batch_matches_single_agents(robot: str) -> None:
    n_agents, steps = 10, 500 if robot != "CC11" else 300
    assignment = np.array([0, 1, 2, 3, 3, 2, 1, 0, 1, 3])
    batch = BatchEngine(BATCH_MAZES, robot, n_agents, assignment=assignment)
    singles = [BatchEngine([BATCH_MAZES[m]], robot, 1) for m in assignment]
    actions = _random_actions(robot, steps, n_agents, seed=42)
    obs = batch.reset()
    for k, single in enumerate(singles):
        np.testing.assert_array_equal(obs[k], single.observe()[0])
    n_episodes = 0
    for t in range(steps):
        result = batch.step(actions[t])
        n_episodes += len(result.episodes)
        for k, single in enumerate(singles):
            alone = single.step(actions[t, k : k + 1])
            np.testing.assert_array_equal(result.observations[k], alone.observations[0])
            assert result.rewards[k] == alone.rewards[0]
            assert result.terminated[k] == alone.terminated[0]
            assert result.truncated[k] == alone.truncated[0]
            if alone.done[0]:
                row = int(np.flatnonzero(result.episodes.agents == k)[0])
                np.testing.assert_array_equal(
                    result.final_observations[row], alone.final_observations[0]
                )
                assert result.episodes.cumulative_reward[row] == alone.episodes.cumulative_reward[0]
                assert (
                    result.episodes.path_length[row]
                    == Maze.from_string(BATCH_MAZES[assignment[k]]).path_length
                )
        np.testing.assert_array_equal(
            batch.positions, np.concatenate([s.positions for s in singles])
        )
    if robot != "CC11":
        assert n_episodes > 0  # auto-reset exercised (deadlines of the small mazes)


def test_auto_reset_restarts_at_start() -> None:
    maze = Maze.from_string("M4_5x5_U")
    bump = int(np.flatnonzero(maze.walls[maze.start])[0])
    deadline = 4 * maze.path_length
    engine = BatchEngine([maze], "DD", 2)
    manual = BatchEngine([maze], "DD", 2, auto_reset=False)
    first = engine.reset().copy()
    for _ in range(deadline):
        result = engine.step(np.array([bump, bump]))
        last = manual.step(np.array([bump, bump]))
    assert result.truncated.all() and last.truncated.all()
    np.testing.assert_array_equal(result.observations, first)
    np.testing.assert_array_equal(result.final_observations, last.observations)
    assert result.episodes.agents.tolist() == [0, 1]
    assert engine.timesteps.tolist() == [0, 0]
    assert engine.cumulative_rewards.tolist() == [0.0, 0.0]
    # a fresh deadline: the next episode lasts as long again
    for t in range(deadline):
        result = engine.step(np.array([bump, bump]))
        assert result.truncated.all() == (t == deadline - 1)
    assert result.episodes.pretty_rewards().tolist() == [-1.0, -1.0]


def test_reset_switches_mazes_and_returns_all() -> None:
    engine = BatchEngine(["M4_5x5_U", SIGNED], "DD", 4)
    assert engine.assignment.tolist() == [0, 1, 0, 1]
    obs = engine.reset(np.array([1]), assignment=np.array([0]))
    assert obs.shape == (4, 8)
    assert engine.assignment.tolist() == [0, 0, 0, 1]
    np.testing.assert_array_equal(obs[1], obs[0])
    with pytest.raises(ValueError):
        engine.reset(np.array([0]), assignment=np.array([2]))


def test_fresh_arrays() -> None:
    for robot, action in [("DD", np.zeros(3, dtype=np.int64)), ("H9", np.ones(3, dtype=np.int64))]:
        engine = BatchEngine([SIGNED], robot, 3)
        obs = engine.reset()
        before = obs.copy()
        a = engine.step(action)
        b = engine.step(action)
        assert not np.shares_memory(a.observations, b.observations)
        assert not np.shares_memory(obs, a.observations)
        a.observations[...] = 7
        np.testing.assert_array_equal(engine.reset(), before)
    engine = BatchEngine([SIGNED], "CC9", 2)
    x = engine.step(np.zeros((2, 2)))
    y = engine.step(np.zeros((2, 2)))
    assert not np.shares_memory(x.observations, y.observations)


def test_invalid_actions() -> None:
    engine = BatchEngine(["M4_5x5_U"], "DD", 2)
    with pytest.raises(ValueError, match=r"0\.\.3.*agents \[1\] got \[4\]"):
        engine.step(np.array([0, 4]))
    with pytest.raises(ValueError, match=r"agents \[0\] got \[-1\]"):
        engine.step(np.array([-1, 2], dtype=np.int32))
    with pytest.raises(ValueError, match="integers"):
        engine.step(np.array([0.0, 1.0]))
    with pytest.raises(ValueError, match="integers"):
        engine.step(np.array([True, False]))
    with pytest.raises(ValueError, match="2 integers"):
        engine.step(np.array([0]))
    continuous = BatchEngine(["M4_5x5_U"], "CC", 2)
    with pytest.raises(ValueError):
        continuous.step(np.zeros(2))


@pytest.mark.parametrize("robot", ["DD", "H9"])
@pytest.mark.parametrize("parallel", [False, True])
def test_refused_steps_change_nothing(robot: str, parallel: bool) -> None:
    """Actions are validated before any agent moves: a refused step leaves no trace."""
    actions = _random_actions(robot, 60, 5, seed=3)
    checked = BatchEngine(BATCH_MAZES, robot, 5, parallel=parallel)
    plain = BatchEngine(BATCH_MAZES, robot, 5, parallel=parallel)
    for t in range(actions.shape[0]):
        bad = actions[t].copy()
        bad[(t % 4) + 1] = 4 + t % 3  # agents before the bad one would move first
        with pytest.raises(ValueError, match=r"0\.\.3"):
            checked.step(bad)
        a, b = checked.step(actions[t]), plain.step(actions[t])
        np.testing.assert_array_equal(a.observations, b.observations)
        np.testing.assert_array_equal(a.rewards, b.rewards)
    np.testing.assert_array_equal(checked.cells, plain.cells)
    np.testing.assert_array_equal(checked.cumulative_rewards, plain.cumulative_rewards)


def test_integer_action_types() -> None:
    engine = BatchEngine([SIGNED], "DD", 4)
    reference = BatchEngine([SIGNED], "DD", 4)
    for dtype in (np.int8, np.uint8, np.int32, np.uint64, np.int64):
        actions = np.array([0, 1, 2, 3], dtype=dtype)
        result = engine.step(actions)
        expected = reference.step([0, 1, 2, 3])
        np.testing.assert_array_equal(result.observations, expected.observations)
    strided = np.arange(8, dtype=np.int64)[::2] % 4  # a non-contiguous view
    np.testing.assert_array_equal(
        engine.step(strided).observations, reference.step(strided.copy()).observations
    )


def test_stepping_an_ended_agent_names_it() -> None:
    maze = Maze.from_string("M4_5x5_U")
    bump = int(np.flatnonzero(maze.walls[maze.start])[0])
    engine = BatchEngine([maze], "DD", 3, auto_reset=False)
    for _ in range(4 * maze.path_length - 1):
        engine.step(np.array([bump, bump, bump]))
    engine.reset(np.array([1]))
    last = engine.step(np.array([bump, bump, bump]))
    assert last.truncated.tolist() == [True, False, True]
    assert last.episodes.agents.tolist() == [0, 2]
    steps = engine.timesteps.copy()
    with pytest.raises(EpisodeEndedError, match=r"agents \[0, 2\]"):
        engine.step(np.array([bump, bump, bump]))
    np.testing.assert_array_equal(engine.timesteps, steps)  # agent 1 did not move either
    engine.reset(np.array([0, 2]))
    assert engine.step(np.array([bump, bump, bump])).rewards.tolist() == [-1.2] * 3


def test_results_are_ordinary_frozen_dataclasses() -> None:
    engine = BatchEngine(["M4_5x5_U"], "DD", 2)
    result = engine.step(np.array([0, 1]))
    fields = {f.name for f in dataclasses.fields(result)}
    assert fields == set(vars(result))
    assert {f.name for f in dataclasses.fields(result.episodes)} == set(vars(result.episodes))
    assert result == dataclasses.replace(result)
    with pytest.raises(dataclasses.FrozenInstanceError):
        result.rewards = None  # type: ignore[misc]
    assert len(result.episodes) == 0 and result.final_observations.shape == (0, 8)


@pytest.mark.parametrize("robot", ["DD", "H11", "CC11"])
@pytest.mark.parametrize("auto_reset", [True, False])
def test_parallel_kernels_match_serial(robot: str, auto_reset: bool) -> None:
    """Both kernel families give identical results, episode ends and resets included."""
    n_agents, steps = 12, 400 if robot != "CC11" else 250
    assignment = np.arange(n_agents) % len(BATCH_MAZES)
    engines = [
        BatchEngine(
            BATCH_MAZES,
            robot,
            n_agents,
            assignment=assignment,
            auto_reset=auto_reset,
            deadline_factor=1.0,
            parallel=parallel,
        )
        for parallel in (False, True)
    ]
    assert [e.parallel for e in engines] == [False, True]
    actions = _random_actions(robot, steps, n_agents, seed=5)
    n_episodes = 0
    for t in range(steps):
        serial, parallel = (e.step(actions[t]) for e in engines)
        for name in ("observations", "rewards", "terminated", "truncated", "final_observations"):
            np.testing.assert_array_equal(getattr(serial, name), getattr(parallel, name), name)
        for f in dataclasses.fields(serial.episodes):
            a, b = getattr(serial.episodes, f.name), getattr(parallel.episodes, f.name)
            np.testing.assert_array_equal(a, b, f.name)
        n_episodes += len(serial.episodes)
        np.testing.assert_array_equal(engines[0].positions, engines[1].positions)
        if not auto_reset and len(serial.episodes):
            for engine in engines:
                engine.reset(serial.episodes.agents)
    assert n_episodes > 0


def test_large_batches_choose_their_kernels_by_timing(monkeypatch) -> None:
    monkeypatch.setattr(numba, "get_num_threads", lambda: 2)
    monkeypatch.setattr(os, "getloadavg", lambda: (2.7, 2.5, 2.0))  # ignored by the engine
    assert BatchEngine(["M4_5x5_U"], "DD", 4096).kernel_choice.adaptive
    assert BatchEngine(["M4_5x5_U"], "CC", 256).kernel_choice.adaptive
    small = BatchEngine(["M4_5x5_U"], "DD", 1024)  # too little work for threads
    assert not small.kernel_choice.adaptive and not small.parallel
    forced = BatchEngine(["M4_5x5_U"], "DD", 4096, parallel=False)
    assert not forced.kernel_choice.adaptive and not forced.parallel
    tiny = BatchEngine(["M4_5x5_U"], "DD", 4, parallel=True)
    assert not tiny.kernel_choice.adaptive and tiny.parallel
    monkeypatch.setattr(numba, "get_num_threads", lambda: 1)
    alone = BatchEngine(["M4_5x5_U"], "CC", 4096)
    assert not alone.kernel_choice.adaptive and not alone.parallel


class _RandomClock:
    """A clock whose every reading moves on by a random time, up to 3 s.

    An engine timing its kernels with it sees random costs and tries the other
    kernel after almost every decision: its choice flips back and forth.
    """

    def __init__(self, seed: int) -> None:
        self.rng = np.random.default_rng(seed)
        self.now = 0.0

    def __call__(self) -> float:
        self.now += float(self.rng.uniform(0.0, 3.0))
        return self.now


@pytest.mark.parametrize("robot", ["DD", "H11", "CC11"])
@pytest.mark.parametrize("auto_reset", [True, False])
def test_results_do_not_depend_on_the_kernel_choice(robot: str, auto_reset: bool) -> None:
    """An engine switching between its kernels at random steps as one that never does."""
    n_agents, steps = 12, 300 if robot != "CC11" else 200
    engines = [
        BatchEngine(
            BATCH_MAZES, robot, n_agents, auto_reset=auto_reset, deadline_factor=1.0,
            parallel=False,
        )
        for _ in range(2)
    ]  # fmt: skip
    switching = engines[1]
    switching.kernel_choice = KernelChoice(
        *switching.kernel_choice.kernels, None, clock=_RandomClock(7)
    )
    actions = _random_actions(robot, steps, n_agents, seed=11)
    n_episodes = 0
    for t in range(steps):
        serial, either = (e.step(actions[t]) for e in engines)
        for name in ("observations", "rewards", "terminated", "truncated", "final_observations"):
            np.testing.assert_array_equal(getattr(serial, name), getattr(either, name), name)
        for f in dataclasses.fields(serial.episodes):
            a, b = getattr(serial.episodes, f.name), getattr(either.episodes, f.name)
            np.testing.assert_array_equal(a, b, f.name)
        n_episodes += len(serial.episodes)
        if not auto_reset and len(serial.episodes):
            for engine in engines:
                engine.reset(serial.episodes.agents)
    assert n_episodes > 0
    assert min(switching.kernel_choice.calls) > steps // 10 and switching.kernel_choice.switches > 5
    np.testing.assert_array_equal(engines[0].cells, switching.cells)
    np.testing.assert_array_equal(engines[0].cumulative_rewards, switching.cumulative_rewards)


def test_steps_without_ended_episodes_share_read_only_empty_results() -> None:
    """Nothing a step returns can change under a caller who keeps it."""
    maze = Maze.from_string("M4_5x5_U")
    bump = int(np.flatnonzero(maze.walls[maze.start])[0])
    engine = BatchEngine([maze], "DD", 2)
    quiet = [engine.step(np.array([bump, bump])) for _ in range(3)]
    for result in quiet:
        assert len(result.episodes) == 0 and result.final_observations.shape == (0, 8)
        for array in (result.final_observations, *vars(result.episodes).values()):
            if isinstance(array, np.ndarray):
                assert array.size == 0 and not array.flags.writeable
        for array in (result.observations, result.rewards, result.terminated):
            assert array.flags.writeable  # the arrays with content are the caller's
        with pytest.raises(ValueError):
            result.episodes.agents[...] = 1
    while True:
        ended = engine.step(np.array([bump, bump]))
        if len(ended.episodes):
            break
    again = engine.step(np.array([bump, bump]))
    assert len(ended.episodes) == 2 and ended.final_observations.shape == (2, 8)
    assert ended.episodes.agents.flags.writeable and ended.final_observations.flags.writeable
    kept = ended.final_observations.copy(), ended.episodes.cumulative_reward.copy()
    while not len(again.episodes):
        again = engine.step(np.array([bump, bump]))
    assert not np.shares_memory(again.final_observations, ended.final_observations)
    assert not np.shares_memory(again.episodes.agents, ended.episodes.agents)
    np.testing.assert_array_equal(ended.final_observations, kept[0])
    np.testing.assert_array_equal(ended.episodes.cumulative_reward, kept[1])
    assert all(len(q.episodes) == 0 for q in quiet)
