"""Built-in controllers: random, oracle and tabular, run through the policy protocol."""

from __future__ import annotations

import json
import math
from collections import deque
from pathlib import Path

import numpy as np
import pytest

from amaze.agents.engine import BatchEngine
from amaze.errors import AmazeError
from amaze.evaluation.controllers import (
    CONTROLLERS,
    ORACLE_DAMPING,
    ORACLE_GAIN,
    ControllerError,
    OracleController,
    RandomController,
    TabularController,
    goal_directions,
    make_controller,
    train_tabular,
)
from amaze.evaluation.policy import EpisodeResults, Policy, record_episode, run_episodes
from amaze.maze.directions import OFFSETS, OFFSETS_ARRAY, direction_between
from amaze.maze.maze import Maze

#: Sizes 5x5 to 20x20, unicursive and not, clues, lures, traps, every start corner.
VARIED = [
    "M4_5x5_C1",
    "M16_5x10_U",
    "M1_10x10_C1",
    "M2_10x10_U",
    "M3_12x7_NE_C1_l.5_L.25",
    "M5_10x10_SE_C1_t.5_T.5",
    "M6_15x15_NW_C1_l.25_L.25_t.5_T.5",
    "M7_9x11_NE_R_C1",
    "M8_20x20_C1_l.25_L.25_t.5_T.5",
    "M9_20x20_SE_U",
]

#: A maze with side branches, for runs that start off the solution.
BRANCHING = "M1_10x10_C1"


def _results_equal(a: EpisodeResults, b: EpisodeResults) -> bool:
    return all(
        np.array_equal(getattr(a, name), getattr(b, name))
        for name in ("success", "steps", "collisions", "backsteps", "cumulative_reward")
    )


def _distances(maze: Maze, goal: tuple[int, int]) -> np.ndarray:
    """Breadth-first distances (in moves) from every cell to ``goal`` (-1 if unreachable)."""
    distance = np.full((maze.width, maze.height), -1, dtype=np.int64)
    distance[goal] = 0
    queue = deque([goal])
    while queue:
        i, j = queue.popleft()
        for d, (di, dj) in enumerate(OFFSETS):
            n = (i + di, j + dj)
            if not maze.walls[i, j, d] and distance[n] < 0:
                distance[n] = distance[i, j] + 1
                queue.append(n)
    return distance


def _off_solution_cell(maze: Maze) -> tuple[int, int]:
    """The cell off the solution that is farthest from the goal."""
    distance = _distances(maze, maze.end)
    for cell in maze.solution:
        distance[cell] = -1
    i, j = np.unravel_index(int(np.argmax(distance)), distance.shape)
    return int(i), int(j)


def _drive_to(engine: BatchEngine, field: np.ndarray, cell: tuple[int, int]) -> int:
    """Move agent 0 of a one-agent engine along ``field`` until it stands in ``cell``."""
    steps = 0
    while tuple(engine.cells[0]) != cell:
        here = engine.cells[0]
        d = int(field[here[0], here[1]])
        if engine.robot.discrete_outputs:
            action = np.array([d])
        else:  # the oracle's PD law, towards the next cell of this field
            error = here + 0.5 + OFFSETS_ARRAY[d] - engine.positions[0]
            a = ORACLE_GAIN * error - ORACLE_DAMPING * engine.velocities[0]
            action = (a / max(1.0, float(np.linalg.norm(a))))[None]
        result = engine.step(action)
        assert not result.done[0], "the episode ended before reaching the off-solution cell"
        steps += 1
    return steps


# -----------------------------------------------------------------------------
# Random


def test_controllers_are_policies() -> None:
    assert isinstance(RandomController("DD"), Policy)
    assert isinstance(OracleController("CC11"), Policy)
    assert isinstance(TabularController(), Policy)


def test_random_discrete_covers_every_direction_and_is_reproducible() -> None:
    observations = np.zeros((4000, 8), dtype=np.float32)
    controller = RandomController("DD", seed=3)
    actions = controller(observations)
    assert actions.shape == (4000,) and np.issubdtype(actions.dtype, np.integer)
    counts = np.bincount(actions, minlength=4)
    assert counts.shape == (4,) and (counts > 850).all(), counts
    assert not np.array_equal(controller(observations), actions)  # the generator moves on
    controller.reset(4000)
    assert np.array_equal(controller(observations), actions)
    assert not np.array_equal(RandomController("DD", seed=4)(observations), actions)


def test_random_continuous_covers_the_full_circle() -> None:
    observations = np.zeros((4000, 1, 11, 11), dtype=np.uint8)
    controller = RandomController("CC11", seed=0)
    actions = controller(observations)
    assert actions.shape == (4000, 2)
    magnitude = np.linalg.norm(actions, axis=1)
    assert magnitude.max() < 1 and magnitude.max() > 0.99 and abs(magnitude.mean() - 0.5) < 0.03
    angle = np.mod(np.arctan2(actions[:, 1], actions[:, 0]), 2 * math.pi)
    quadrants = np.bincount((angle // (math.pi / 2)).astype(int), minlength=4)
    assert quadrants.shape == (4,) and (quadrants > 850).all(), quadrants  # south included
    assert abs((actions[:, 1] < 0).mean() - 0.5) < 0.05
    controller.reset(4000)
    assert np.array_equal(controller(observations), actions)
    assert not np.array_equal(RandomController("CC11", seed=1)(observations), actions)


@pytest.mark.parametrize("robot", ["DD", "H7", "CC7"])
def test_random_runs_are_reproducible_per_seed(robot: str) -> None:
    mazes = ["M4_5x5_C1", "M16_5x10_U"]
    first = run_episodes(BatchEngine(mazes, robot, 6), RandomController(robot, seed=11))
    again = run_episodes(BatchEngine(mazes, robot, 6), RandomController(robot, seed=11))
    other = run_episodes(BatchEngine(mazes, robot, 6), RandomController(robot, seed=12))
    assert _results_equal(first, again)
    assert not _results_equal(first, other)


def test_random_recorded_trajectories_repeat() -> None:
    _, first = record_episode("M4_5x5_C1", "DD", RandomController("DD", seed=2))
    _, again = record_episode("M4_5x5_C1", "DD", RandomController("DD", seed=2))
    _, other = record_episode("M4_5x5_C1", "DD", RandomController("DD", seed=3))
    assert first.actions == again.actions and first.positions == again.positions
    assert first.actions != other.actions


@pytest.mark.parametrize("seed", [-1, 1.5, True, "0"])
def test_random_rejects_bad_seeds(seed: object) -> None:
    with pytest.raises(AmazeError, match=f"seed {seed!r}"):
        RandomController("DD", seed=seed)  # type: ignore[arg-type]


# -----------------------------------------------------------------------------
# Oracle


def test_goal_directions_lead_every_cell_to_the_goal() -> None:
    for text in ("M1_10x10_C1", "M6_15x15_NW_C1_l.25_L.25_t.5_T.5", "M9_20x20_SE_U"):
        maze = Maze.from_string(text)
        field = goal_directions(maze)
        distance = _distances(maze, maze.end)
        assert field[maze.end] == -1
        for a, b in zip(maze.solution, maze.solution[1:], strict=False):
            assert field[a] == direction_between(a, b)
        for i in range(maze.width):
            for j in range(maze.height):
                if distance[i, j] <= 0:
                    assert field[i, j] == -1
                    continue
                d = int(field[i, j])
                assert not maze.walls[i, j, d]
                di, dj = OFFSETS[d]
                assert distance[i + di, j + dj] == distance[i, j] - 1  # one step closer


def test_goal_directions_rejects_a_goal_outside_the_maze() -> None:
    with pytest.raises(AmazeError, match=r"\(5, 0\)"):
        goal_directions("M4_5x5_C1", goal=(5, 0))


@pytest.mark.parametrize("robot", ["DD", "H11"])
def test_oracle_is_optimal_with_discrete_actions(robot: str) -> None:
    mazes = [Maze.from_string(text) for text in VARIED]
    engine = BatchEngine(mazes, robot, 2 * len(mazes))
    results = run_episodes(engine, OracleController(robot))
    lengths = np.array([m.path_length for m in mazes])[results.maze_index]
    assert np.array_equal(results.path_length, lengths)
    assert results.success.all()
    assert np.array_equal(results.steps, lengths - 1)
    assert (results.collisions == 0).all() and (results.backsteps == 0).all()
    assert (results.normalized_reward == 1.0).all()
    assert (results.cumulative_reward == lengths).all()  # the reference's optimal R = l


class _Recording:
    """Wraps a policy and keeps every batch of actions it returns."""

    def __init__(self, policy: OracleController) -> None:
        self.policy = policy
        self.actions: list[np.ndarray] = []

    def bind(self, engine: BatchEngine) -> None:
        self.policy.bind(engine)

    def __call__(self, observations: np.ndarray) -> np.ndarray:
        self.actions.append(self.policy(observations))
        return self.actions[-1]


def test_oracle_reaches_the_goal_with_continuous_actions() -> None:
    mazes = [Maze.from_string(text) for text in VARIED]
    oracle = _Recording(OracleController("CC11"))
    results = run_episodes(BatchEngine(mazes, "CC11", len(mazes)), oracle)
    norms = np.linalg.norm(np.concatenate(oracle.actions), axis=1)
    assert norms.max() <= 1 + 1e-12  # inside the unit disc (and the action box)
    assert np.allclose(norms[: len(mazes)], 1.0)  # full thrust away from the start
    assert results.success.all(), [VARIED[m] for m in results.maze_index[~results.success]]
    assert (results.collisions == 0).all()  # it brakes before every turn
    # Top speed is one cell per 10 steps: well inside the deadline of 40 l steps.
    assert (results.steps < 20 * (results.path_length - 1)).all()
    assert (results.normalized_reward > 0).all()


def test_oracle_trajectory_follows_the_solution() -> None:
    for text in ("M5_10x10_SE_C1_t.5_T.5", "M7_9x11_NE_R_C1"):
        maze = Maze.from_string(text)
        results, trajectory = record_episode(maze, "DD", OracleController("DD"))
        cells = [(int(x), int(y)) for x, y in trajectory.positions]
        assert cells == list(maze.solution[:-1])
        assert trajectory.final_position == (maze.end[0] + 0.5, maze.end[1] + 0.5)
        assert results.normalized_reward[0] == 1.0


@pytest.mark.parametrize("robot", ["DD", "CC7"])
def test_oracle_keeps_reaching_the_goal_after_auto_reset(robot: str) -> None:
    mazes = [Maze.from_string(t) for t in ("M4_5x5_C1", "M16_5x10_U", "M2_10x10_U")]
    engine = BatchEngine(mazes, robot, 6)
    oracle = OracleController(robot)
    run_episodes(engine, oracle)  # the agents of short mazes are already in later episodes
    observations = engine.observe()[:, None] if robot.startswith("C") else engine.observe()
    ended = np.zeros(len(mazes), dtype=np.int64)
    dt = 1 if robot == "DD" else 10
    for _ in range(3 * dt * max(m.path_length for m in mazes)):
        result = engine.step(oracle(observations))
        observations = result.observations[:, None] if robot != "DD" else result.observations
        episodes = result.episodes
        assert episodes.success.all()
        if robot == "DD":
            assert np.array_equal(episodes.steps, episodes.path_length - 1)
        np.add.at(ended, engine.assignment[episodes.agents], 1)
    assert (ended >= 2).all(), ended


@pytest.mark.parametrize("robot", ["DD", "CC11"])
def test_oracle_reaches_the_goal_from_off_the_solution(robot: str) -> None:
    maze = Maze.from_string(BRANCHING)
    cell = _off_solution_cell(maze)
    assert cell not in maze.solution
    engine = BatchEngine([maze], robot, 1, auto_reset=False)
    detour = _drive_to(engine, goal_directions(maze, goal=cell), cell)
    oracle = OracleController(robot)
    oracle.bind(engine)
    steps = 0
    observations = engine.observe()
    while True:
        result = engine.step(oracle(observations[:, None] if robot != "DD" else observations))
        observations = result.observations
        steps += 1
        if result.done[0]:
            break
    assert result.terminated[0], "the oracle missed the goal"
    if robot == "DD":
        assert steps == _distances(maze, maze.end)[cell]
        assert result.episodes.steps[0] == detour + steps
        assert result.episodes.collisions[0] == 0


def test_oracle_must_be_bound() -> None:
    with pytest.raises(AmazeError, match="bind"):
        OracleController("DD")(np.zeros((1, 8), dtype=np.float32))


def test_oracle_rejects_another_robot_and_another_batch() -> None:
    with pytest.raises(AmazeError, match="CC11"):
        OracleController("DD").bind(BatchEngine(["M4_5x5_C1"], "CC11", 1))
    oracle = OracleController("DD")
    oracle.bind(BatchEngine(["M4_5x5_C1"], "DD", 2))
    with pytest.raises(AmazeError, match="3 observations"):
        oracle(np.zeros((3, 8), dtype=np.float32))


# -----------------------------------------------------------------------------
# Tabular


@pytest.mark.parametrize("method", ["q_learning", "sarsa"])
@pytest.mark.parametrize("maze", ["M4_5x5_C1", "M1_10x10_U"])
def test_tabular_training_learns_a_successful_greedy_policy(method: str, maze: str) -> None:
    untrained = run_episodes(BatchEngine([maze], "DD", 1), TabularController())
    assert not untrained.success[0]  # the test can fail: ties alone do not find the goal
    controller = train_tabular([maze], method=method, episodes=30, seed=0)
    results = run_episodes(BatchEngine([maze], "DD", 1), controller)
    assert results.success[0]
    assert results.normalized_reward[0] > 0.9


def test_tabular_training_cycles_through_mazes() -> None:
    mazes = ["M1_10x10_U", "M2_10x10_U"]
    controller = train_tabular(mazes, method="q_learning", episodes=40, seed=1)
    results = run_episodes(BatchEngine(mazes, "DD", 2), controller)
    assert results.success.all()


def test_q_learning_and_sarsa_updates() -> None:
    s = np.array([0, 1, 0.5, 1, 0, 0, 0, 0], dtype=np.float32)
    s_next = np.array([1, 0, 1, 0.5, 0, 0, 0, 0], dtype=np.float32)
    controller = TabularController()
    assert controller.q_learning_update(s, 0, -1.0, s_next, 0.5, 0.9, False) == -1.0
    assert controller.values(s)[0] == -0.5
    controller.q_learning_update(s_next, 1, 4.0, s, 1.0, 0.9, True)  # done: no bootstrap
    controller.q_learning_update(s_next, 3, -2.0, s, 1.0, 0.9, True)
    assert controller.values(s_next).tolist() == [0.0, 4.0, 0.0, -2.0]
    # Q-learning bootstraps from the best next value, SARSA from the next action's.
    controller.q_learning_update(s, 2, -1.0, s_next, 1.0, 0.5, False)
    assert controller.values(s)[2] == -1.0 + 0.5 * 4.0
    controller.sarsa_update(s, 3, -1.0, s_next, 3, 1.0, 0.5, False)
    assert controller.values(s)[3] == -1.0 + 0.5 * -2.0
    controller.sarsa_update(s, 1, -1.0, s_next, 3, 1.0, 0.5, True)
    assert controller.values(s)[1] == -1.0
    with pytest.raises(AmazeError, match="action 4"):
        controller.sarsa_update(s, 0, -1.0, s_next, 4, 1.0, 0.5, False)


def test_tabular_action_selection() -> None:
    s = np.array([0, 1, 1, 1, 0, 0, 0, 0], dtype=np.float32)
    greedy = TabularController(epsilon=0.0, seed=0)
    greedy.q_learning_update(s, 2, 1.0, s, 1.0, 0.0, True)
    assert {greedy.act(s) for _ in range(50)} == {2}
    assert greedy(np.stack([s, s])).tolist() == [2, 2]
    explorer = TabularController(epsilon=1.0, seed=0)
    explorer.q = greedy.q
    counts = np.bincount([explorer.act(s) for _ in range(2000)], minlength=4)
    assert (counts > 400).all(), counts
    assert {explorer.act(s, explore=False) for _ in range(50)} == {2}


def test_tabular_ties_follow_the_seed() -> None:
    observations = np.random.default_rng(5).integers(0, 3, size=(200, 8)) / 2
    first = TabularController(seed=7)(observations)
    assert set(first.tolist()) == {0, 1, 2, 3}
    assert np.array_equal(TabularController(seed=7)(observations), first)
    assert not np.array_equal(TabularController(seed=8)(observations), first)


def test_tabular_rejects_other_observations() -> None:
    with pytest.raises(AmazeError, match=r"\(2, 1, 7, 7\)"):
        TabularController()(np.zeros((2, 1, 7, 7), dtype=np.uint8))


def test_tabular_save_load_round_trip(tmp_path: Path) -> None:
    mazes = ["M4_5x5_C1", "M1_10x10_U"]
    controller = train_tabular(mazes, method="sarsa", episodes=20, seed=3, epsilon=0.2)
    path = controller.save(tmp_path / "agent.json")
    data = json.loads(path.read_text())
    assert data["controller"] == "tabular" and data["robot"] == "DD"
    assert data["epsilon"] == 0.2 and data["seed"] == 3
    assert len(data["q"]) == len(controller.q)
    assert all(len(o) == 8 and len(v) == 4 for o, v in data["q"])
    loaded = TabularController.load(path)
    assert loaded.to_dict() == controller.to_dict()
    assert loaded.q.keys() == controller.q.keys()
    assert all(np.array_equal(loaded.q[k], v) for k, v in controller.q.items())
    observations = np.array([o for o, _ in data["q"]] + [[0.5] * 8], dtype=np.float32)
    controller.reset()
    loaded.reset()
    assert np.array_equal(loaded(observations), controller(observations))
    first = run_episodes(BatchEngine(mazes, "DD", 4), controller)
    again = run_episodes(BatchEngine(mazes, "DD", 4), loaded)
    assert _results_equal(first, again)


GOOD = {"controller": "tabular", "robot": "DD", "epsilon": 0.1, "seed": 0, "q": []}
ENTRY = [[0, 1, 0.5, 1, 0, 0, 0, 0], [0.0, -1.0, 0.0, 0.0]]


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("{not json", "not valid JSON"),
        ("[1, 2]", "expected a JSON object"),
        (json.dumps({k: v for k, v in GOOD.items() if k != "q"}), r"missing keys \['q'\]"),
        (json.dumps({**GOOD, "controller": "random"}), "controller 'random'"),
        (json.dumps({**GOOD, "robot": "H15"}), "robot 'H15'"),
        (json.dumps({**GOOD, "epsilon": 2}), "epsilon 2"),
        (json.dumps({**GOOD, "seed": -3}), "seed -3"),
        (json.dumps({**GOOD, "q": {"a": 1}}), "'q' must be a list"),
        (json.dumps({**GOOD, "q": [ENTRY, [[0] * 7, [0] * 4]]}), "q entry 1"),
        (json.dumps({**GOOD, "q": [[ENTRY[0], [0, 0, "x", 0]]]}), "q entry 0"),
        (json.dumps({**GOOD, "q": [ENTRY, ENTRY]}), "repeated"),
        ("[" * 100_000 + "]" * 100_000, "not valid JSON"),
        ('{"seed": ' + "9" * 5000 + "}", "not valid JSON"),
        (json.dumps({**GOOD, "q": [[ENTRY[0], [10**400, 0, 0, 0]]]}), "q entry 0"),
        (json.dumps({**GOOD, "q": [[[1e300, *ENTRY[0][1:]], ENTRY[1]]]}), "q entry 0"),
        ("", "not valid JSON"),
        (json.dumps({**GOOD, "q": [ENTRY]})[:40], "not valid JSON"),
    ],
)
def test_tabular_load_rejects_bad_files(tmp_path: Path, content: str, message: str) -> None:
    path = tmp_path / "bad.json"
    path.write_text(content)
    with pytest.raises(ControllerError, match=message) as caught:
        TabularController.load(path)
    assert "bad.json" in str(caught.value)


def test_tabular_load_refuses_random_bytes_and_folders(tmp_path: Path) -> None:
    (tmp_path / "random.json").write_bytes(bytes(range(256)))
    (tmp_path / "folder.json").mkdir()
    for name in ("random.json", "folder.json"):
        with pytest.raises(ControllerError, match="cannot read tabular controller") as caught:
            TabularController.load(tmp_path / name)
        assert name in str(caught.value)


def test_tabular_load_accepts_a_good_file_and_rejects_a_missing_one(tmp_path: Path) -> None:
    path = tmp_path / "good.json"
    path.write_text(json.dumps({**GOOD, "q": [ENTRY]}))
    controller = TabularController.load(path)
    assert controller.values(np.array(ENTRY[0])).tolist() == ENTRY[1]
    with pytest.raises(AmazeError, match="cannot read"):
        TabularController.load(tmp_path / "missing.json")


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        ({"method": "dqn"}, "'dqn'"),
        ({"episodes": 0}, "episodes 0"),
        ({"alpha": 0}, "alpha 0"),
        ({"gamma": 1.5}, "gamma 1.5"),
        ({"epsilon": -0.1}, "epsilon -0.1"),
    ],
)
def test_train_tabular_rejects_bad_arguments(arguments: dict, message: str) -> None:
    with pytest.raises(AmazeError, match=message):
        train_tabular("M4_5x5_C1", **{"episodes": 1, **arguments})


def test_train_tabular_needs_a_maze() -> None:
    with pytest.raises(AmazeError, match="at least one maze"):
        train_tabular([], episodes=1)


# -----------------------------------------------------------------------------
# Factory


def test_make_controller(tmp_path: Path) -> None:
    assert CONTROLLERS == ("random", "oracle")
    random = make_controller("random", "CC11", seed=5)
    assert isinstance(random, RandomController) and random.seed == 5
    assert str(random.robot) == "CC11"
    assert isinstance(make_controller("oracle", "H11"), OracleController)
    path = TabularController(seed=4).save(tmp_path / "tabular.json")
    loaded = make_controller(str(path), "DD")
    assert isinstance(loaded, TabularController) and loaded.seed == 4
    with pytest.raises(AmazeError, match="DD robots only"):
        make_controller(str(path), "CC11")


def test_make_controller_rejects_unknown_names() -> None:
    with pytest.raises(AmazeError, match=r"'cheater'.*random, oracle") as error:
        make_controller("cheater", "DD")
    assert isinstance(error.value, ValueError) and isinstance(error.value, ControllerError)
