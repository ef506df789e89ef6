"""The gymnasium environment ``AMaze-v0`` (registered by ``import amaze``).

``gymnasium.make("AMaze-v0", maze="M4_10x10_C1", robot="DD")`` gives one agent
in one maze with the reference wrapper's spaces (``docs/reference-behaviour.md`` §8.5):

* observations: ``Box(-1, 1, (8,), float32)`` for discrete inputs, or
  ``Box(0, 255, (1, v, v), uint8)`` images (channel first) for hybrid and
  continuous robots;
* actions: ``Discrete(4)`` (E, N, W, S) or ``Box(-1, 1, (2,), float32)`` accelerations;
* ``terminated`` when the goal is reached, ``truncated`` at the deadline;
* ``reset(options={"maze": STRING})`` switches to another maze for the next episodes
  (``options`` is a dict or None; an unknown key is an error naming it);
* ``info`` holds the episode statistics and, at the end of an episode, both
  normalised rewards (``pretty_reward``, the reference's, and ``normalized_reward``,
  the paper's R̄).

Options are checked when the environment is made (:class:`~amaze.errors.OptionError`
naming the value): ``deadline_factor`` is a finite number in [1, 1000]
(:func:`~amaze.agents.rewards.check_deadline_factor`), ``render_mode`` one of
``metadata["render_modes"]`` or None. Actions follow the contract of
``docs/reference-behaviour.md`` §4.3-4.4 (:class:`~amaze.errors.ActionError`
otherwise): discrete ones are integers 0..3; continuous ones two real
numbers, clipped to the action space [-1, 1] when finite, refused when a NaN
or an infinity (:mod:`amaze.agents.actions`).

The semantics are those of the readable :class:`~amaze.agents.simulation.Simulation`.
Continuous robots are stepped by one. Robots with discrete actions (``DD`` and
hybrid ``H``) run on the per-maze tables of :mod:`amaze.agents.tables` instead: the
state is a few plain integers (cell, arrival side, counters), a move is one
look-up in the neighbour table and an observation one precomputed array per
(cell, arrival side), copied on return. Single-agent training loops spend most
of their time in ``step``, and this keeps it several times faster than
stepping a ``Simulation``; the tests check both give identical episodes.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import gymnasium
import numpy as np
from gymnasium import spaces

from amaze.agents.rewards import (
    DEFAULT_DEADLINE_FACTOR,
    RewardScheme,
    check_deadline_factor,
    normalized_reward,
    pretty_reward,
)
from amaze.agents.robot import Robot, as_robot
from amaze.agents.simulation import Simulation
from amaze.agents.tables import (
    N_ARRIVALS,
    WHITE,
    cell_tiles,
    discrete_observations,
    marker_pixel,
    neighbour_cells,
)
from amaze.errors import EpisodeEndedError, OptionError
from amaze.maze.directions import discrete_action
from amaze.maze.maze import Maze, as_maze
from amaze.maze.spec import MazeSpec

ENV_ID = "AMaze-v0"
DEFAULT_MAZE = "M0_10x10_C1"
#: The keys of ``reset(options=...)``.
RESET_OPTIONS = ("maze",)

#: Arrival code (1 + the side leading back) after a move towards E, N, W, S.
_ARRIVAL_AFTER_MOVE = (1 + 2, 1 + 3, 1 + 0, 1 + 1)
_ENDED_MESSAGE = "the episode has ended (goal or deadline reached); call reset() first"


def observation_space(robot: Robot) -> spaces.Box:
    """The observation space of a robot (float vector or uint8 image)."""
    if robot.discrete_inputs:
        return spaces.Box(-1.0, 1.0, shape=(8,), dtype=np.float32)
    return spaces.Box(0, 255, shape=(1, robot.vision, robot.vision), dtype=np.uint8)


def action_space(robot: Robot) -> spaces.Space:
    """``Discrete(4)`` (E, N, W, S) or a 2-D acceleration in [-1, 1]²."""
    if robot.discrete_outputs:
        return spaces.Discrete(4)
    return spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)


def check_reset_options(options: object, known: tuple[str, ...] = RESET_OPTIONS) -> dict:
    """``reset``'s ``options`` as a dict: None or a mapping whose keys are all ``known``.

    Raises :class:`~amaze.errors.OptionError` naming the value or the unknown keys
    (a misspelt key would otherwise be ignored silently).
    """
    if options is None:
        return {}
    if not isinstance(options, Mapping):
        raise OptionError(
            f"reset options must be a dict (such as {{'maze': 'M4_10x10_C1'}}) or None,"
            f" not {options!r}"
        )
    unknown = [key for key in options if key not in known]
    if unknown:
        accepted = ", ".join(map(repr, known)) if known else "none"
        raise OptionError(
            f"unknown reset option(s) {', '.join(map(repr, unknown))} (accepted: {accepted})"
        )
    return dict(options)


def to_image_u8(image: np.ndarray) -> np.ndarray:
    """A float image with values k/255 as the uint8 (1, v, v) observation k."""
    return np.rint(image * 255.0).astype(np.uint8)[None]


class _GridMaze:
    """One maze compiled for a robot with discrete actions (see the module docstring).

    Cells are numbered ``i * height + j``; an observation state is
    ``cell * N_ARRIVALS + arrival`` (arrival 0 at the start, else 1 + the side
    leading back to the previous cell). Rewards are precomputed per outcome,
    summed in the order of ``Simulation.step`` so that the floats are identical.
    """

    __slots__ = (
        "back_rewards",
        "collision_reward",
        "deadline",
        "end",
        "height",
        "move_rewards",
        "neighbours",
        "observations",
        "path_length",
        "scheme",
        "start",
        "tiles",
        "vision",
    )

    def __init__(self, maze: Maze, robot: Robot, deadline_factor: float) -> None:
        self.height = maze.height
        self.start = maze.start[0] * maze.height + maze.start[1]
        self.end = maze.end[0] * maze.height + maze.end[1]
        self.neighbours: list[int] = neighbour_cells(maze).ravel().tolist()
        scheme = RewardScheme(maze.path_length, 1.0, deadline_factor)
        self.scheme = scheme
        self.path_length = maze.path_length
        self.deadline = scheme.deadline
        # A collision leaves the robot in its cell: never the goal, never a step back.
        self.collision_reward = 0.0 + scheme.collision + scheme.timestep
        move = 0.0 + scheme.timestep
        # Indexed by success. The finish bonus is only ever paid at the goal here:
        # Simulation.step pays it at the deadline only when the step *starts* past
        # the deadline, and such a step is refused.
        self.move_rewards = (move, move + scheme.finish)
        self.back_rewards = (move + scheme.backward, move + scheme.finish + scheme.backward)
        n_states = maze.width * maze.height * N_ARRIVALS
        self.vision = robot.vision or 0
        if robot.discrete_inputs:
            self.tiles = None
            self.observations: list[np.ndarray | None] = list(
                discrete_observations(maze).reshape(n_states, 8)
            )
        else:  # images are drawn on first use: most (cell, arrival) pairs are never seen
            self.tiles = cell_tiles(maze, self.vision)
            self.observations = [None] * n_states

    def image(self, state: int) -> np.ndarray:
        """The uint8 ``(1, v, v)`` image of an observation state (drawn once, then kept)."""
        cell, arrival = divmod(state, N_ARRIVALS)
        image = self.tiles[cell].copy()
        if arrival:
            image[marker_pixel(arrival - 1, self.vision)] = WHITE
        image = image[None]
        self.observations[state] = image
        return image


class MazeEnv(gymnasium.Env):
    """One agent in one AMaze maze.

    ``simulation`` is the :class:`~amaze.agents.simulation.Simulation` of a continuous
    robot; robots with discrete actions have none (they run on tables).
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["human", "rgb_array"], "render_fps": 30}

    def __init__(
        self,
        maze: Maze | MazeSpec | str = DEFAULT_MAZE,
        robot: Robot | str = "DD",
        deadline_factor: float = DEFAULT_DEADLINE_FACTOR,
        render_mode: str | None = None,
    ) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            modes = self.metadata["render_modes"]
            raise OptionError(f"render_mode {render_mode!r} is not one of {modes} or None")
        self.deadline_factor = check_deadline_factor(deadline_factor)
        self.robot = as_robot(robot)
        self.render_mode = render_mode
        self.observation_space = observation_space(self.robot)
        self.action_space = action_space(self.robot)
        self.simulation: Simulation | None = None
        self._grid: _GridMaze | None = None
        self._viewer = None
        self._background = None  # (maze, its rendered picture, its layout)
        self._use_maze(as_maze(maze))
        self._start_episode()

    # -- state ----------------------------------------------------------------

    def _use_maze(self, maze: Maze) -> None:
        """Make ``maze`` the maze of the next episodes."""
        if self.robot.discrete_outputs:
            self._grid = _GridMaze(maze, self.robot, self.deadline_factor)
        elif self.simulation is None:
            self.simulation = Simulation(maze, self.robot, deadline_factor=self.deadline_factor)
        else:
            self.simulation.reset(maze)
        self._maze = maze
        self._maze_string = maze.to_string()

    def _start_episode(self) -> None:
        grid = self._grid
        if grid is None:
            self.simulation.reset()
            return
        self._cell = grid.start
        self._arrival = 0
        self._t = 0
        self._collisions = 0
        self._backsteps = 0
        self._return = 0.0
        self._ended = grid.start == grid.end or 0 >= grid.deadline

    @property
    def maze(self) -> Maze:
        return self._maze

    @property
    def position(self) -> tuple[float, float]:
        """The robot's position (the centre of its cell for discrete actions)."""
        if self._grid is None:
            return self.simulation.position
        i, j = divmod(self._cell, self._grid.height)
        return (i + 0.5, j + 0.5)

    @property
    def cumulative_reward(self) -> float:
        """Return of the current episode so far."""
        return self._return if self._grid is not None else self.simulation.cumulative_reward

    def _observation(self) -> np.ndarray:
        grid = self._grid
        if grid is None:
            obs = self.simulation.observe()
            return obs if self.robot.discrete_inputs else to_image_u8(obs)
        state = self._cell * N_ARRIVALS + self._arrival
        obs = grid.observations[state]
        if obs is None:
            obs = grid.image(state)
        return obs.copy()

    def _info(self) -> dict[str, Any]:
        grid = self._grid
        if grid is not None:
            success = self._cell == grid.end
            return self._grid_info(grid, success, self._ended)
        sim = self.simulation
        info: dict[str, Any] = {
            "maze": self._maze_string,
            "time": sim.timestep,
            "len": sim.maze.path_length,
            "steps": sim.stats.steps,
            "collisions": sim.stats.collisions,
            "backsteps": sim.stats.backsteps,
            "success": sim.success(),
        }
        if sim.done():
            info["pretty_reward"] = sim.pretty_reward()
            info["normalized_reward"] = sim.normalized_reward()
        return info

    def _grid_info(self, grid: _GridMaze, success: bool, ended: bool) -> dict[str, Any]:
        t = self._t
        info: dict[str, Any] = {
            "maze": self._maze_string,
            "time": t,
            "len": grid.path_length,
            "steps": t,
            "collisions": self._collisions,
            "backsteps": self._backsteps,
            "success": success,
        }
        if ended:
            info["pretty_reward"] = pretty_reward(self._return, grid.scheme)
            info["normalized_reward"] = normalized_reward(
                success, t, self._collisions, self._backsteps, grid.path_length, 1.0
            )
        return info

    # -- gymnasium API --------------------------------------------------------

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode; ``options={"maze": STRING}`` switches the maze."""
        maze = check_reset_options(options).get("maze")
        super().reset(seed=seed)
        if maze is not None:
            self._use_maze(as_maze(maze))
        self._start_episode()
        if self.render_mode == "human":
            self.render()
        return self._observation(), self._info()

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        grid = self._grid
        if grid is None:
            return self._step_simulation(action)
        if self._ended:
            raise EpisodeEndedError(_ENDED_MESSAGE)
        if action.__class__ is not int or action < 0 or action > 3:
            action = discrete_action(action)
        target = grid.neighbours[self._cell * 4 + action]
        if target < 0:
            reward = grid.collision_reward
            self._collisions += 1
            success = False
        else:
            success = target == grid.end
            if self._arrival == action + 1:  # back into the cell just left
                reward = grid.back_rewards[success]
                self._backsteps += 1
            else:
                reward = grid.move_rewards[success]
            self._cell = target
            self._arrival = _ARRIVAL_AFTER_MOVE[action]
        self._return += reward
        t = self._t + 1
        self._t = t
        truncated = t >= grid.deadline  # both can hold, as in the reference
        state = self._cell * N_ARRIVALS + self._arrival
        obs = grid.observations[state]
        if obs is None:
            obs = grid.image(state)
        if success or truncated:
            self._ended = True
        info = self._grid_info(grid, success, self._ended)
        if self.render_mode == "human":
            self.render()
        return obs.copy(), reward, success, truncated, info

    def _step_simulation(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        sim = self.simulation
        reward = sim.step(action)
        terminated = sim.success()
        truncated = sim.failure()  # both can hold, as in the reference
        if self.render_mode == "human":
            self.render()
        return self._observation(), reward, terminated, truncated, self._info()

    def render(self) -> np.ndarray | None:
        """``rgb_array``: the maze with the agent, as an RGB array; ``human``: a window."""
        if self.render_mode is None:
            gymnasium.logger.warn("render() called without a render_mode; set one in make()")
            return None
        frame = self._frame()
        if self.render_mode == "rgb_array":
            return frame
        self._show(frame)
        return None

    def _frame(self) -> np.ndarray:
        """The maze picture with the agent drawn at its position."""
        from PIL import ImageDraw

        if self._background is None or self._background[0] is not self.maze:
            from amaze.maze.render import MazeLayout, RenderOptions, render_maze

            options = RenderOptions(cell_size=24)
            layout = MazeLayout.of(self.maze, options)
            self._background = (self.maze, render_maze(self.maze, options), layout)
        _, background, layout = self._background
        image = background.copy()
        x, y = self.position
        px = layout.margin + x * layout.cell_size
        py = layout.margin + (self.maze.height - y) * layout.cell_size
        radius = layout.cell_size * (0.3 if self.robot.discrete_outputs else 0.1)
        radius = max(radius, 3)
        ImageDraw.Draw(image).ellipse(
            (px - radius, py - radius, px + radius, py + radius), fill="#ff7f0e", outline="black"
        )
        return np.asarray(image.convert("RGB"))

    def _show(self, frame: np.ndarray) -> None:
        import matplotlib.pyplot as plt

        if self._viewer is None:
            plt.ion()
            figure, axes = plt.subplots()
            axes.set_axis_off()
            self._viewer = (figure, axes.imshow(frame))
        else:
            self._viewer[1].set_data(frame)
        self._viewer[0].canvas.draw_idle()
        plt.pause(1 / self.metadata["render_fps"])

    def close(self) -> None:
        if self._viewer is not None:
            import matplotlib.pyplot as plt

            plt.close(self._viewer[0])
            self._viewer = None
        self._background = None  # (maze, its rendered picture, its layout)


def register_environments() -> None:
    """Register ``AMaze-v0`` with gymnasium (idempotent)."""
    if ENV_ID in gymnasium.registry:
        return
    gymnasium.register(
        id=ENV_ID,
        entry_point="amaze.envs.gym_env:MazeEnv",
        vector_entry_point="amaze.envs.vector_env:MazeVectorEnv",
    )
