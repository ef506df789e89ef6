"""The gymnasium environment ``AMaze-v0`` (registered by ``import amaze``).

``gymnasium.make("AMaze-v0", maze="M4_10x10_C1", robot="DD")`` gives one agent
in one maze with the reference wrapper's spaces (``AMAZE_REFERENCE.md`` §8.5):

* observations: ``Box(-1, 1, (8,), float32)`` for discrete inputs, or
  ``Box(0, 255, (1, v, v), uint8)`` images (channel first) for hybrid and
  continuous robots;
* actions: ``Discrete(4)`` (E, N, W, S) or ``Box(-1, 1, (2,), float32)`` accelerations;
* ``terminated`` when the goal is reached, ``truncated`` at the deadline;
* ``reset(options={"maze": STRING})`` switches to another maze for the next episodes;
* ``info`` holds the episode statistics and, at the end of an episode, both
  normalised rewards (``pretty_reward``, the reference's, and ``paper_reward``,
  the paper's R̄).
"""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium
import numpy as np
from gymnasium import spaces

from amaze.maze import Maze, as_maze
from amaze.robot import Robot, as_robot
from amaze.simulation import Simulation
from amaze.spec import MazeSpec

ENV_ID = "AMaze-v0"
DEFAULT_MAZE = "M0_10x10_C1"


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


def to_image_u8(image: np.ndarray) -> np.ndarray:
    """A float image with values k/255 as the uint8 (1, v, v) observation k."""
    return np.rint(image * 255.0).astype(np.uint8)[None]


class MazeEnv(gymnasium.Env):
    """One agent in one AMaze maze."""

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["human", "rgb_array"], "render_fps": 30}

    def __init__(
        self,
        maze: Maze | MazeSpec | str = DEFAULT_MAZE,
        robot: Robot | str = "DD",
        deadline_factor: float = 4.0,
        render_mode: str | None = None,
    ) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            modes = self.metadata["render_modes"]
            raise ValueError(f"render_mode {render_mode!r} is not one of {modes}")
        self.robot = as_robot(robot)
        self.render_mode = render_mode
        self.simulation = Simulation(as_maze(maze), self.robot, deadline_factor=deadline_factor)
        self.observation_space = observation_space(self.robot)
        self.action_space = action_space(self.robot)
        self._viewer = None
        self._background = None  # (maze, its rendered picture, its layout)

    @property
    def maze(self) -> Maze:
        return self.simulation.maze

    def _observation(self) -> np.ndarray:
        obs = self.simulation.observe()
        return obs if self.robot.discrete_inputs else to_image_u8(obs)

    def _info(self) -> dict[str, Any]:
        sim = self.simulation
        info: dict[str, Any] = {
            "maze": sim.maze.to_string(),
            "time": sim.timestep,
            "len": sim.maze.path_length,
            "steps": sim.stats.steps,
            "collisions": sim.stats.collisions,
            "backsteps": sim.stats.backsteps,
            "success": sim.success(),
        }
        if sim.done():
            info["pretty_reward"] = sim.pretty_reward()
            info["paper_reward"] = sim.paper_reward()
        return info

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode; ``options={"maze": STRING}`` switches the maze."""
        super().reset(seed=seed)
        maze = (options or {}).get("maze")
        self.simulation.reset(as_maze(maze) if maze is not None else None)
        if self.render_mode == "human":
            self.render()
        return self._observation(), self._info()

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        reward = self.simulation.step(action)
        terminated = self.simulation.success()
        truncated = self.simulation.failure()  # both can hold, as in the reference
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
            from amaze.render import MazeLayout, RenderOptions, render_maze

            options = RenderOptions(cell_size=24)
            layout = MazeLayout.of(self.maze, options)
            self._background = (self.maze, render_maze(self.maze, options), layout)
        _, background, layout = self._background
        image = background.copy()
        x, y = self.simulation.position
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
        entry_point="amaze.gym_env:MazeEnv",
        vector_entry_point="amaze.vector_env:MazeVectorEnv",
    )
