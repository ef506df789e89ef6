"""The guided controller: a continuous robot steered where a hybrid agent would go."""

from __future__ import annotations

import numpy as np
import pytest

from amaze.agents.engine import BatchEngine
from amaze.agents.robot import as_robot
from amaze.agents.tables import marker_pixel
from amaze.errors import AmazeError
from amaze.evaluation.controllers import GuidedController, OracleController
from amaze.evaluation.policy import run_episodes
from amaze.maze.directions import OFFSETS
from amaze.maze.maze import Maze

#: Perfect mazes (one way between any two cells), with signs of every kind: the
#: right-hand rule reaches the goal of each.
MAZES = [
    "M4_5x5_C1",
    "M3_7x6_NE_C1_l.5_L.25",
    "M5_6x6_SE_C1_t.5_T.5",
    "M8_7x7_NW_C1_l.25_L.25_t.5_T.5",
]
#: A maze whose right-hand walk is too long for the continuous robot's deadline.
LONG_WALK = "M7_7x7_NW_C1_l.25_L.25_t.5_T.5"


class RightHand:
    """A memoryless hybrid agent that follows the wall on its right, reading only its image.

    The walls are the white edges of the image, the side it came in by is the
    origin marker (a white pixel on an edge without a wall). Facing away from
    that side, it turns right if it can, else goes straight on, else left,
    else back; in the start cell (no marker) it faces east. It remembers which
    images it was shown.
    """

    def __init__(self, vision: int) -> None:
        self.vision = vision
        self.shown: list[np.ndarray] = []

    def __call__(self, observations: np.ndarray) -> np.ndarray:
        images = np.asarray(observations)[:, 0]
        self.shown.append(images.copy())
        v = self.vision
        walls = np.stack(
            [images[:, 1, v - 1], images[:, 0, 1], images[:, 1, 0], images[:, v - 1, 1]], axis=1
        ) > 0  # fmt: skip
        markers = np.stack([images[:, r, c] for r, c in (marker_pixel(s, v) for s in range(4))], 1)
        arrived = (markers > 0) & ~walls
        facing = np.where(arrived.any(axis=1), (arrived.argmax(axis=1) + 2) % 4, 0)
        directions = np.zeros(len(images), dtype=np.int64)
        for k in range(len(images)):
            for turn in (3, 0, 1, 2):  # right, straight on, left, back
                d = (facing[k] + turn) % 4
                if not walls[k, d]:
                    directions[k] = d
                    break
        return directions


def _cells_visited(
    engine: BatchEngine, policy, steps: int
) -> tuple[list[tuple[int, int]], list[int], bool]:
    """The cells one robot enters until its episode ends or ``steps``, the index of the
    policy call made first in each, and whether it reached the goal."""
    observations = engine.observe()[:, None]
    cells, calls = [tuple(engine.cells[0])], [0]
    for step in range(steps):
        result = engine.step(policy(observations))
        if result.done[0]:
            return cells, calls, bool(result.terminated[0])
        observations = result.observations[:, None]
        cell = tuple(engine.cells[0])
        if cell != cells[-1]:
            cells.append(cell)
            calls.append(step + 1)
    return cells, calls, False


@pytest.mark.parametrize("text", [*MAZES, LONG_WALK])
def test_the_robot_goes_where_the_guide_goes_and_the_guide_sees_a_hybrid_robots_image(
    text: str,
) -> None:
    maze = Maze.from_string(text)
    hybrid_guide = RightHand(7)
    hybrid = BatchEngine([maze], "H7", 1, auto_reset=False)
    hybrid_cells, _, hybrid_success = _cells_visited(hybrid, hybrid_guide, 10_000)
    assert hybrid_success, "the right-hand rule solves a perfect maze"
    guide = RightHand(7)
    controller = GuidedController("CC7", guide)
    continuous = BatchEngine([maze], "CC7", 1, auto_reset=False)
    controller.bind(continuous)
    continuous_cells, calls, continuous_success = _cells_visited(continuous, controller, 100_000)
    assert continuous_cells == hybrid_cells[: len(continuous_cells)]
    assert continuous_success == (text != LONG_WALK)
    assert continuous_success == (len(continuous_cells) == len(hybrid_cells))
    # In each cell the continuous robot entered, its guide was shown the hybrid
    # robot's observation of that cell, origin marker included.
    assert len(calls) > 5
    for call, seen in zip(calls, hybrid_guide.shown, strict=False):
        assert np.array_equal(guide.shown[call], seen)


def test_arrival_sides_are_the_origin_markers_side_and_the_previous_cells() -> None:
    maze = Maze.from_string(MAZES[1])
    for robot in ("H7", "CC7"):
        engine = BatchEngine([maze], robot, 1)
        assert engine.arrival_sides.tolist() == [-1]  # none in the start cell
        policy = OracleController(robot)
        policy.bind(engine)
        observations = engine.observe()[:, None]
        cell, previous, seen = tuple(engine.cells[0]), None, set()
        for _ in range(300):
            observations = engine.step(policy(observations)).observations[:, None]
            side = int(engine.arrival_sides[0])
            if tuple(engine.cells[0]) != cell:
                cell, previous = tuple(engine.cells[0]), cell
            if previous is None or cell == maze.start:
                continue  # an episode began again: no arrival side yet
            offset = (previous[0] - cell[0], previous[1] - cell[1])
            assert side == OFFSETS.index(offset), (robot, cell, previous, side)
            seen.add(side)
            if robot == "H7":  # the hybrid image shows its marker there (the continuous
                image = observations[0, 0]  # window moves with the robot, marker too)
                assert image[marker_pixel(side, 7)] == 255
        assert len(seen) >= 2


def test_a_guide_that_solves_the_suite_mazes_makes_a_teacher_that_solves_them() -> None:
    mazes = [Maze.from_string(text) for text in MAZES]
    results = run_episodes(
        BatchEngine(mazes, "CC7", 2 * len(mazes)), GuidedController("CC7", RightHand(7))
    )
    assert results.success.all()
    assert (results.collisions == 0).all()


class _Fixed:
    def __init__(self, actions: np.ndarray) -> None:
        self.actions = actions

    def __call__(self, observations: np.ndarray) -> np.ndarray:
        return self.actions


def test_guided_controller_refuses_bad_robots_guides_and_answers() -> None:
    with pytest.raises(AmazeError, match="continuous robots"):
        GuidedController("H7", RightHand(7))
    with pytest.raises(AmazeError, match="callable"):
        GuidedController("CC7", "H7 agent")
    with pytest.raises(AmazeError, match="gain"):
        GuidedController("CC7", RightHand(7), gain=0)
    with pytest.raises(AmazeError, match="damping"):
        GuidedController("CC7", RightHand(7), damping=float("nan"))
    controller = GuidedController("CC7", RightHand(7))
    assert controller.guide_robot == as_robot("H7")
    with pytest.raises(AmazeError, match="bind"):
        controller(np.zeros((1, 1, 7, 7), dtype=np.uint8))
    with pytest.raises(AmazeError, match="CC9"):
        controller.bind(BatchEngine(MAZES[:1], "CC9", 1))
    engine = BatchEngine(MAZES[:1], "CC7", 2)
    observations = engine.observe()[:, None]
    controller.bind(engine)
    with pytest.raises(AmazeError, match="3 observations"):
        controller(np.zeros((3, 1, 7, 7), dtype=np.uint8))
    for answer, message in (
        (np.array([0, 4]), "outside 0..3"),
        (np.array([0, -1]), "outside 0..3"),
        (np.array([0]), "2 integer directions"),
        (np.array([0.0, 1.0]), "2 integer directions"),
    ):
        guided = GuidedController("CC7", _Fixed(answer))
        guided.bind(engine)
        with pytest.raises(AmazeError, match=message):
            guided(observations)


class _Pushed:
    """``controller``'s actions, replaced by a full push in a turning direction for
    ``length`` steps every ``every`` steps (deterministic)."""

    def __init__(self, controller: GuidedController, every: int, length: int) -> None:
        self.controller, self.every, self.length = controller, every, length
        self.step = 0

    def __call__(self, observations: np.ndarray) -> np.ndarray:
        actions = np.asarray(self.controller(observations), dtype=np.float64)
        phase, kick = self.step % self.every, self.step // self.every
        self.step += 1
        if phase < self.length:
            actions[:] = OFFSETS[kick % 4]
        return actions


def _track(maze: Maze, policy: _Pushed, steps: int) -> tuple[list, list, bool]:
    """The cells the robot enters and the guide's track cells (the controller's, after
    each step) until the episode ends, and whether it reached the goal."""
    engine = BatchEngine([maze], "CC7", 1, auto_reset=False)
    policy.controller.bind(engine)
    observations = engine.observe()[:, None]
    cells, track = [tuple(engine.cells[0])], [tuple(engine.cells[0])]
    for _ in range(steps):
        result = engine.step(policy(observations))
        if result.done[0]:  # the goal cell is not counted, as in _cells_visited
            return cells, track, bool(result.terminated[0])
        observations = result.observations[:, None]
        if tuple(engine.cells[0]) != cells[-1]:
            cells.append(tuple(engine.cells[0]))
        if policy.controller.track and tuple(policy.controller.track_cells[0]) != track[-1]:
            track.append(tuple(policy.controller.track_cells[0]))
    return cells, track, False


@pytest.mark.parametrize("text", [MAZES[1], MAZES[3]])
def test_on_its_track_the_guide_walks_the_hybrid_agents_cells_and_brings_strays_back(
    text: str,
) -> None:
    maze = Maze.from_string(text)
    hybrid_cells, _, _ = _cells_visited(BatchEngine([maze], "H7", 1, auto_reset=False),
                                        RightHand(7), 10_000)  # fmt: skip
    # Unpushed, the track changes nothing: the robot enters the hybrid agent's cells.
    calm = _Pushed(GuidedController("CC7", RightHand(7), track=True), every=10**9, length=0)
    cells, track, success = _track(maze, calm, 100_000)
    assert success and cells == hybrid_cells and track == hybrid_cells
    # Pushed off its way, the robot strays into cells the agent never entered in that
    # order; on its track the guide still walks the agent's cells, and reaches the goal.
    tracked = _Pushed(GuidedController("CC7", RightHand(7), track=True), every=80, length=20)
    cells, track, success = _track(maze, tracked, 100_000)
    assert cells != hybrid_cells, "the pushes must make the robot stray"
    assert track == hybrid_cells
    assert success
    # Asked again wherever it strays, the memoryless guide walks other cells than the
    # agent's: sent back the way it came by the origin marker of the cell it left.
    untracked = _Pushed(GuidedController("CC7", RightHand(7)), every=80, length=20)
    cells, _, _ = _track(maze, untracked, 100_000)
    assert cells[: len(hybrid_cells)] != hybrid_cells[: len(cells)]


def test_the_track_starts_again_with_each_episode() -> None:
    maze = Maze.from_string(MAZES[1])
    controller = GuidedController("CC7", RightHand(7), track=True)
    engine = BatchEngine([maze], "CC7", 1)  # auto-reset: episodes follow one another
    controller.bind(engine)
    observations = engine.observe()[:, None]
    episodes: list[list[tuple[int, int]]] = [[tuple(engine.cells[0])]]
    while len(episodes) < 3:
        result = engine.step(controller(observations))
        observations = result.observations[:, None]
        if result.done[0]:
            assert result.terminated[0]
            episodes.append([tuple(engine.cells[0])])
        elif tuple(engine.cells[0]) != episodes[-1][-1]:
            episodes[-1].append(tuple(engine.cells[0]))
    assert episodes[0] == episodes[1] and episodes[0][-1] != maze.start


def test_track_is_refused_unless_a_boolean() -> None:
    with pytest.raises(AmazeError, match="track must be True or False"):
        GuidedController("CC7", RightHand(7), track=1)
    with pytest.raises(AmazeError, match="bind"):
        _ = GuidedController("CC7", RightHand(7), track=True).track_cells
