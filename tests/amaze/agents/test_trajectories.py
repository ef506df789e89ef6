"""Pictures of episodes (amaze.agents.trajectories): sizes, where the path lands, markers,
collision ticks, revisit lanes, animation frames, GIF files and input checking.

Pixel positions come from :class:`amaze.maze.render.MazeLayout` (north up, cell
``(0, 0)`` south-west), and each check compares a picture with the bare maze of
:func:`render_maze`, so a path drawn in the wrong place or orientation fails.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np
import pytest
from PIL import Image, ImageSequence

from amaze.agents.simulation import Simulation, Trajectory
from amaze.agents.trajectories import (
    TrajectoryError,
    frame_steps,
    render_episode_frames,
    render_trajectory,
    save_episode_gif,
    save_trajectory_png,
)
from amaze.errors import AmazeError
from amaze.evaluation.policy import record_episode
from amaze.maze.directions import OFFSETS, direction_between
from amaze.maze.maze import Maze
from amaze.maze.render import MazeLayout, RenderOptions, palette, render_maze
from amaze.maze.spec import MazeSpec

MAZE = "M3_6x6_C1"
CELL = 20
AGENT = (255, 127, 14)


@pytest.fixture(scope="module")
def maze() -> Maze:
    return Maze.from_string(MAZE)


def walk(maze: Maze, actions: Sequence[int]) -> Trajectory:
    """The trajectory of a discrete robot doing ``actions`` (0..3 = E, N, W, S)."""
    simulation = Simulation(maze, "DD", record_trajectory=True)
    for action in actions:
        simulation.step(action)
    assert simulation.trajectory is not None
    return simulation.trajectory


def oracle_actions(maze: Maze, steps: int | None = None) -> list[int]:
    """The moves along the solution (all of them, or the first ``steps``)."""
    moves = [int(direction_between(a, b)) for a, b in itertools.pairwise(maze.solution)]
    return moves if steps is None else moves[:steps]


def pixels(image: Image.Image) -> np.ndarray:
    assert image.mode == "RGB"
    return np.asarray(image).astype(int)


def cell_changed(before: np.ndarray, after: np.ndarray, layout: MazeLayout, cell) -> int:
    """How many pixels of a cell (between its grid lines) differ."""
    x0, y0, x1, y1 = layout.cell_box(*cell)
    return int(np.any(before[y0:y1, x0:x1] != after[y0:y1, x0:x1], axis=-1).sum())


def layout_of(maze: Maze, **options) -> MazeLayout:
    return MazeLayout.of(maze, RenderOptions(**options))


# -- the still picture ---------------------------------------------------------------------


@pytest.mark.parametrize("theme", ["light", "dark"])
@pytest.mark.parametrize("cell_size", [None, 12])
def test_size_equals_the_maze_picture(maze: Maze, theme: str, cell_size: int | None) -> None:
    trajectory = walk(maze, oracle_actions(maze, 5))
    image = render_trajectory(maze, trajectory, theme=theme, cell_size=cell_size)
    assert image.mode == "RGB"
    assert image.size == render_maze(maze, theme=theme, cell_size=cell_size).size


def test_path_covers_visited_cells_and_leaves_far_cells_alone(maze: Maze) -> None:
    steps = 4
    trajectory = walk(maze, oracle_actions(maze, steps))
    visited = maze.solution[: steps + 1]
    layout = layout_of(maze, cell_size=CELL)
    bare = pixels(render_maze(maze, cell_size=CELL))
    drawn = pixels(render_trajectory(maze, trajectory, cell_size=CELL))
    for cell in visited[:-1]:  # the final cell holds a marker, its centre a glyph
        x, y = layout.cell_center(*cell)
        assert tuple(drawn[y, x]) != tuple(bare[y, x]), cell
    for cell in visited:
        assert cell_changed(bare, drawn, layout, cell) >= CELL, cell
    far = [
        (i, j)
        for i in range(maze.width)
        for j in range(maze.height)
        if min(max(abs(i - a), abs(j - b)) for a, b in visited) >= 2
    ]
    assert len(far) >= 10
    for cell in far:
        assert cell_changed(bare, drawn, layout, cell) == 0, cell


def test_path_is_coloured_from_dark_to_light_over_time(maze: Maze) -> None:
    """The time gradient (viridis) brightens from the first step to the last."""
    trajectory = walk(maze, oracle_actions(maze))
    layout = layout_of(maze, cell_size=CELL)
    drawn = pixels(render_trajectory(maze, trajectory, cell_size=CELL))

    def lightness(cell) -> float:
        x, y = layout.cell_center(*cell)
        return float(drawn[y, x].sum())

    early, late = maze.solution[2], maze.solution[-3]
    assert lightness(early) + 150 < lightness(late)
    # The gradient is green-blue, not the background or a wall.
    x, y = layout.cell_center(*maze.solution[len(maze.solution) // 2])
    red, green, blue = drawn[y, x]
    assert green > red and blue > red


def test_start_and_final_markers(maze: Maze) -> None:
    """A ring around the start (west of its centre, where no path goes) and a disc
    at the final position; an unreached goal cell stays as it was."""
    cell = 40
    trajectory = walk(maze, oracle_actions(maze, 6))
    final = maze.solution[6]
    layout = layout_of(maze, cell_size=cell)
    bare = pixels(render_maze(maze, cell_size=cell))
    drawn = pixels(render_trajectory(maze, trajectory, cell_size=cell))
    x, y = layout.cell_center(*maze.start)
    west = slice(x - cell // 3 - 2, x - cell // 5), slice(y - 3, y + 4)
    assert np.any(drawn[west[1], west[0]] != bare[west[1], west[0]])
    fx, fy = layout.cell_center(*final)
    disc = drawn[fy - 3 : fy + 4, fx + 5 : fx + 7]
    assert np.all(disc != bare[fy - 3 : fy + 4, fx + 5 : fx + 7])
    assert cell_changed(bare, drawn, layout, maze.end) == 0
    # When the goal is reached, the final marker sits in the goal cell.
    success = render_trajectory(maze, walk(maze, oracle_actions(maze)), cell_size=cell)
    assert cell_changed(bare, pixels(success), layout, maze.end) > cell * cell // 8


def test_collisions_leave_a_tick_at_the_wall(maze: Maze) -> None:
    first = oracle_actions(maze, 1)[0]
    cell = maze.solution[1]
    side = next(s for s in range(4) if maze.walls[cell[0], cell[1], s])
    plain = walk(maze, [first])
    bumped = walk(maze, [first, side])
    assert plain.final_position == bumped.final_position
    size = 40
    layout = layout_of(maze, cell_size=size)
    a = pixels(render_trajectory(maze, plain, cell_size=size))
    b = pixels(render_trajectory(maze, bumped, cell_size=size))
    ys, xs = np.nonzero(np.any(a != b, axis=-1))
    assert len(xs) > 10
    # Every difference lies within a quarter cell of the middle of that wall, inside the cell.
    wx, wy = layout.edge_midpoint(cell[0], cell[1], side)
    dx, dy = OFFSETS[side]
    assert np.all(np.abs(xs - wx) <= size // 4) and np.all(np.abs(ys - wy) <= size // 4)
    inward = -(xs - wx) * dx + (ys - wy) * dy  # picture y grows southwards
    assert np.all(inward >= -layout.wall_width)
    red, green = b[ys, xs, 0], b[ys, xs, 1]
    assert np.mean(red > green) > 0.8  # magenta ticks


def test_revisits_run_in_separate_lanes(maze: Maze) -> None:
    """Going back and forth through a passage widens its drawn band."""
    there = oracle_actions(maze, 1)[0]
    back = (there + 2) % 4
    size = 40
    layout = layout_of(maze, cell_size=size)
    bare = pixels(render_maze(maze, cell_size=size))
    dx, dy = OFFSETS[there]
    x, y = layout.cell_center(*maze.start)
    mx, my = x + dx * size // 2, y - dy * size // 2  # the middle of the passage

    def band(actions: list[int]) -> int:
        drawn = pixels(render_trajectory(maze, walk(maze, actions), cell_size=size))
        if dx:  # an east-west passage: look across it, north-south
            across = drawn[my - 12 : my + 13, mx] != bare[my - 12 : my + 13, mx]
        else:
            across = drawn[my, mx - 12 : mx + 13] != bare[my, mx - 12 : mx + 13]
        return int(np.any(across, axis=-1).sum())

    once, thrice = band([there]), band([there, back, there])
    assert once >= 2
    assert thrice >= 2 * once


def test_continuous_robot_leaves_a_smooth_trail(maze: Maze) -> None:
    simulation = Simulation(maze, "CC11", record_trajectory=True)
    push = OFFSETS[oracle_actions(maze, 1)[0]]
    for k in range(40):
        simulation.step(push if k < 20 else (-push[0] * 0.5, -push[1] * 0.5))
    trajectory = simulation.trajectory
    assert trajectory is not None
    start = np.array(trajectory.positions[0])
    assert np.hypot(*(np.array(trajectory.final_position) - start)) > 0.5
    layout = layout_of(maze, cell_size=CELL)
    bare = pixels(render_maze(maze, cell_size=CELL))
    image = render_trajectory(maze, trajectory, cell_size=CELL)
    assert image.size == render_maze(maze, cell_size=CELL).size
    drawn = pixels(image)
    for x, y in trajectory.positions[5::7]:
        px = round(layout.margin + x * CELL)
        py = round(layout.margin + (maze.height - y) * CELL)
        assert np.any(
            drawn[py - 1 : py + 2, px - 1 : px + 2] != bare[py - 1 : py + 2, px - 1 : px + 2]
        )
    assert render_trajectory(maze, trajectory, cell_size=CELL, robot="CC11") == image
    # Far from the trail nothing changes.
    assert cell_changed(bare, drawn, layout, (maze.width - 1, maze.height - 1)) == 0


def random_walk(maze: Maze, robot: str, steps: int, seed: int = 0) -> Trajectory:
    """A seeded random episode (uniform moves, or normal accelerations), cut at ``steps``."""
    rng = np.random.default_rng(seed)
    simulation = Simulation(maze, robot, record_trajectory=True)
    discrete = simulation.robot.discrete_outputs
    for _ in range(steps):
        if simulation.done():
            break
        simulation.step(int(rng.integers(0, 4)) if discrete else rng.normal(size=2))
    assert simulation.trajectory is not None
    return simulation.trajectory


def test_episodes_of_each_robot_kind(maze: Maze) -> None:
    rng = np.random.default_rng(0)
    _, recorded = record_episode(maze, "DD", lambda obs: rng.integers(0, 4, len(obs)))
    hybrid = random_walk(maze, "CD5", 60)
    continuous = random_walk(maze, "CC11", 300)
    size = render_maze(maze, cell_size=12).size
    for trajectory in (recorded, hybrid, continuous):
        assert render_trajectory(maze, trajectory, cell_size=12).size == size
    auto = render_trajectory(maze, recorded, cell_size=12)
    assert render_trajectory(maze, recorded, cell_size=12, robot="DD") == auto
    # A hybrid robot moves like a discrete one: its inferred kind is the same.
    assert render_trajectory(maze, hybrid, cell_size=12) == render_trajectory(
        maze, hybrid, cell_size=12, robot="CD5"
    )


@pytest.mark.parametrize("colorblind", [False, True])
def test_dark_theme(maze: Maze, colorblind: bool) -> None:
    trajectory = walk(maze, oracle_actions(maze))
    options = RenderOptions(theme="dark", colorblind=colorblind, cell_size=CELL)
    bare = pixels(render_maze(maze, options))
    drawn = pixels(render_trajectory(maze, trajectory, options=options))
    assert tuple(drawn[1, 1]) == palette("dark").background
    layout = MazeLayout.of(maze, options)
    x, y = layout.cell_center(*maze.solution[len(maze.solution) // 2])
    assert tuple(drawn[y, x]) != tuple(bare[y, x])
    assert drawn[y, x].sum() > 150  # the path stands out of the near-black background
    assert render_trajectory(maze, trajectory, options=options, theme="light") != Image.fromarray(
        drawn.astype(np.uint8)
    )


def test_caption_adds_a_band_below(maze: Maze) -> None:
    trajectory = walk(maze, oracle_actions(maze))
    plain = render_trajectory(maze, trajectory, cell_size=CELL)
    captioned = render_trajectory(maze, trajectory, cell_size=CELL, caption=True)
    custom = render_trajectory(maze, trajectory, cell_size=CELL, caption="PPO, seed 3")
    assert captioned.width == plain.width and captioned.height > plain.height
    assert custom.height > captioned.height
    band = pixels(captioned)[plain.height :]
    assert np.any(band != np.array(palette().background))  # text and the gradient bar
    layout = layout_of(maze, cell_size=CELL)
    inner = slice(0, plain.height - layout.margin)
    assert np.array_equal(pixels(captioned)[inner], pixels(plain)[inner])


def test_accepts_maze_strings_and_specs(maze: Maze) -> None:
    trajectory = walk(maze, oracle_actions(maze, 5))
    expected = render_trajectory(maze, trajectory, cell_size=12)
    assert render_trajectory(MAZE, trajectory, cell_size=12) == expected
    assert render_trajectory(MazeSpec.from_string(MAZE), trajectory, cell_size=12) == expected


def test_save_png(maze: Maze, tmp_path) -> None:
    trajectory = walk(maze, oracle_actions(maze, 5))
    path = save_trajectory_png(MAZE, trajectory, tmp_path / "sub" / "path.png", cell_size=12)
    with Image.open(path) as image:
        assert image.format == "PNG"
        assert image.convert("RGB") == render_trajectory(maze, trajectory, cell_size=12)


# -- frames and GIFs ------------------------------------------------------------------------


@pytest.mark.parametrize(("n_steps", "max_frames"), [(1, 200), (5, 200), (10, 11), (500, 7)])
def test_frame_steps_spread_evenly_with_both_ends(n_steps: int, max_frames: int) -> None:
    steps = frame_steps(n_steps, max_frames)
    assert steps[0] == 0 and steps[-1] == n_steps
    assert len(steps) == min(n_steps + 1, max_frames)
    gaps = np.diff(steps)
    assert np.all(gaps >= 1) and gaps.max() - gaps.min() <= 1


def test_frames_show_the_agent_over_the_maze(maze: Maze) -> None:
    actions = oracle_actions(maze)
    trajectory = walk(maze, actions)
    frames = render_episode_frames(maze, trajectory, cell_size=CELL)
    assert len(frames) == len(actions) + 1
    layout = layout_of(maze, cell_size=CELL)
    bare = pixels(render_maze(maze, cell_size=CELL))
    for frame in frames:
        assert frame.mode == "RGB" and frame.size == render_maze(maze, cell_size=CELL).size
    first, last = pixels(frames[0]), pixels(frames[-1])
    x, y = layout.cell_center(*maze.start)
    assert np.abs(first[y, x] - AGENT).max() <= 3
    # Nothing but the agent in the first frame.
    changed = np.argwhere(np.any(first != bare, axis=-1))
    assert np.abs(changed - [y, x]).max() <= 0.3 * CELL + 2
    gx, gy = layout.cell_center(*maze.end)
    assert np.abs(last[gy + CELL // 5, gx] - AGENT).max() <= 3
    # The trail is there, fainter than in the still picture.
    still = pixels(render_trajectory(maze, trajectory, cell_size=CELL))
    mx, my = layout.cell_center(*maze.solution[len(maze.solution) // 2])
    white = np.array(palette().background)
    assert tuple(last[my, mx]) != tuple(bare[my, mx])
    assert np.abs(last[my, mx] - white).sum() < np.abs(still[my, mx] - white).sum()


def test_frames_are_subsampled(maze: Maze) -> None:
    rng = np.random.default_rng(0)
    _, trajectory = record_episode(maze, "DD", lambda obs: rng.integers(0, 4, len(obs)))
    n = len(trajectory.positions)
    assert n > 20
    frames = render_episode_frames(maze, trajectory, cell_size=8, max_frames=9)
    assert len(frames) == 9
    layout = layout_of(maze, cell_size=8)
    cx, cy = layout.cell_center(*maze.start)
    assert np.abs(pixels(frames[0])[cy, cx] - AGENT).max() <= 3
    final = trajectory.final_position
    fx = round(layout.margin + final[0] * 8)
    fy = round(layout.margin + (maze.height - final[1]) * 8)
    assert np.any(np.abs(pixels(frames[-1])[fy - 1 : fy + 2, fx - 1 : fx + 2] - AGENT).max(-1) <= 3)


def test_continuous_frames_use_the_robot_radius(maze: Maze) -> None:
    trajectory = random_walk(maze, "CC11", 100)
    frames = render_episode_frames(maze, trajectory, cell_size=40, max_frames=3)
    assert len(frames) == 3
    agent = np.all(np.abs(pixels(frames[0]) - AGENT) <= 3, axis=-1)
    ys, xs = np.nonzero(agent)
    # The robot's radius is a tenth of a cell: a disc about 8 px across at 40 px per cell.
    assert 4 <= xs.max() - xs.min() + 1 <= 9 and 4 <= ys.max() - ys.min() + 1 <= 9


def test_gif_has_one_frame_per_step_a_loop_and_a_final_pause(maze: Maze, tmp_path) -> None:
    actions = oracle_actions(maze)
    trajectory = walk(maze, actions)
    path = save_episode_gif(maze, trajectory, tmp_path / "episode.gif", fps=20, cell_size=10)
    frames = render_episode_frames(maze, trajectory, cell_size=10)
    with Image.open(path) as gif:
        assert gif.format == "GIF" and gif.is_animated
        assert gif.n_frames == len(actions) + 1 == len(frames)  # the first frame only once
        assert gif.info["loop"] == 0
        durations = [frame.info["duration"] for frame in ImageSequence.Iterator(gif)]
        gif.seek(0)
        first = pixels(gif.convert("RGB"))
    assert durations[:-1] == [50] * len(actions)
    assert durations[-1] == 1500
    assert np.abs(first - pixels(frames[0])).mean() < 2  # one shared palette, no dithering


def test_gif_subsampling(maze: Maze, tmp_path) -> None:
    trajectory = random_walk(maze, "DD", 200, seed=1)
    assert len(trajectory.positions) > 60
    path = save_episode_gif(
        maze, trajectory, tmp_path / "random.gif", fps=10, max_frames=30, final_pause=2, cell_size=8
    )
    with Image.open(path) as gif:
        durations = [frame.info["duration"] for frame in ImageSequence.Iterator(gif)]
    assert len(durations) <= 30
    assert sum(durations) == 29 * 100 + 2000  # 30 frames; merged ones keep their time
    assert durations[-1] >= 2000


def test_gif_merges_identical_frames(maze: Maze, tmp_path) -> None:
    """Bumping into the same wall again and again changes nothing after the third
    tick: those frames become one longer frame."""
    wall = next(side for side in range(4) if maze.walls[maze.start[0], maze.start[1], side])
    trajectory = walk(maze, [wall] * 5 + oracle_actions(maze, 2))
    frames = render_episode_frames(maze, trajectory, cell_size=20)
    assert len(frames) == 8
    assert frames[3] == frames[4] == frames[5] and frames[2] != frames[3]
    path = save_episode_gif(maze, trajectory, tmp_path / "bumps.gif", fps=10, cell_size=20)
    with Image.open(path) as gif:
        assert gif.n_frames == 6
        durations = [frame.info["duration"] for frame in ImageSequence.Iterator(gif)]
    assert durations == [100, 100, 100, 300, 100, 1500]


# -- bad input ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "draw",
    [
        lambda m, t, p: render_trajectory(m, t),
        lambda m, t, p: save_trajectory_png(m, t, p / "x.png"),
        lambda m, t, p: render_episode_frames(m, t),
        lambda m, t, p: save_episode_gif(m, t, p / "x.gif"),
    ],
)
def test_empty_trajectory_raises(maze: Maze, tmp_path, draw) -> None:
    with pytest.raises(TrajectoryError, match="empty"):
        draw(maze, Trajectory(), tmp_path)
    assert issubclass(TrajectoryError, AmazeError) and issubclass(TrajectoryError, ValueError)
    assert not list(tmp_path.iterdir())


def test_bad_input_names_the_value(maze: Maze, tmp_path) -> None:
    good = walk(maze, oracle_actions(maze, 2))
    outside = Trajectory(positions=[(0.5, 0.5), (7.5, 0.5)], final_position=(0.5, 0.5))
    with pytest.raises(TrajectoryError, match=r"7\.5"):
        render_trajectory(maze, outside)
    with pytest.raises(TrajectoryError, match="final_position"):
        render_trajectory(maze, Trajectory(positions=[(0.5, 0.5)]))
    with pytest.raises(TrajectoryError, match="3 actions"):
        render_trajectory(
            maze, Trajectory([(0.5, 0.5)], [(1.0, 0.0)] * 3, [], final_position=(0.5, 0.5))
        )
    with pytest.raises(TrajectoryError, match="max_frames 1"):
        render_episode_frames(maze, good, max_frames=1)
    with pytest.raises(TrajectoryError, match="fps 0"):
        save_episode_gif(maze, good, tmp_path / "x.gif", fps=0)
    with pytest.raises(TrajectoryError, match="sparkle"):
        render_trajectory(maze, good, sparkle=True)
    with pytest.raises(TrajectoryError, match="purple"):
        render_trajectory(maze, good, theme="purple")
    with pytest.raises(TrajectoryError, match="caption=3"):
        render_trajectory(maze, good, caption=3)
    with pytest.raises(TrajectoryError, match="XX"):
        render_trajectory(maze, good, robot="XX")
    with pytest.raises(AmazeError, match="M-1"):
        render_trajectory("M-1_5x5", good)
