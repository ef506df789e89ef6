"""Built-in controllers: random, oracle (privileged) and tabular (reference §8.4).

Every controller here is a :class:`~amaze.evaluation.policy.Policy`: a callable from a
batch of observations (gymnasium format) to a batch of actions, with the
optional ``reset(n_agents)`` and ``bind(engine)`` hooks.

* :class:`RandomController` draws uniform actions from its own seeded
  generator; continuous accelerations cover the full circle (the reference drew
  angles in [0, π) only, so it never accelerated south).
* :class:`OracleController` follows the shortest way to the goal from whatever
  cell a robot is in, reading the engine's state (it replaces the reference's
  "cheater"). It is the yardstick of an optimal run: ``R̄ = 1`` with discrete
  actions.
* :class:`TabularController` is a Q-table over the 8-float discrete
  observation, trained by :func:`train_tabular` with Q-learning or SARSA and
  saved as plain JSON.

:func:`make_controller` builds one of them from a command-line name.
"""

from __future__ import annotations

import json
import math
from collections import deque
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from amaze.agents.engine import BatchEngine
from amaze.agents.rewards import DEFAULT_DEADLINE_FACTOR
from amaze.agents.robot import IOType, Robot, as_robot, robot_name
from amaze.agents.simulation import Simulation
from amaze.agents.tables import WHITE, marker_pixel
from amaze.errors import AmazeError
from amaze.maze.directions import OFFSETS, OFFSETS_ARRAY
from amaze.maze.maze import Maze, as_maze
from amaze.maze.spec import MazeSpec
from amaze.validation import check_integer, check_number

__all__ = [
    "CONTROLLERS",
    "ControllerError",
    "GuidedController",
    "OracleController",
    "RandomController",
    "TabularController",
    "goal_directions",
    "make_controller",
    "run_folder_agent",
    "steer",
    "train_tabular",
]

#: Names of the built-in controllers accepted by :func:`make_controller`
#: (a path to a saved tabular controller is accepted too).
CONTROLLERS: tuple[str, ...] = ("random", "oracle")

#: Number of discrete actions (E, N, W, S).
N_ACTIONS = 4

#: Gains of the continuous oracle's PD law: acceleration = GAIN * (target - position)
#: - DAMPING * velocity, clipped to the unit disc.
ORACLE_GAIN = 8.0
ORACLE_DAMPING = 6.0

#: The largest float32: a Q-table's observations are stored as float32.
_FLOAT32_MAX = float(np.finfo(np.float32).max)

TRAINING_METHODS: tuple[str, ...] = ("q_learning", "sarsa")
#: Default learning rate and discount of :func:`train_tabular` (see there).
TRAINING_ALPHA = 0.5
TRAINING_GAMMA = 0.1


class ControllerError(AmazeError):
    """A controller was misused or built from bad arguments or a bad file."""


# -----------------------------------------------------------------------------
# Random


class RandomController:
    """Uniformly random actions from a seeded generator.

    Discrete outputs: integers ``0..3`` (E, N, W, S), shape ``(n,)``.
    Continuous outputs: accelerations ``(n, 2)`` of angle uniform in ``[0, 2π)``
    and magnitude uniform in ``[0, 1)``. ``reset`` restarts the generator from
    the seed, so that every run with the same seed draws the same actions.
    """

    def __init__(self, robot: Robot | str, seed: int = 0) -> None:
        self.robot = as_robot(robot)
        self.seed = _check_seed(seed)
        self._rng = np.random.default_rng(self.seed)

    def reset(self, n_agents: int | None = None) -> None:
        """Restart the generator from the seed (``n_agents`` is not needed)."""
        self._rng = np.random.default_rng(self.seed)

    def __call__(self, observations: np.ndarray) -> np.ndarray:
        n = _batch_size(observations)
        if self.robot.discrete_outputs:
            return self._rng.integers(0, N_ACTIONS, size=n, dtype=np.int64)
        angle = self._rng.uniform(0.0, 2.0 * math.pi, size=n)
        magnitude = self._rng.random(n)
        return np.stack([magnitude * np.cos(angle), magnitude * np.sin(angle)], axis=1)


# -----------------------------------------------------------------------------
# Oracle


def goal_directions(maze: Maze | MazeSpec | str, goal: tuple[int, int] | None = None) -> np.ndarray:
    """int8 ``(width, height)``: the first move on a shortest way from each cell to the goal.

    Computed by a breadth-first search from the goal (``maze.end`` unless another
    ``goal`` cell is given) through open walls, so it is defined in every cell, on
    the solution or off it (-1 at the goal itself and in cells that cannot reach it).
    """
    maze = as_maze(maze)
    w, h = maze.width, maze.height
    walls = maze.walls
    if goal is None:
        goal = maze.end
    ei, ej = (int(c) for c in goal)
    if not (0 <= ei < w and 0 <= ej < h):
        raise ControllerError(f"goal cell {tuple(goal)} is outside the {w}x{h} maze")
    field = np.full((w, h), -1, dtype=np.int8)
    seen = np.zeros((w, h), dtype=bool)
    seen[ei, ej] = True
    queue = deque([(ei, ej)])
    while queue:
        i, j = queue.popleft()
        for d, (di, dj) in enumerate(OFFSETS):
            ni, nj = i + di, j + dj
            if walls[i, j, d] or not (0 <= ni < w and 0 <= nj < h) or seen[ni, nj]:
                continue
            seen[ni, nj] = True
            field[ni, nj] = (d + 2) % 4  # from the neighbour, back towards (i, j)
            queue.append((ni, nj))
    return field


class OracleController:
    """A privileged controller that follows the shortest way to the goal.

    :meth:`bind` hands it the :class:`~amaze.agents.engine.BatchEngine`; it then
    precomputes, for every maze and every cell, the first move towards the goal
    (:func:`goal_directions`) and, on each call, reads where every agent stands
    (and, for continuous robots, how it moves). It works in several mazes at
    once, from any cell, and with agents that auto-reset, since it keeps no
    memory of past steps.

    Discrete outputs: the direction of that first move (an optimal run: ``l - 1``
    steps, no collision, ``R̄ = 1``). Continuous outputs: a PD law that steers
    towards the centre of the next cell on the way, ``a = GAIN * (target - x) -
    DAMPING * v`` clipped to the unit disc; the damping term brakes before turns
    despite the robot's inertia.
    """

    def __init__(
        self,
        robot: Robot | str,
        *,
        gain: float = ORACLE_GAIN,
        damping: float = ORACLE_DAMPING,
    ) -> None:
        self.robot = as_robot(robot)
        self.gain = _check_gain(gain)
        self.damping = _check_damping(damping)
        self._engine: BatchEngine | None = None
        self._directions = np.empty(0, dtype=np.int64)
        self._offsets = np.empty(0, dtype=np.int64)
        self._heights = np.empty(0, dtype=np.int64)

    def bind(self, engine: BatchEngine) -> None:
        """Attach to ``engine`` and precompute the way to the goal in all its mazes."""
        if engine.robot.kind != self.robot.kind:
            raise ControllerError(
                f"oracle built for a {self.robot.kind} robot ({self.robot}) cannot drive"
                f" the engine's {engine.robot.kind} robot ({engine.robot})"
            )
        fields = [goal_directions(maze).astype(np.int64) for maze in engine.mazes]
        sizes = np.array([f.size for f in fields], dtype=np.int64)
        self._offsets = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
        self._heights = np.array([f.shape[1] for f in fields], dtype=np.int64)
        self._directions = np.concatenate([f.ravel() for f in fields])
        self._engine = engine

    def _next_direction(self, maze_index: np.ndarray, cells: np.ndarray) -> np.ndarray:
        flat = self._offsets[maze_index] + cells[:, 0] * self._heights[maze_index] + cells[:, 1]
        return self._directions[flat]

    def __call__(self, observations: np.ndarray) -> np.ndarray:
        engine = _bound_engine(self._engine, observations, "OracleController", "oracle")
        cells = engine.cells
        directions = self._next_direction(engine.assignment, cells)
        if self.robot.discrete_outputs:
            return np.where(directions >= 0, directions, 0).astype(np.int64)
        return steer(engine, cells, directions, self.gain, self.damping)


def steer(
    engine: BatchEngine, cells: np.ndarray, directions: np.ndarray, gain: float, damping: float
) -> np.ndarray:
    """float64 (n, 2): accelerations towards the centre of the next cell in ``directions``.

    The continuous oracle's PD law, ``a = gain * (target - x) - damping * v``
    clipped to the unit disc, with ``target`` the centre of the neighbour of
    each robot's cell in its direction (its own cell's centre where the
    direction is -1).
    """
    moving = directions >= 0
    target = cells + 0.5 + np.where(moving[:, None], OFFSETS_ARRAY[directions], 0)
    acceleration = gain * (target - engine.positions) - damping * engine.velocities
    norm = np.linalg.norm(acceleration, axis=1, keepdims=True)
    return acceleration / np.maximum(norm, 1.0)


class GuidedController:
    """A continuous robot steered where a hybrid agent would go: no maze solution.

    The ``guide`` is a policy of the hybrid robot with the same vision (an
    image of its cell in, a direction out; ``H7`` for ``CC7``), for instance an
    agent trained by evolution or RL from rewards alone. On each call it is
    shown, for every continuous robot, the image a hybrid robot would see in
    that cell (the cell's tile with the origin marker on the side the robot
    came in by, :attr:`BatchEngine.arrival_sides`), and the robot is steered by
    the oracle's PD law (:func:`steer`) towards the centre of the neighbour the
    guide chooses. So the continuous robot follows the guide's decisions from
    cell to cell, and goes wherever it would go: into a wall, round a loop, or
    to the goal. It reads the engine's state (the robot's cell, position and
    velocity), as the oracle does, but knows nothing of the way to the goal.
    :func:`evolution.imitation.imitate` takes it as a teacher, so that a
    network learns continuous control from an agent that learnt the maze from
    rewards.

    The guide is called once per step on the whole batch (its ``reset`` hook,
    if any, when the controller is bound); it is shown one image per robot and
    nothing else, as a memoryless hybrid agent would see it.

    ``track=True`` keeps the guide on its own track: the hybrid agent walks
    the maze cell by cell as it would in the discrete maze (its cell and the
    side it came in by are the controller's, moved on when the robot reaches
    the cell the guide chose), and a robot that leaves that track (inertia
    carrying it past a turn, a student's mistake while teaching) is steered
    back to the guide's cell by the shortest way through the maze's open
    walls, instead of the guide being asked again from the cell it strayed
    into. Without it, a stray turns the guide round: the robot re-enters the
    cell it came from, whose origin marker now points the other way, and a
    memoryless guide goes back the way it came (DAgger taught by guides on
    their track: docs/robots.md). The way back uses the maze's layout, never
    its goal: the guide alone decides where to go. The track starts again in
    each robot's start cell (its ``timesteps`` back at 0). The guide is still
    asked once per step, at the track's cells.
    """

    def __init__(
        self,
        robot: Robot | str,
        guide: Any,
        *,
        gain: float = ORACLE_GAIN,
        damping: float = ORACLE_DAMPING,
        track: bool = False,
    ) -> None:
        self.robot = as_robot(robot)
        if self.robot.kind != "continuous":
            raise ControllerError(
                f"a guided controller drives continuous robots (CC), not {robot_name(self.robot)}"
            )
        if not isinstance(track, bool):
            raise ControllerError(f"track must be True or False, got {track!r}")
        #: Whether the guide walks its own track (see the class docstring).
        self.track = track
        if not callable(guide):
            raise ControllerError(
                f"the guide must be a policy (callable), got {type(guide).__name__}"
            )
        #: The hybrid robot the guide drives: the same vision, discrete outputs.
        self.guide_robot = Robot(IOType.CONTINUOUS, IOType.DISCRETE, self.robot.vision)
        self.guide = guide
        self.gain = _check_gain(gain)
        self.damping = _check_damping(damping)
        self._engine: BatchEngine | None = None

    def bind(self, engine: BatchEngine) -> None:
        """Attach to ``engine``, whose robot must be this controller's."""
        if engine.robot != self.robot:
            raise ControllerError(
                f"guided controller built for {robot_name(self.robot)} cannot drive the"
                f" engine's {robot_name(engine.robot)}"
            )
        reset = getattr(self.guide, "reset", None)
        if callable(reset):
            reset(engine.n_agents)
        self._engine = engine
        #: The guide's own cell and arrival side per robot (``track=True``).
        self._track_cells = engine.cells
        self._track_sides = engine.arrival_sides
        #: The guide's last choice at its own cell per robot, -1 before the first.
        self._track_directions = np.full(engine.n_agents, -1, dtype=np.int64)
        #: The way to a cell from every other, per (maze index, cell): see :meth:`_way_back`.
        self._ways: dict[tuple[int, int, int], np.ndarray] = {}

    @property
    def track_cells(self) -> np.ndarray:
        """int64 (n, 2): the guide's own cell for every robot (``track=True``; a copy)."""
        _bound_engine(self._engine, None, "GuidedController", "guided controller")
        return self._track_cells.copy()

    def guide_observations(
        self, cells: np.ndarray | None = None, sides: np.ndarray | None = None
    ) -> np.ndarray:
        """uint8 (n, 1, v, v): what a hybrid robot would see in every robot's cell
        (``cells``: the engine's, if the caller has them already), having come in by
        ``sides`` (the engine's arrival sides by default; -1: no origin marker)."""
        engine = _bound_engine(self._engine, None, "GuidedController", "guided controller")
        tables = engine.tables
        cells = engine.cells if cells is None else cells
        maze = engine.assignment
        flat = tables.cell_offset[maze] + cells[:, 0] * tables.height[maze] + cells[:, 1]
        images = tables.tiles[flat]  # fancy indexing: a copy
        sides = engine.arrival_sides if sides is None else sides
        v = int(self.robot.vision)
        for side in range(len(OFFSETS)):
            row, column = marker_pixel(side, v)
            images[sides == side, row, column] = WHITE
        return images[:, None]

    def __call__(self, observations: np.ndarray) -> np.ndarray:
        engine = _bound_engine(self._engine, observations, "GuidedController", "guided controller")
        cells = engine.cells
        if self.track:
            directions = self._tracked_directions(engine, cells)
        else:
            directions = self._ask(cells, engine.arrival_sides)
        return steer(engine, cells, directions, self.gain, self.damping)

    def _ask(self, cells: np.ndarray, sides: np.ndarray) -> np.ndarray:
        """int64 (n,): the guide's direction in ``cells``, having come in by ``sides``."""
        n = len(cells)
        directions = np.asarray(self.guide(self.guide_observations(cells, sides))).reshape(-1)
        if directions.shape != (n,) or not np.issubdtype(directions.dtype, np.integer):
            raise ControllerError(
                f"the guide must return {n} integer directions, got {directions.dtype}"
                f" of shape {directions.shape}"
            )
        if directions.min(initial=0) < 0 or directions.max(initial=0) >= N_ACTIONS:
            raise ControllerError("the guide returned a direction outside 0..3 (E, N, W, S)")
        return directions.astype(np.int64)

    def _tracked_directions(self, engine: BatchEngine, cells: np.ndarray) -> np.ndarray:
        """int64 (n,): the guide's direction for robots on its track, the way back to
        it for the others. The track moves on where a robot reached the cell the guide
        chose at the last step, so the guide is asked once per step."""
        last = self._track_directions
        chosen = self._track_cells + OFFSETS_ARRAY[np.maximum(last, 0)]
        moved = (last >= 0) & np.all(cells == chosen, axis=1)
        self._track_cells[moved] = chosen[moved]
        self._track_sides[moved] = (last[moved] + 2) % N_ACTIONS
        fresh = engine.timesteps == 0
        self._track_cells[fresh] = cells[fresh]
        self._track_sides[fresh] = engine.arrival_sides[fresh]
        directions = self._ask(self._track_cells, self._track_sides)
        self._track_directions = directions.copy()
        maze = engine.assignment
        for k in np.flatnonzero(np.any(cells != self._track_cells, axis=1)):
            way = self._way_back(engine, int(maze[k]), self._track_cells[k])
            directions[k] = way[cells[k, 0], cells[k, 1]]
        return directions

    def _way_back(self, engine: BatchEngine, maze: int, cell: np.ndarray) -> np.ndarray:
        """The first move from every cell of maze ``maze`` towards ``cell`` (cached)."""
        key = (maze, int(cell[0]), int(cell[1]))
        way = self._ways.get(key)
        if way is None:
            way = self._ways[key] = goal_directions(engine.mazes[maze], goal=key[1:])
        return way


# -----------------------------------------------------------------------------
# Tabular


def _key(observation: np.ndarray) -> bytes:
    """Hashable key of one 8-float observation: its float32 bytes (-0.0 folded into 0.0)."""
    return (np.asarray(observation, dtype=np.float32).reshape(8) + np.float32(0.0)).tobytes()


def _observation(key: bytes) -> np.ndarray:
    return np.frombuffer(key, dtype=np.float32)


class TabularController:
    """A Q-table over the discrete robot's 8-float observations (DD robots only).

    Values start at 0. Calling it on a batch gives the greedy actions; ties are
    broken by its own generator, seeded with ``seed`` (restarted by
    :meth:`reset`, so that evaluations are reproducible). :meth:`act` is
    epsilon-greedy for training. Since the observation shows the walls, the side
    the robot came from and the sign of the cell (its lightness in the slot of
    the direction it points to), a table can learn to follow corridors and clues.
    """

    robot = Robot()

    def __init__(self, epsilon: float = 0.1, seed: int = 0) -> None:
        self.epsilon = _check_probability("epsilon", epsilon)
        self.seed = _check_seed(seed)
        self.q: dict[bytes, np.ndarray] = {}
        self._rng = np.random.default_rng(self.seed)

    def reset(self, n_agents: int | None = None) -> None:
        """Restart the generator from the seed (``n_agents`` is not needed)."""
        self._rng = np.random.default_rng(self.seed)

    # -- values ---------------------------------------------------------------

    def values(self, observation: np.ndarray) -> np.ndarray:
        """The four action values of an observation (zeros if never seen; a copy)."""
        values = self.q.get(_key(observation))
        return np.zeros(N_ACTIONS) if values is None else values.copy()

    def _row(self, observation: np.ndarray) -> np.ndarray:
        key = _key(observation)
        row = self.q.get(key)
        if row is None:
            row = self.q[key] = np.zeros(N_ACTIONS)
        return row

    def greedy(self, observation: np.ndarray) -> int:
        """The best action of an observation, ties broken at random."""
        values = self.q.get(_key(observation))
        if values is None:
            return int(self._rng.integers(N_ACTIONS))
        best = np.flatnonzero(values == values.max())
        return int(best[0] if best.size == 1 else self._rng.choice(best))

    def act(self, observation: np.ndarray, explore: bool = True) -> int:
        """Epsilon-greedy action of one observation (greedy when ``explore`` is False)."""
        if explore and self.epsilon > 0 and self._rng.random() < self.epsilon:
            return int(self._rng.integers(N_ACTIONS))
        return self.greedy(observation)

    def __call__(self, observations: np.ndarray) -> np.ndarray:
        batch = np.asarray(observations, dtype=np.float32)
        if batch.ndim != 2 or batch.shape[1] != 8:
            raise ControllerError(
                f"tabular controller takes (n, 8) discrete observations, got shape {batch.shape}"
            )
        return np.array([self.greedy(o) for o in batch], dtype=np.int64)

    # -- learning -------------------------------------------------------------

    def q_learning_update(
        self,
        s: np.ndarray,
        a: int,
        r: float,
        s_next: np.ndarray,
        alpha: float,
        gamma: float,
        done: bool,
    ) -> float:
        """Q-learning: ``Q(s,a) += α (r + γ max Q(s',·) - Q(s,a))``; returns the TD error.

        ``done`` ends the episode: nothing is bootstrapped from ``s_next``.
        """
        future = 0.0 if done else float(self.values(s_next).max())
        return self._update(s, a, r + gamma * future, alpha)

    def sarsa_update(
        self,
        s: np.ndarray,
        a: int,
        r: float,
        s_next: np.ndarray,
        a_next: int,
        alpha: float,
        gamma: float,
        done: bool,
    ) -> float:
        """SARSA: ``Q(s,a) += α (r + γ Q(s',a') - Q(s,a))``; returns the TD error."""
        future = 0.0 if done else float(self.values(s_next)[_check_action(a_next)])
        return self._update(s, a, r + gamma * future, alpha)

    def _update(self, s: np.ndarray, a: int, target: float, alpha: float) -> float:
        row = self._row(s)
        a = _check_action(a)
        error = target - row[a]
        row[a] += alpha * error
        return float(error)

    # -- persistence ----------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """The JSON document of :meth:`save` (entries sorted by observation)."""
        entries = sorted(
            ([float(x) for x in _observation(key)], [float(v) for v in values])
            for key, values in self.q.items()
        )
        return {
            "controller": "tabular",
            "robot": self.robot.to_string(),
            "epsilon": self.epsilon,
            "seed": self.seed,
            "q": [[observation, values] for observation, values in entries],
        }

    def save(self, path: str | Path) -> Path:
        """Write the controller as JSON (no pickle) and return the path."""
        path = Path(path)
        path.write_text(json.dumps(self.to_dict(), indent=1) + "\n", encoding="utf-8")
        return path

    @classmethod
    def from_dict(cls, data: Any, source: str = "tabular controller") -> TabularController:
        """Rebuild a controller from :meth:`to_dict`'s document, checking every field."""
        if not isinstance(data, dict):
            raise ControllerError(f"{source}: expected a JSON object, got {type(data).__name__}")
        missing = [k for k in ("controller", "robot", "epsilon", "seed", "q") if k not in data]
        if missing:
            raise ControllerError(f"{source}: missing keys {missing}")
        if data["controller"] != "tabular":
            raise ControllerError(f"{source}: controller {data['controller']!r} is not 'tabular'")
        if data["robot"] != "DD":
            raise ControllerError(f"{source}: robot {data['robot']!r} is not 'DD'")
        try:
            controller = cls(epsilon=data["epsilon"], seed=data["seed"])
        except ControllerError as error:
            raise ControllerError(f"{source}: {error}") from None
        if not isinstance(data["q"], list):
            raise ControllerError(f"{source}: 'q' must be a list, got {type(data['q']).__name__}")
        for n, entry in enumerate(data["q"]):
            if not (
                isinstance(entry, list)
                and len(entry) == 2
                and _numbers(entry[0], 8, limit=_FLOAT32_MAX)
                and _numbers(entry[1], N_ACTIONS)
            ):
                raise ControllerError(
                    f"{source}: q entry {n} {entry!r} is not [8 observation numbers"
                    f" (float32), {N_ACTIONS} finite values]"
                )
            key = _key(np.array(entry[0], dtype=np.float32))
            if key in controller.q:
                raise ControllerError(f"{source}: q entry {n}: observation {entry[0]} repeated")
            controller.q[key] = np.array(entry[1], dtype=np.float64)
        return controller

    @classmethod
    def load(cls, path: str | Path) -> TabularController:
        """Read a controller written by :meth:`save`; a bad file raises :class:`ControllerError`."""
        path = Path(path)
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as error:
            raise ControllerError(f"cannot read tabular controller '{path}': {error}") from None
        try:
            data = json.loads(text)
        except (ValueError, RecursionError) as error:  # bad JSON, too deep, too many digits
            raise ControllerError(f"'{path}' is not valid JSON: {error}") from None
        return cls.from_dict(data, source=f"'{path}'")


def train_tabular(
    mazes: Maze | MazeSpec | str | Sequence[Maze | MazeSpec | str],
    *,
    method: str = "q_learning",
    episodes: int,
    alpha: float = TRAINING_ALPHA,
    gamma: float = TRAINING_GAMMA,
    epsilon: float = 0.1,
    seed: int = 0,
    deadline_factor: float = DEFAULT_DEADLINE_FACTOR,
) -> TabularController:
    """Train a :class:`TabularController` with Q-learning or SARSA on :class:`Simulation`.

    One episode per maze in turn (cycling through ``mazes``), epsilon-greedy
    exploration from the controller's own seeded generator. Reaching the goal is
    terminal; the deadline (``deadline_factor * l`` steps) only cuts the episode,
    so the last step there still bootstraps from the next observation.

    The default short horizon (``gamma = 0.1``) is deliberate: the observation
    aliases many cells (every straight corridor looks the same), so long-horizon
    values blur across places, while the immediate penalties for collisions and
    backward steps, and the goal bonus, already single out the right move in
    every observation of a unicursive maze and next to clues.
    """
    if method not in TRAINING_METHODS:
        raise ControllerError(
            f"training method {method!r} is not one of {', '.join(TRAINING_METHODS)}"
        )
    episodes = check_integer("episodes", episodes, minimum=1, error=ControllerError)
    check_number("alpha", alpha, minimum=0, strict_minimum=True, maximum=1, error=ControllerError)
    _check_probability("gamma", gamma)
    items = [mazes] if isinstance(mazes, Maze | MazeSpec | str) else list(mazes)
    if not items:
        raise ControllerError("train_tabular needs at least one maze, got none")
    pool = [as_maze(m) for m in items]
    controller = TabularController(epsilon=epsilon, seed=seed)
    simulation = Simulation(pool[0], "DD", deadline_factor=deadline_factor)
    sarsa = method == "sarsa"
    for episode in range(episodes):
        simulation.reset(pool[episode % len(pool)])
        s = simulation.observe()
        a = controller.act(s)
        while not simulation.done():
            r = simulation.step(a)
            s_next = simulation.observe()
            done = simulation.success()
            a_next = controller.act(s_next)
            if sarsa:
                controller.sarsa_update(s, a, r, s_next, a_next, alpha, gamma, done)
            else:
                controller.q_learning_update(s, a, r, s_next, alpha, gamma, done)
            s, a = s_next, a_next
    return controller


# -----------------------------------------------------------------------------
# Factory


#: Entry-point group through which other packages load their saved agents by
#: file suffix (``zip = rl_baselines.agent_loader:load_agent``), so that the command
#: line runs them without ``amaze`` importing those packages.
AGENT_LOADERS = "amaze.agent_loaders"


def _agent_loader(path: str) -> Any | None:
    """The registered loader of saved agents with this file's suffix, if any."""
    from importlib.metadata import entry_points

    suffix = Path(path).suffix.lstrip(".").lower()
    if not suffix or suffix == "json":
        return None
    found = entry_points(group=AGENT_LOADERS, name=suffix)
    return next(iter(found)).load() if found else None


def make_controller(name: str, robot: Robot | str | None = None, *, seed: int = 0) -> Any:
    """The policy called ``name`` for ``robot``, for the command line.

    ``name`` is ``random`` (seeded with ``seed``), ``oracle``, the path of a
    tabular controller saved as JSON (which keeps its own seed; DD robots only),
    the path of an agent saved by another package that registers a loader
    for its file suffix (SB3 agents, ``.zip``, from ``rl_baselines``; evolved
    agents, ``.npz``, from ``evolution``), or a run folder (its agent).
    ``robot=None`` takes the robot a saved agent records (DD for ``random``
    and ``oracle``); a robot that the agent does not drive is refused, named
    as the user spelled it.
    """
    given = "DD" if robot is None else robot
    as_robot(given)  # a bad robot string is refused before any file is read
    if isinstance(name, str) and Path(name).is_dir():
        name = str(run_folder_agent(Path(name)))
    if name == "random":
        return RandomController(given, seed=seed)
    if name == "oracle":
        return OracleController(given)
    loader = _agent_loader(name) if isinstance(name, str) else None
    if loader is not None:
        if not Path(name).is_file():
            what = "is not a file" if Path(name).exists() else "does not exist"
            raise ControllerError(f"agent file '{name}' {what}")
        agent = _pointing_at_the_run_agent(name, loader)
        _check_agent_robot(name, getattr(agent, "robot", None), robot)
        return agent
    if isinstance(name, str) and (name.endswith(".json") or Path(name).is_file()):
        if robot is not None and as_robot(robot) != TabularController.robot:
            raise ControllerError(
                f"tabular controller '{name}' drives DD robots only, not {robot_name(robot)}"
            )
        return _pointing_at_the_run_agent(name, TabularController.load)
    raise ControllerError(
        f"unknown controller {name!r}: choose {', '.join(CONTROLLERS)},"
        " or the path of a saved agent (tabular .json, SB3 .zip with rl_baselines,"
        " evolved .npz with evolution)"
    )


def run_folder_agent(folder: Path) -> Path:
    """The agent file of the run folder ``folder`` (its ``summary.json``'s ``agent``).

    A folder that is not a run, a run that has not finished, or a folder of
    replicates (``seed-<s>/`` runs) raises :class:`ControllerError` saying
    which agent file to give instead.
    """
    if not (folder / "config.json").is_file():
        seeds = sorted(p.name for p in folder.glob("seed-*") if (p / "config.json").is_file())
        if seeds:
            shown = ", ".join(seeds[:3]) + (", ..." if len(seeds) > 3 else "")
            raise ControllerError(
                f"'{folder}' holds replicates ({shown}), one agent each: give one run's folder"
                f" (such as '{folder / seeds[0]}')"
            )
        raise ControllerError(f"'{folder}' is a folder, not a run folder (it has no config.json)")
    agents = sorted(p for p in folder.glob("agent.*") if p.suffix in (".npz", ".zip"))
    if not agents:
        raise ControllerError(
            f"run folder '{folder}' has no agent yet: a run writes agent.npz or agent.zip"
            " when it finishes (resume it to finish it)"
        )
    return agents[0]


#: How far up from a file :func:`_run_agent_hint` looks for the run folder holding it.
_RUN_FOLDER_DEPTH = 6


def _pointing_at_the_run_agent(name: str, load: Any) -> Any:
    """``load(name)``; a file that is no agent but lies in a run folder names the run's agent.

    Run folders hold many files (checkpoints, learners, progress logs) and
    one agent, written at the top when the run finishes (``summary.json``'s
    ``agent``): an error on another file says where that one is.
    """
    try:
        return load(name)
    except AmazeError as error:
        hint = _run_agent_hint(Path(name))
        if not hint:
            raise
        raise type(error)(f"{error}; {hint}") from None


def _run_agent_hint(path: Path) -> str:
    """Where the agent of the run folder holding ``path`` is, if ``path`` is inside one."""
    for folder in list(path.resolve().parents)[:_RUN_FOLDER_DEPTH]:
        if not (folder / "config.json").is_file():
            continue
        for agent in sorted(folder.glob("agent.*")):
            if agent.suffix in (".npz", ".zip") and agent.resolve() != path.resolve():
                return f"it is not an agent file: the agent of the run '{folder}' is '{agent}'"
        return f"it is not an agent file: the run '{folder}' writes its agent when it finishes"
    return ""


def _check_agent_robot(
    name: str, agent_robot: Robot | str | None, robot: Robot | str | None
) -> None:
    """Refuse a robot that a saved agent does not drive (``None``: no robot asked or known)."""
    if agent_robot is None or robot is None:
        return
    drives = as_robot(agent_robot)
    if drives != as_robot(robot):
        raise ControllerError(
            f"agent '{name}' drives {drives.to_string()} robots, not {robot_name(robot)}:"
            f" pass --robot {drives.to_string()}"
        )


# -----------------------------------------------------------------------------
# Checks


def _bound_engine(
    engine: BatchEngine | None, observations: np.ndarray | None, kind: str, name: str
) -> BatchEngine:
    """The engine a controller is bound to, refused if none or if ``observations`` (when
    given) are not one per agent of it."""
    if engine is None:
        raise ControllerError(
            f"{kind} is not bound to an engine: call bind(engine) first"
            " (run_episodes and record_episode do)"
        )
    if observations is not None:
        n = _batch_size(observations)
        if n != engine.n_agents:
            raise ControllerError(
                f"{name} got {n} observations for an engine of {engine.n_agents} agents"
            )
    return engine


def _batch_size(observations: np.ndarray) -> int:
    shape = np.shape(observations)
    if len(shape) < 2:
        raise ControllerError(f"expected a batch of observations, got shape {shape}")
    return int(shape[0])


def _check_gain(gain: Any) -> float:
    return check_number(
        "steering gain", gain, minimum=0, strict_minimum=True, error=ControllerError
    )


def _check_damping(damping: Any) -> float:
    return check_number("steering damping", damping, minimum=0, error=ControllerError)


def _check_seed(seed: Any) -> int:
    return check_integer("seed", seed, minimum=0, error=ControllerError)


def _check_probability(name: str, value: Any) -> float:
    return check_number(name, value, minimum=0, maximum=1, error=ControllerError)


def _check_action(action: Any) -> int:
    direction = check_integer("action", action, error=ControllerError)
    if not 0 <= direction < N_ACTIONS:
        raise ControllerError(f"action {action!r} is not one of 0, 1, 2, 3 (E, N, W, S)")
    return direction


def _numbers(values: Any, count: int, limit: float | None = None) -> bool:
    """Whether ``values`` is a list of ``count`` finite numbers (a Q-table file's entry).

    ``limit`` bounds their magnitude (observations are stored as float32).
    """
    if not isinstance(values, list) or len(values) != count:
        return False
    low = None if limit is None else -limit
    try:
        for value in values:
            check_number("value", value, minimum=low, maximum=limit, error=ControllerError)
    except ControllerError:
        return False
    return True
