"""Batch engine: many agents in many mazes, stepped together in compiled code.

:class:`BatchEngine` runs ``n_agents`` independent episodes of one robot kind
(discrete, hybrid or continuous) on a list of mazes, possibly of different
sizes, with the exact step semantics of the reference ``Simulation.step``
(``AMAZE_REFERENCE.md`` §4.5): collision penalty -0.2 (no move in discrete
mode; a clamp, velocity kept, in continuous mode), time step ``-dt``, finish
bonus ``2l - 1`` when the goal is reached, backward step -0.1 when re-entering
the cell just left, deadline ``deadline_factor * l / dt`` steps. Observations
follow §5 (gray levels ``round(255 * x)`` for images), built from the tables of
:mod:`amaze.tables`.

Unlike the reference, stepping an agent whose episode ended is an error (the
reference paid the finish bonus again), unless ``auto_reset`` restarts it in
the same step (gymnasium's "same-step" autoreset: the returned observation is
the first one of the new episode, the last one of the old episode is in
``StepResult.final_observations``).

The hot loops are numba kernels parallel over agents; all per-agent state
lives in two arrays (integers and floats) so that the kernels stay small.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numba
import numpy as np

from amaze.errors import EpisodeEndedError
from amaze.maze import Maze
from amaze.rewards import (
    BACKWARD_PENALTY,
    COLLISION_PENALTY,
    DEFAULT_DEADLINE_FACTOR,
    RewardScheme,
    paper_reward,
    pretty_reward,
)
from amaze.robot import ACCELERATION_SCALE, INERTIAL_LOSS, RADIUS, Robot, as_robot
from amaze.tables import MazeTables, compile_mazes

__all__ = ["BatchEngine", "EpisodeEndedError", "EpisodeStatistics", "StepResult"]


# -----------------------------------------------------------------------------
# State layout (column indices, compile-time constants for numba)

# integer state, int64 (n_agents, 9)
_MAZE, _CI, _CJ, _PI, _PJ, _T, _STEPS, _COLL, _BACK = range(9)
_N_ISTATE = 9
# float state, float64 (n_agents, 5): position, velocity, cumulative reward
_X, _Y, _VX, _VY, _RET = range(5)
_N_FSTATE = 5
# per-maze integers, int64 (n_mazes, 8)
_OFF, _W, _H, _SI, _SJ, _EI, _EJ, _L = range(8)
# per-maze floats, float64 (n_mazes, 2)
_DEADLINE, _FINISH = range(2)
# episode statistics, int64 (n_agents, 4)
_EP_STEPS, _EP_COLL, _EP_BACK, _EP_SUCC = range(4)

_COLLISION = COLLISION_PENALTY
_BACKWARD = BACKWARD_PENALTY
_RADIUS = RADIUS
_DAMPING = 1 - INERTIAL_LOSS * 0.1  # continuous dt = 0.1, as in the reference
_ACC_SCALE = ACCELERATION_SCALE
_DT_CONTINUOUS = 0.1
_MIN_SPEED = min(0.01, ACCELERATION_SCALE / 2)


# -----------------------------------------------------------------------------
# Compiled helpers


@numba.njit(cache=True, inline="always")
def _wall(walls, off, h, i, j, d):
    return (walls[off + i * h + j] >> d) & 1


@numba.njit(cache=True, inline="always")
def _global_cell(k, ist, mint):
    """Index of agent ``k``'s cell in the concatenated per-cell tables."""
    m = ist[k, _MAZE]
    return mint[m, _OFF] + ist[k, _CI] * mint[m, _H] + ist[k, _CJ]


@numba.njit(cache=True, inline="always")
def _arrival_side(ci, cj, pi, pj):
    """Side (0..3) of the cell leading back to the previous cell, -1 if none."""
    dx = pi - ci
    dy = pj - cj
    if dy == 0:
        if dx == 1:
            return 0
        if dx == -1:
            return 2
    elif dx == 0:
        if dy == 1:
            return 1
        if dy == -1:
            return 3
    return -1  # same cell, or diagonal (the reference raises there)


@numba.njit(cache=True, inline="always")
def _reset_agent(k, ist, fst, mint):
    m = ist[k, _MAZE]
    si = mint[m, _SI]
    sj = mint[m, _SJ]
    ist[k, _CI] = si
    ist[k, _CJ] = sj
    ist[k, _PI] = si
    ist[k, _PJ] = sj
    ist[k, _T] = 0
    ist[k, _STEPS] = 0
    ist[k, _COLL] = 0
    ist[k, _BACK] = 0
    fst[k, _X] = si + 0.5
    fst[k, _Y] = sj + 0.5
    fst[k, _VX] = 0.0
    fst[k, _VY] = 0.0
    fst[k, _RET] = 0.0


@numba.njit(cache=True, inline="always")
def _account(k, collision, ni, nj, dt, ist, fst, mint, mflt, rewards, term, trunc):
    """Reward and bookkeeping of one step, in the reference's order (§4.5).

    Returns True when the episode ended (goal reached or deadline).
    """
    m = ist[k, _MAZE]
    ci = ist[k, _CI]
    cj = ist[k, _CJ]
    ppi = ist[k, _PI]
    ppj = ist[k, _PJ]
    t = ist[k, _T]
    reward = 0.0
    if collision:
        reward += _COLLISION
        ist[k, _COLL] += 1
    pi = ppi
    pj = ppj
    if ni != ci or nj != cj:
        pi = ci
        pj = cj
    reward += -dt
    ist[k, _STEPS] += 1
    success = ni == mint[m, _EI] and nj == mint[m, _EJ]
    deadline = mflt[m, _DEADLINE]
    if success or t >= deadline:
        reward += mflt[m, _FINISH]
    if (ppi != pi or ppj != pj) and ppi == ni and ppj == nj:
        reward += _BACKWARD
        ist[k, _BACK] += 1
    fst[k, _RET] += reward
    t += 1
    ist[k, _CI] = ni
    ist[k, _CJ] = nj
    ist[k, _PI] = pi
    ist[k, _PJ] = pj
    ist[k, _T] = t
    rewards[k] = reward
    failure = t >= deadline
    term[k] = success
    trunc[k] = failure
    return success or failure


@numba.njit(cache=True, inline="always")
def _record_end(k, success, ist, fst, ep_ret, ep_int):
    ep_ret[k] = fst[k, _RET]
    ep_int[k, _EP_STEPS] = ist[k, _STEPS]
    ep_int[k, _EP_COLL] = ist[k, _COLL]
    ep_int[k, _EP_BACK] = ist[k, _BACK]
    ep_int[k, _EP_SUCC] = success


@numba.njit(cache=True, inline="always")
def _observe_discrete(k, out, ist, mint, dobs):
    g = _global_cell(k, ist, mint)
    a = _arrival_side(ist[k, _CI], ist[k, _CJ], ist[k, _PI], ist[k, _PJ]) + 1
    for s in range(8):
        out[k, s] = dobs[g, a, s]


@numba.njit(cache=True, inline="always")
def _marker(side, v):
    """Row and column of the origin marker on ``side`` of a ``v x v`` tile."""
    half = v // 2
    if side == 0:
        return half, v - 1
    if side == 1:
        return 0, half
    if side == 2:
        return half, 0
    return v - 1, half


@numba.njit(cache=True, inline="always")
def _observe_tile(k, out, ist, mint, tiles):
    g = _global_cell(k, ist, mint)
    ci = ist[k, _CI]
    cj = ist[k, _CJ]
    v = out.shape[1]
    for r in range(v):
        for c in range(v):
            out[k, r, c] = tiles[g, r, c]
    side = _arrival_side(ci, cj, ist[k, _PI], ist[k, _PJ])
    if side >= 0:
        r, c = _marker(side, v)
        out[k, r, c] = 255


@numba.njit(cache=True, inline="always")
def _observe_window(k, out, ist, fst, mint, canvas, canvas_off):
    """The continuous observation (§5.3): a ``v x v`` window following the robot."""
    m = ist[k, _MAZE]
    x = fst[k, _X]
    y = fst[k, _Y]
    ci = int(x)
    cj = int(y)
    v = out.shape[1]
    dpx = int((x - ci - 0.5) * v)
    dpy = int((y - cj - 0.5) * v)
    h = mint[m, _H]
    cols = (mint[m, _W] + 2) * v
    r0 = (h - cj) * v - dpy
    c0 = (ci + 1) * v + dpx
    base = canvas_off[m] + r0 * cols + c0
    for r in range(v):
        row = base + r * cols
        for c in range(v):
            out[k, r, c] = canvas[row + c]
    side = _arrival_side(ci, cj, ist[k, _PI], ist[k, _PJ])
    if side >= 0:
        mr, mc = _marker(side, v)
        r = mr + dpy
        c = mc - dpx
        if 0 <= r < v and 0 <= c < v:
            out[k, r, c] = 255


@numba.njit(cache=True, inline="always")
def _grid_move(k, a, ist, mint, walls):
    """Discrete move (§4.3): the new cell and whether the robot bumped into a wall."""
    m = ist[k, _MAZE]
    ci = ist[k, _CI]
    cj = ist[k, _CJ]
    if _wall(walls, mint[m, _OFF], mint[m, _H], ci, cj, a):
        return ci, cj, True
    if a == 0:
        return ci + 1, cj, False
    if a == 1:
        return ci, cj + 1, False
    if a == 2:
        return ci - 1, cj, False
    return ci, cj - 1, False


@numba.njit(cache=True, inline="always")
def _continuous_move(k, ax, ay, ist, fst, mint, walls):
    """Continuous physics and wall handling (§4.4); returns whether it collided."""
    m = ist[k, _MAZE]
    off = mint[m, _OFF]
    w = mint[m, _W]
    h = mint[m, _H]
    dt = _DT_CONTINUOUS
    accx = _ACC_SCALE * ax
    accy = _ACC_SCALE * ay
    vx = _DAMPING * fst[k, _VX] + dt * accx
    vy = _DAMPING * fst[k, _VY] + dt * accy
    if np.sqrt(vx**2 + vy**2) < _MIN_SPEED:
        vx = 0.0
        vy = 0.0
    fst[k, _VX] = vx
    fst[k, _VY] = vy
    x = fst[k, _X] + dt * vx
    y = fst[k, _Y] + dt * vy
    x_ = x
    y_ = y
    i = int(x)
    j = int(y)
    r = _RADIUS
    o_w = x - i <= r
    o_e = i + 1 - x <= r
    o_s = y - j <= r
    o_n = j + 1 - y <= r

    if o_w:
        if _wall(walls, off, h, i, j, 2):
            x_ = i + r
    elif o_e:
        if _wall(walls, off, h, i, j, 0):
            x_ = i + 1 - r
    if o_s:
        if _wall(walls, off, h, i, j, 3):
            y_ = j + r
    elif o_n:
        if _wall(walls, off, h, i, j, 1):
            y_ = j + 1 - r

    corner = False
    cx = 0.0
    cy = 0.0
    if o_w and o_s and i > 0 and j > 0:
        corner = (_wall(walls, off, h, i - 1, j, 3) | _wall(walls, off, h, i, j - 1, 2)) != 0
        cx, cy = float(i), float(j)
    elif o_w and o_n and i > 0 and j < h - 1:
        corner = (_wall(walls, off, h, i - 1, j, 1) | _wall(walls, off, h, i, j + 1, 2)) != 0
        cx, cy = float(i), float(j + 1)
    elif o_e and o_s and i < w - 1 and j > 0:
        corner = (_wall(walls, off, h, i + 1, j, 3) | _wall(walls, off, h, i, j - 1, 0)) != 0
        cx, cy = float(i + 1), float(j)
    elif o_e and o_n and i < w - 1 and j < h - 1:
        corner = (_wall(walls, off, h, i + 1, j, 1) | _wall(walls, off, h, i, j + 1, 0)) != 0
        cx, cy = float(i + 1), float(j + 1)
    if corner:
        dvx = cx - x
        dvy = cy - y
        d = np.sqrt(dvx**2 + dvy**2)
        pen = r - d
        if d < r:
            dvx = dvx / d
            dvy = dvy / d
            x_ -= dvx * pen
            y_ -= dvy * pen

    fst[k, _X] = x_
    fst[k, _Y] = y_
    return (x != x_) or (y != y_)


# -----------------------------------------------------------------------------
# Compiled kernels (one per robot kind)


@numba.njit(cache=True, parallel=True)
def _step_discrete(
    actions, ist, fst, mint, mflt, walls, dobs, auto_reset,
    obs, rewards, term, trunc, ended, final_obs, ep_ret, ep_int,
):  # fmt: skip
    for k in numba.prange(actions.shape[0]):
        ni, nj, collision = _grid_move(k, actions[k], ist, mint, walls)
        done = _account(k, collision, ni, nj, 1.0, ist, fst, mint, mflt, rewards, term, trunc)
        _observe_discrete(k, obs, ist, mint, dobs)
        ended[k] = done
        if done:
            _record_end(k, term[k], ist, fst, ep_ret, ep_int)
            for s in range(obs.shape[1]):
                final_obs[k, s] = obs[k, s]
            if auto_reset:
                _reset_agent(k, ist, fst, mint)
                _observe_discrete(k, obs, ist, mint, dobs)


@numba.njit(cache=True, parallel=True)
def _step_hybrid(
    actions, ist, fst, mint, mflt, walls, tiles, auto_reset,
    obs, rewards, term, trunc, ended, final_obs, ep_ret, ep_int,
):  # fmt: skip
    v = obs.shape[1]
    for k in numba.prange(actions.shape[0]):
        ni, nj, collision = _grid_move(k, actions[k], ist, mint, walls)
        done = _account(k, collision, ni, nj, 1.0, ist, fst, mint, mflt, rewards, term, trunc)
        ended[k] = done
        if done:
            _record_end(k, term[k], ist, fst, ep_ret, ep_int)
            _observe_tile(k, final_obs, ist, mint, tiles)
            if auto_reset:
                _reset_agent(k, ist, fst, mint)
                _observe_tile(k, obs, ist, mint, tiles)
            else:
                for r in range(v):
                    for c in range(v):
                        obs[k, r, c] = final_obs[k, r, c]
        else:
            _observe_tile(k, obs, ist, mint, tiles)


@numba.njit(cache=True, parallel=True)
def _step_continuous(
    actions, ist, fst, mint, mflt, walls, canvas, canvas_off, auto_reset,
    obs, rewards, term, trunc, ended, final_obs, ep_ret, ep_int,
):  # fmt: skip
    v = obs.shape[1]
    for k in numba.prange(actions.shape[0]):
        collision = _continuous_move(k, actions[k, 0], actions[k, 1], ist, fst, mint, walls)
        ni = int(fst[k, _X])
        nj = int(fst[k, _Y])
        done = _account(
            k, collision, ni, nj, _DT_CONTINUOUS, ist, fst, mint, mflt, rewards, term, trunc
        )
        ended[k] = done
        if done:
            _record_end(k, term[k], ist, fst, ep_ret, ep_int)
            _observe_window(k, final_obs, ist, fst, mint, canvas, canvas_off)
            if auto_reset:
                _reset_agent(k, ist, fst, mint)
                _observe_window(k, obs, ist, fst, mint, canvas, canvas_off)
            else:
                for r in range(v):
                    for c in range(v):
                        obs[k, r, c] = final_obs[k, r, c]
        else:
            _observe_window(k, obs, ist, fst, mint, canvas, canvas_off)


@numba.njit(cache=True, parallel=True)
def _reset_kernel(agents, ist, fst, mint):
    for n in numba.prange(agents.shape[0]):
        _reset_agent(agents[n], ist, fst, mint)


@numba.njit(cache=True, parallel=True)
def _observe_all_discrete(ist, mint, dobs, out):
    for k in numba.prange(out.shape[0]):
        _observe_discrete(k, out, ist, mint, dobs)


@numba.njit(cache=True, parallel=True)
def _observe_all_hybrid(ist, mint, tiles, out):
    for k in numba.prange(out.shape[0]):
        _observe_tile(k, out, ist, mint, tiles)


@numba.njit(cache=True, parallel=True)
def _observe_all_continuous(ist, fst, mint, canvas, canvas_off, out):
    for k in numba.prange(out.shape[0]):
        _observe_window(k, out, ist, fst, mint, canvas, canvas_off)


# -----------------------------------------------------------------------------
# Public API


@dataclass(frozen=True)
class EpisodeStatistics:
    """Statistics of the episodes that ended in one step, aligned with ``agents``.

    ``cumulative_reward`` is the reference's raw return ``R``; ``steps``,
    ``collisions``, ``backsteps`` its counters; ``success`` whether the goal was
    reached; ``path_length`` the maze's ``l``. :meth:`pretty_rewards` and
    :meth:`paper_rewards` give both normalised scores.
    """

    agents: np.ndarray
    cumulative_reward: np.ndarray
    steps: np.ndarray
    collisions: np.ndarray
    backsteps: np.ndarray
    success: np.ndarray
    path_length: np.ndarray
    dt: float
    deadline_factor: float

    def __len__(self) -> int:
        return int(self.agents.shape[0])

    def pretty_rewards(self) -> np.ndarray:
        """The reference's ``normalized_reward()`` (``pretty_reward``) of each episode."""
        return np.array(
            [
                pretty_reward(float(r), RewardScheme(int(l_), self.dt, self.deadline_factor))
                for r, l_ in zip(self.cumulative_reward, self.path_length, strict=True)
            ],
            dtype=np.float64,
        )

    def paper_rewards(self) -> np.ndarray:
        """The paper's normalised reward ``R̄`` of each episode (1 for an optimal run)."""
        return np.array(
            [
                paper_reward(bool(s), int(n), int(c), int(b), int(l_), self.dt)
                for s, n, c, b, l_ in zip(
                    self.success,
                    self.steps,
                    self.collisions,
                    self.backsteps,
                    self.path_length,
                    strict=True,
                )
            ],
            dtype=np.float64,
        )


@dataclass(frozen=True)
class StepResult:
    """What :meth:`BatchEngine.step` returns (all arrays are fresh).

    ``observations`` (n, ...): the observation of every agent after the step
    (the first of its new episode for an agent that was auto-reset);
    ``rewards`` float64 (n,); ``terminated`` (goal reached) and ``truncated``
    (deadline) bool (n,); ``final_observations`` (len(episodes), ...): the last
    observation of each episode that ended, aligned with ``episodes.agents``;
    ``episodes``: their statistics.
    """

    observations: np.ndarray
    rewards: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray
    final_observations: np.ndarray
    episodes: EpisodeStatistics

    @property
    def done(self) -> np.ndarray:
        """Agents whose episode ended in this step."""
        return self.terminated | self.truncated


class BatchEngine:
    """``n_agents`` agents of one robot kind in a list of mazes, stepped together.

    Agent ``k`` runs in maze ``assignment[k]`` (default ``k % len(mazes)``).
    Discrete and hybrid robots take actions ``0..3`` (E, N, W, S), int (n,);
    continuous robots take accelerations, float (n, 2), not clipped (as in the
    reference). Observations are float32 (n, 8) for discrete robots and uint8
    (n, v, v) images for hybrid and continuous ones.
    """

    def __init__(
        self,
        mazes: Sequence[Maze | str],
        robot: Robot | str,
        n_agents: int,
        *,
        assignment: np.ndarray | None = None,
        deadline_factor: float = DEFAULT_DEADLINE_FACTOR,
        auto_reset: bool = True,
    ) -> None:
        if n_agents < 1:
            raise ValueError(f"n_agents must be positive, got {n_agents}")
        self.robot = as_robot(robot)
        self.mazes = [m if isinstance(m, Maze) else Maze.from_string(m) for m in mazes]
        self.tables: MazeTables = compile_mazes(self.mazes, self.robot, deadline_factor)
        self.n_agents = int(n_agents)
        self.deadline_factor = float(deadline_factor)
        self.auto_reset = bool(auto_reset)
        self.kind = self.robot.kind
        self.dt = self.tables.dt
        t = self.tables
        self._mint = np.ascontiguousarray(
            np.stack(
                [
                    t.cell_offset,
                    t.width,
                    t.height,
                    t.start_ij[:, 0],
                    t.start_ij[:, 1],
                    t.end_ij[:, 0],
                    t.end_ij[:, 1],
                    t.path_length,
                ],
                axis=1,
            ).astype(np.int64)
        )
        self._mflt = np.ascontiguousarray(np.stack([t.deadline, t.finish], axis=1))
        n = self.n_agents
        self._ist = np.zeros((n, _N_ISTATE), dtype=np.int64)
        self._fst = np.zeros((n, _N_FSTATE), dtype=np.float64)
        self._ended = np.zeros(n, dtype=np.bool_)
        self._ep_ret = np.zeros(n, dtype=np.float64)
        self._ep_int = np.zeros((n, 4), dtype=np.int64)
        self._final = np.zeros((n, *self.observation_shape), dtype=self.observation_dtype)
        if assignment is None:
            assignment = np.arange(n) % len(self.mazes)
        self._ist[:, _MAZE] = self._check_assignment(assignment, n)
        self.reset()

    # -- description ----------------------------------------------------------

    @property
    def observation_shape(self) -> tuple[int, ...]:
        """Shape of one agent's observation: (8,) or (v, v)."""
        if self.robot.discrete_inputs:
            return (8,)
        return (self.tables.vision, self.tables.vision)

    @property
    def observation_dtype(self) -> type:
        return np.float32 if self.robot.discrete_inputs else np.uint8

    @property
    def assignment(self) -> np.ndarray:
        """Maze index of every agent (a copy)."""
        return self._ist[:, _MAZE].copy()

    @property
    def positions(self) -> np.ndarray:
        """float64 (n, 2): every robot's position (cell centre + offset in continuous mode)."""
        if self.kind == "continuous":
            return self._fst[:, [_X, _Y]].copy()
        return self._ist[:, [_CI, _CJ]].astype(np.float64) + 0.5

    @property
    def velocities(self) -> np.ndarray:
        """float64 (n, 2): every robot's velocity (zero for discrete actions)."""
        return self._fst[:, [_VX, _VY]].copy()

    @property
    def cells(self) -> np.ndarray:
        """int64 (n, 2): every robot's cell ``(i, j)``."""
        return self._ist[:, [_CI, _CJ]].copy()

    @property
    def timesteps(self) -> np.ndarray:
        """int64 (n,): steps taken in the current episode."""
        return self._ist[:, _T].copy()

    @property
    def cumulative_rewards(self) -> np.ndarray:
        """float64 (n,): return of the current episode so far."""
        return self._fst[:, _RET].copy()

    # -- episodes -------------------------------------------------------------

    def _check_assignment(self, assignment: np.ndarray, n: int) -> np.ndarray:
        a = np.asarray(assignment)
        if a.shape != (n,) or not np.issubdtype(a.dtype, np.integer):
            raise ValueError(f"assignment must be {n} integers, got shape {a.shape} {a.dtype}")
        if n and (a.min() < 0 or a.max() >= len(self.mazes)):
            raise ValueError(f"maze indices must be in [0, {len(self.mazes)})")
        return a.astype(np.int64)

    def reset(
        self, agents: np.ndarray | None = None, assignment: np.ndarray | None = None
    ) -> np.ndarray:
        """Start new episodes for ``agents`` (default: all) and return ALL observations.

        ``assignment`` (aligned with ``agents``) switches those agents to other mazes.
        """
        if agents is None:
            agents = np.arange(self.n_agents, dtype=np.int64)
        else:
            agents = np.asarray(agents)
            if agents.dtype == np.bool_:
                agents = np.flatnonzero(agents)
            agents = agents.astype(np.int64).ravel()
            if agents.size and (agents.min() < 0 or agents.max() >= self.n_agents):
                raise IndexError("agent index out of range")
        if assignment is not None:
            self._ist[agents, _MAZE] = self._check_assignment(assignment, agents.shape[0])
        _reset_kernel(agents, self._ist, self._fst, self._mint)
        self._ended[agents] = False
        return self.observe()

    def observe(self) -> np.ndarray:
        """The current observation of every agent (a fresh array)."""
        out = np.empty((self.n_agents, *self.observation_shape), dtype=self.observation_dtype)
        t = self.tables
        if self.kind == "discrete":
            _observe_all_discrete(self._ist, self._mint, t.discrete_obs, out)
        elif self.kind == "hybrid":
            _observe_all_hybrid(self._ist, self._mint, t.tiles, out)
        else:
            _observe_all_continuous(
                self._ist, self._fst, self._mint, t.canvas, t.canvas_offset, out
            )
        return out

    def step(self, actions: np.ndarray) -> StepResult:
        """Apply one action per agent; see :class:`StepResult`."""
        n = self.n_agents
        if not self.auto_reset and self._ended.any():
            raise EpisodeEndedError(
                f"agents {np.flatnonzero(self._ended)[:10].tolist()} ended their episode:"
                " reset them before stepping"
            )
        t = self.tables
        obs = np.empty((n, *self.observation_shape), dtype=self.observation_dtype)
        rewards = np.empty(n, dtype=np.float64)
        term = np.empty(n, dtype=np.bool_)
        trunc = np.empty(n, dtype=np.bool_)
        ended = self._ended
        if self.kind == "continuous":
            a = np.asarray(actions, dtype=np.float64)
            if a.shape != (n, 2):
                raise ValueError(f"continuous actions must have shape ({n}, 2), got {a.shape}")
            _step_continuous(
                a, self._ist, self._fst, self._mint, self._mflt, t.walls,
                t.canvas, t.canvas_offset, self.auto_reset,
                obs, rewards, term, trunc, ended, self._final, self._ep_ret, self._ep_int,
            )  # fmt: skip
        else:
            a = np.asarray(actions)
            if a.shape != (n,) or not np.issubdtype(a.dtype, np.integer):
                raise ValueError(f"discrete actions must be {n} integers, got {a.shape} {a.dtype}")
            if a.dtype != np.int64 and a.dtype != np.int8:
                a = a.astype(np.int64)
            if a.min() < 0 or a.max() > 3:
                raise ValueError("discrete actions must be in 0..3 (E, N, W, S)")
            kernel, table = (
                (_step_discrete, t.discrete_obs)
                if self.kind == "discrete"
                else (_step_hybrid, t.tiles)
            )
            kernel(
                a, self._ist, self._fst, self._mint, self._mflt, t.walls, table, self.auto_reset,
                obs, rewards, term, trunc, ended, self._final, self._ep_ret, self._ep_int,
            )  # fmt: skip
        if self.auto_reset:
            ended_idx = np.flatnonzero(ended)
            ended[:] = False
        else:
            ended_idx = np.flatnonzero(ended)
        return StepResult(
            observations=obs,
            rewards=rewards,
            terminated=term,
            truncated=trunc,
            final_observations=self._final[ended_idx],
            episodes=self._episodes(ended_idx),
        )

    def _episodes(self, idx: np.ndarray) -> EpisodeStatistics:
        ep = self._ep_int[idx]
        return EpisodeStatistics(
            agents=idx,
            cumulative_reward=self._ep_ret[idx],
            steps=ep[:, _EP_STEPS],
            collisions=ep[:, _EP_COLL],
            backsteps=ep[:, _EP_BACK],
            success=ep[:, _EP_SUCC].astype(np.bool_),
            path_length=self.tables.path_length[self._ist[idx, _MAZE]],
            dt=self.dt,
            deadline_factor=self.deadline_factor,
        )
