"""Batch engine: many agents in many mazes, stepped together in compiled code.

:class:`BatchEngine` runs ``n_agents`` independent episodes of one robot kind
(discrete, hybrid or continuous) on a list of mazes, possibly of different
sizes, with the exact step semantics of the reference ``Simulation.step``
(``docs/reference-behaviour.md`` §4.5): collision penalty -0.2 (no move in discrete
mode; a clamp, velocity kept, in continuous mode), time step ``-dt``, finish
bonus ``2l - 1`` when the goal is reached, backward step -0.1 when re-entering
the cell just left, deadline ``deadline_factor * l / dt`` steps. Observations
follow §5 (gray levels ``round(255 * x)`` for images), built from the tables of
:mod:`amaze.agents.tables`.

Stepping an agent whose episode ended is an error, unless ``auto_reset``
restarts it in the same step (gymnasium's "same-step" autoreset: the returned
observation is the first of the new episode, the last of the old one is in
``StepResult.final_observations``).

Continuous actions follow :mod:`amaze.agents.actions`: finite accelerations are
clipped to [-1, 1], a NaN or an infinity is refused (:class:`~amaze.errors.ActionError`,
naming the agents). The differences from the reference are listed in
``docs/reference-behaviour.md`` §10.

The hot loops are numba kernels on one int32 and one float64 row of state per
agent; a discrete step is a look-up in the maze's neighbour table and a copy of
the cell's 8 floats, the outcome selected by bit masks rather than branches.
Whatever they are given, the kernels never index outside their arrays: they
clip accelerations themselves, apply a non-finite one as 0 and clamp every cell
coordinate to the maze (which changes nothing for legal actions but a robot
at full speed landing exactly on the east or north border, where the
reference indexed outside the maze too).

Kernels come in a serial and a parallel (``prange``) version, with identical
results. A parallel step pays a thread start-up and a barrier on every call,
and stalls whenever another process holds a core, so an engine with enough
work per step times both on its own calls and runs the faster
(:class:`~amaze.agents.kernel_choice.KernelChoice`); smaller batches run the
serial kernels. ``BatchEngine(parallel=True/False)`` fixes the choice.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NoReturn, TypeVar

import numba
import numpy as np

from amaze.agents.actions import continuous_actions, non_finite_actions_message
from amaze.agents.kernel_choice import KernelChoice
from amaze.agents.rewards import (
    BACKWARD_PENALTY,
    COLLISION_PENALTY,
    DEFAULT_DEADLINE_FACTOR,
    check_deadline_factor,
    normalized_rewards,
    pretty_rewards,
)
from amaze.agents.robot import (
    ACCELERATION_SCALE,
    CONTINUOUS_DT,
    INERTIAL_LOSS,
    MIN_SPEED,
    RADIUS,
    Robot,
    as_robot,
)
from amaze.agents.tables import MazeTables, compile_mazes
from amaze.errors import ActionError, EpisodeEndedError, OptionError
from amaze.maze.directions import OFFSETS
from amaze.maze.maze import Maze, as_maze
from amaze.maze.spec import MazeSpec
from amaze.validation import check_integer

__all__ = [
    "MAX_ENGINE_BYTES",
    "BatchEngine",
    "EndedEpisodes",
    "EpisodeEndedError",
    "StepResult",
    "agent_bytes",
    "check_n_agents",
    "max_agents",
]

_Dataclass = TypeVar("_Dataclass")


# -----------------------------------------------------------------------------
# Layout (column indices, compile-time constants for numba)

# per-agent integers, int32 (n_agents, 10): maze, global cell and arrival code
# (discrete and hybrid robots), step count, collisions, backward steps, current
# and previous cell (continuous robots)
_MAZE, _CELL, _ARR, _T, _COLL, _BACK, _CI, _CJ, _PI, _PJ = range(10)
_N_ISTATE = 10
# per-agent floats, float64 (n_agents, 5): position, velocity, cumulative reward
_X, _Y, _VX, _VY, _RET = range(5)
_N_FSTATE = 5
# per-maze integers, int64 (n_mazes, 11): cell offset, size, start and end as
# local (i, j), path length, start and end as global cells, and the deadline in
# whole steps (``ceil`` of the float deadline: for an integer step count ``t``,
# ``t >= deadline`` and ``t >= ceil(deadline)`` agree)
_OFF, _W, _H, _SI, _SJ, _EI, _EJ, _L, _START, _END, _DEADLINE_STEPS = range(11)
# per-maze floats, float64 (n_mazes, 2)
_DEADLINE, _FINISH = range(2)
# episode statistics of the ended episodes, int64 (5, n_agents), compact
_EP_AGENT, _EP_STEPS, _EP_COLL, _EP_BACK, _EP_LEN = range(5)
_N_EP_INT = 5

_INT64 = np.dtype(np.int64)

#: The engine refuses a number of agents whose arrays (:func:`agent_bytes` each)
#: would take more memory than this (16 GiB), before allocating anything.
MAX_ENGINE_BYTES = 16 * 2**30

# kernel status codes (a kernel returns the number of ended episodes, or one of these)
_BAD_ACTION = -1
_STEPPED_ENDED = -2

_COLLISION = COLLISION_PENALTY
_BACKWARD = BACKWARD_PENALTY
_RADIUS = RADIUS
_DAMPING = 1 - INERTIAL_LOSS * CONTINUOUS_DT  # continuous dt = 0.1, as in the reference
_ACC_SCALE = ACCELERATION_SCALE
_DT_CONTINUOUS = CONTINUOUS_DT
_MIN_SPEED = MIN_SPEED
_SQRT2 = np.sqrt(2.0)  # the corner-to-centre offset (±0.5, ±0.5) times it is a unit vector

#: The engine tries its parallel kernels from this much work per step (agents
#: times the relative cost of an agent-step, ``_WORK_PER_AGENT``): some 30 µs of
#: serial work, against a thread start-up and barrier of about 10 µs.
_PARALLEL_MIN_WORK = 4096
_WORK_PER_AGENT = {"discrete": 1, "hybrid": 8, "continuous": 16}


# -----------------------------------------------------------------------------
# Compiled helpers

#: Decorator of the serial kernels. They run without numba's reference counting
#: (they only index arrays they are given and allocate none): with it, every
#: array handed to an inlined helper is increfed and decrefed on each iteration
#: of the agent loop, which made a discrete step three times slower. (The
#: parallel kernels' loop bodies are compiled without those operations.)
_serial_kernel = numba.njit(cache=True, _nrt=False)


@numba.njit(cache=True, inline="always")
def _u(index):
    """An index known to be non-negative, as unsigned.

    Numba then skips the negative-index wraparound of each array access in the
    hot loops.
    """
    return numba.uint64(index)


@numba.njit(cache=True, inline="always")
def _wall(walls, off, h, i, j, d):
    return (walls[off + i * h + j] >> d) & 1


@numba.njit(cache=True, inline="always")
def _acceleration(a):
    """An acceleration component as the kernels apply it: clipped to [-1, 1], 0 if not finite.

    :meth:`BatchEngine.step` refuses non-finite actions before any kernel runs;
    this is the kernels' own guard, so that whatever reaches them (a NaN, an
    infinity, 1e308) can never move a robot out of its maze.
    """
    if a - a != 0.0:  # NaN or an infinity (x - x is 0 for every finite x)
        return 0.0
    if a > 1.0:
        return 1.0
    if a < -1.0:
        return -1.0
    return a


@numba.njit(cache=True, inline="always")
def _cell_index(x, n):
    """``int(x)`` clamped to ``0 .. n - 1`` (0 for NaN): a cell coordinate inside the maze.

    Positions stay inside the maze (the border walls hold the robot), but one
    at full speed against the east or north border can round to exactly ``n``.
    """
    if x >= n:
        return n - 1
    if x >= 1.0:
        return int(x)
    return 0


@numba.njit(cache=True, inline="always")
def _window_shift(f, v):
    """``int(f)`` clamped to ``[-v, v]`` (0 for NaN): how far a window moves, in pixels.

    Inside its cell a robot shifts its window by at most ``v / 2`` pixels; the
    canvas has a ``v`` pixel ring around the maze, so any clamped shift reads
    inside the canvas.
    """
    if f >= v:
        return v
    if f > -v:
        return int(f)
    if f <= -v:
        return -v
    return 0


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
    """Put agent ``k`` back at the start of its maze with fresh counters."""
    m = ist[k, _MAZE]
    si = mint[m, _SI]
    sj = mint[m, _SJ]
    ist[k, _CELL] = mint[m, _START]
    ist[k, _ARR] = 0
    ist[k, _CI] = si
    ist[k, _CJ] = sj
    ist[k, _PI] = si
    ist[k, _PJ] = sj
    fst[k, _X] = si + 0.5
    fst[k, _Y] = sj + 0.5
    fst[k, _VX] = 0.0
    fst[k, _VY] = 0.0
    ist[k, _T] = 0
    ist[k, _COLL] = 0
    ist[k, _BACK] = 0
    fst[k, _RET] = 0.0


@numba.njit(cache=True, inline="always")
def _check_ended(ended, auto_reset):
    """0 unless an agent whose episode ended would be stepped (without auto-reset)."""
    if not auto_reset:
        for k in range(ended.shape[0]):
            if ended[k]:
                return _STEPPED_ENDED
    return 0


@numba.njit(cache=True, inline="always")
def _check_discrete(actions, ended, auto_reset):
    """0 when no ended agent is stepped and every action is in 0..3, else a status code."""
    status = _check_ended(ended, auto_reset)
    bad = False
    for k in range(actions.shape[0]):
        bad |= (actions[k] < 0) | (actions[k] > 3)
    if bad and status == 0:
        return _BAD_ACTION
    return status


@numba.njit(cache=True, inline="always")
def _check_continuous(actions, ended, auto_reset):
    """0 when no ended agent is stepped and every acceleration is finite, else a status code."""
    status = _check_ended(ended, auto_reset)
    bad = False
    for k in range(actions.shape[0]):
        ax = actions[k, 0]
        ay = actions[k, 1]
        bad |= (ax - ax != 0.0) | (ay - ay != 0.0)
    if bad and status == 0:
        return _BAD_ACTION
    return status


@numba.njit(cache=True, inline="always")
def _grid_step(k, a, ist, fst, mint, mflt, neighbours, rewards, term, trunc):
    """One discrete move of agent ``k`` (§4.3, §4.5); True when its episode ended.

    Whether the move hits a wall, and whether it steps back into the cell just
    left, are coin flips for a random policy, so the move is computed without
    branching on them: ``blocked`` is -1 behind a wall and 0 otherwise, and
    selects between old and new values with bit masks (a branch there was
    mispredicted for every other agent, which cost more than the rest of the
    step). Only the end of an episode, rare, branches.

    The reward is summed in the reference's order (collision, time step,
    finish, backward step). A penalty that does not apply is added as a signed
    zero (``-0.2 * 0``), which leaves the float exactly as the reference's.
    """
    g = ist[k, _CELL]
    arrival = ist[k, _ARR]
    target = neighbours[_u(g), _u(a)]
    blocked = target >> 31  # -1 behind a wall (target -1), else 0
    cell = target + ((g - target) & blocked)  # a wall: no move
    turned = ((a + 2) & 3) + 1  # the arrival code after moving through side a
    backward = numba.int64(arrival == a + 1) & (blocked + 1)  # back into the cell just left
    ist[k, _CELL] = cell
    ist[k, _ARR] = turned + ((arrival - turned) & blocked)  # a wall: the arrival side stays
    ist[k, _COLL] -= blocked
    ist[k, _BACK] += backward
    m = _u(ist[k, _MAZE])
    tk = ist[k, _T]
    deadline = mint[m, _DEADLINE_STEPS]
    success = cell == mint[m, _END]
    reward = _COLLISION * -blocked + -1.0
    if success or tk >= deadline:
        reward += mflt[m, _FINISH]
    reward += _BACKWARD * backward
    tk += 1
    ist[k, _T] = tk
    fst[k, _RET] += reward
    rewards[k] = reward
    failure = tk >= deadline
    term[k] = success
    trunc[k] = failure
    return success | failure


@numba.njit(cache=True, inline="always")
def _observe_discrete(k, out, ist, rows):
    """The 8 floats of agent ``k``: its cell's row, 0.5 on the arrival side (§5.1).

    ``rows`` holds each cell's observation without the arrival mark (the
    arrival-0 rows of ``MazeTables.discrete_obs``; the arrival side is open, so
    its slot holds 0 there): a fifth of the full table, so that it stays in cache.
    """
    g = _u(ist[k, _CELL])
    r0, r1, r2, r3 = rows[g, 0], rows[g, 1], rows[g, 2], rows[g, 3]
    r4, r5, r6, r7 = rows[g, 4], rows[g, 5], rows[g, 6], rows[g, 7]
    out[k, 0], out[k, 1], out[k, 2], out[k, 3] = r0, r1, r2, r3
    out[k, 4], out[k, 5], out[k, 6], out[k, 7] = r4, r5, r6, r7
    arrival = ist[k, _ARR]
    if arrival > 0:
        out[k, arrival - 1] = 0.5


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
def _observe_tile(k, out, ist, tiles):
    """The ``v x v`` image of agent ``k``: its cell's tile and the origin marker (§5.2)."""
    g = _u(ist[k, _CELL])
    v = out.shape[1]
    for r in range(v):
        for c in range(v):
            out[k, r, c] = tiles[g, r, c]
    arrival = ist[k, _ARR]
    if arrival > 0:
        r, c = _marker(arrival - 1, v)
        out[k, r, c] = 255


@numba.njit(cache=True, inline="always")
def _observe_window(k, out, ist, fst, mint, canvas, canvas_off):
    """The continuous observation (§5.3): a ``v x v`` window following the robot."""
    m = ist[k, _MAZE]
    x = fst[k, _X]
    y = fst[k, _Y]
    h = mint[m, _H]
    ci = _cell_index(x, mint[m, _W])
    cj = _cell_index(y, h)
    v = out.shape[1]
    dpx = _window_shift((x - ci - 0.5) * v, v)
    dpy = _window_shift((y - cj - 0.5) * v, v)
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
def _continuous_move(k, ax, ay, ist, fst, mint, walls):
    """Continuous physics and wall handling (§4.4); returns whether it collided."""
    m = ist[k, _MAZE]
    off = mint[m, _OFF]
    w = mint[m, _W]
    h = mint[m, _H]
    dt = _DT_CONTINUOUS
    accx = _ACC_SCALE * _acceleration(ax)
    accy = _ACC_SCALE * _acceleration(ay)
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
    i = _cell_index(x, w)
    j = _cell_index(y, h)
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
            if d > 0.0:
                dvx = dvx / d
                dvy = dvy / d
            else:  # exactly on the wall end: away from it towards the cell's centre
                dvx = (cx - i - 0.5) * _SQRT2
                dvy = (cy - j - 0.5) * _SQRT2
            x_ -= dvx * pen
            y_ -= dvy * pen

    fst[k, _X] = x_
    fst[k, _Y] = y_
    return (x != x_) or (y != y_)


@numba.njit(cache=True, inline="always")
def _continuous_step(k, ax, ay, ist, fst, mint, mflt, walls, rewards, term, trunc):
    """One continuous step of agent ``k`` (§4.4, §4.5); True when its episode ended."""
    collision = _continuous_move(k, ax, ay, ist, fst, mint, walls)
    m = ist[k, _MAZE]
    ni = _cell_index(fst[k, _X], mint[m, _W])
    nj = _cell_index(fst[k, _Y], mint[m, _H])
    ci = ist[k, _CI]
    cj = ist[k, _CJ]
    ppi = ist[k, _PI]
    ppj = ist[k, _PJ]
    tk = ist[k, _T]
    reward = 0.0
    if collision:
        reward += _COLLISION
        ist[k, _COLL] += 1
    pi = ppi
    pj = ppj
    if ni != ci or nj != cj:
        pi = ci
        pj = cj
    reward += -_DT_CONTINUOUS
    success = ni == mint[m, _EI] and nj == mint[m, _EJ]
    deadline = mflt[m, _DEADLINE]
    if success or tk >= deadline:
        reward += mflt[m, _FINISH]
    if (ppi != pi or ppj != pj) and ppi == ni and ppj == nj:
        reward += _BACKWARD
        ist[k, _BACK] += 1
    tk += 1
    ist[k, _T] = tk
    ist[k, _CI] = ni
    ist[k, _CJ] = nj
    ist[k, _PI] = pi
    ist[k, _PJ] = pj
    fst[k, _RET] += reward
    rewards[k] = reward
    failure = tk >= deadline
    term[k] = success
    trunc[k] = failure
    return success or failure


@numba.njit(cache=True, inline="always")
def _record_end(k, count, ist, fst, mint, term, ep_int, ep_ret, ep_success):
    """Write the ended episode of agent ``k`` at row ``count`` of the compact buffers."""
    ep_int[_EP_AGENT, count] = k
    ep_int[_EP_STEPS, count] = ist[k, _T]
    ep_int[_EP_COLL, count] = ist[k, _COLL]
    ep_int[_EP_BACK, count] = ist[k, _BACK]
    ep_int[_EP_LEN, count] = mint[ist[k, _MAZE], _L]
    ep_ret[count] = fst[k, _RET]
    ep_success[count] = term[k]


@numba.njit(cache=True, inline="always")
def _copy_vector(dst, row, src, k):
    for s in range(src.shape[1]):
        dst[row, s] = src[k, s]


@numba.njit(cache=True, inline="always")
def _copy_image(dst, row, src, k):
    for r in range(src.shape[1]):
        for c in range(src.shape[2]):
            dst[row, r, c] = src[k, r, c]


# -----------------------------------------------------------------------------
# Compiled kernels (per robot kind, serial and parallel)
#
# Each returns the number of episodes that ended, or a negative status code, in
# which case no state was touched. The agents whose episode ended are listed in
# ``ep_int[_EP_AGENT, :count]``; the end of their episodes (statistics, last
# observation, reset) is handled after the loop over all agents, serially.


@numba.njit(cache=True, inline="always")
def _list_ended(term, trunc, ep_int):
    """List the agents whose episode ended (after a parallel loop); returns their number."""
    count = 0
    for k in range(term.shape[0]):
        if term[k] or trunc[k]:
            ep_int[_EP_AGENT, count] = k
            count += 1
    return count


@numba.njit(cache=True, inline="always")
def _end_discrete_episodes(
    count, auto_reset, ist, fst, ended, mint, rows, obs, term,
    ep_int, ep_ret, ep_success, final_obs,
):  # fmt: skip
    """Record and restart (or mark as ended) the listed episodes of discrete robots."""
    for i in range(count):
        k = ep_int[_EP_AGENT, i]
        _record_end(k, i, ist, fst, mint, term, ep_int, ep_ret, ep_success)
        _copy_vector(final_obs, i, obs, k)
        if auto_reset:
            _reset_agent(k, ist, fst, mint)
            _observe_discrete(k, obs, ist, rows)
        else:
            ended[k] = True


@numba.njit(cache=True, inline="always")
def _end_hybrid_episodes(
    count, auto_reset, ist, fst, ended, mint, tiles, obs, term,
    ep_int, ep_ret, ep_success, final_obs,
):  # fmt: skip
    """Record and restart (or mark as ended) the listed episodes of hybrid robots."""
    for i in range(count):
        k = ep_int[_EP_AGENT, i]
        _record_end(k, i, ist, fst, mint, term, ep_int, ep_ret, ep_success)
        _copy_image(final_obs, i, obs, k)
        if auto_reset:
            _reset_agent(k, ist, fst, mint)
            _observe_tile(k, obs, ist, tiles)
        else:
            ended[k] = True


@numba.njit(cache=True, inline="always")
def _end_continuous_episodes(
    count, auto_reset, ist, fst, ended, mint, canvas, canvas_off, obs, term,
    ep_int, ep_ret, ep_success, final_obs,
):  # fmt: skip
    """Record and restart (or mark as ended) the listed episodes of continuous robots."""
    for i in range(count):
        k = ep_int[_EP_AGENT, i]
        _record_end(k, i, ist, fst, mint, term, ep_int, ep_ret, ep_success)
        _copy_image(final_obs, i, obs, k)
        if auto_reset:
            _reset_agent(k, ist, fst, mint)
            _observe_window(k, obs, ist, fst, mint, canvas, canvas_off)
        else:
            ended[k] = True


@_serial_kernel
def _step_discrete(
    actions, ist, fst, ended, mint, mflt, neighbours, rows, auto_reset,
    obs, rewards, term, trunc, ep_int, ep_ret, ep_success, final_obs,
):  # fmt: skip
    status = _check_discrete(actions, ended, auto_reset)
    if status < 0:
        return status
    count = 0
    for k in range(actions.shape[0]):
        done = _grid_step(k, actions[k], ist, fst, mint, mflt, neighbours, rewards, term, trunc)
        _observe_discrete(k, obs, ist, rows)
        ep_int[_EP_AGENT, count] = k  # kept only if the episode ended: no branch here
        count += done
    _end_discrete_episodes(
        count, auto_reset, ist, fst, ended, mint, rows, obs, term,
        ep_int, ep_ret, ep_success, final_obs,
    )  # fmt: skip
    return count


@numba.njit(cache=True, parallel=True)
def _step_discrete_parallel(
    actions, ist, fst, ended, mint, mflt, neighbours, rows, auto_reset,
    obs, rewards, term, trunc, ep_int, ep_ret, ep_success, final_obs,
):  # fmt: skip
    status = _check_discrete(actions, ended, auto_reset)
    if status < 0:
        return status
    for k in numba.prange(actions.shape[0]):
        _grid_step(k, actions[k], ist, fst, mint, mflt, neighbours, rewards, term, trunc)
        _observe_discrete(k, obs, ist, rows)
    count = _list_ended(term, trunc, ep_int)
    _end_discrete_episodes(
        count, auto_reset, ist, fst, ended, mint, rows, obs, term,
        ep_int, ep_ret, ep_success, final_obs,
    )  # fmt: skip
    return count


@_serial_kernel
def _step_hybrid(
    actions, ist, fst, ended, mint, mflt, neighbours, tiles, auto_reset,
    obs, rewards, term, trunc, ep_int, ep_ret, ep_success, final_obs,
):  # fmt: skip
    status = _check_discrete(actions, ended, auto_reset)
    if status < 0:
        return status
    count = 0
    for k in range(actions.shape[0]):
        done = _grid_step(k, actions[k], ist, fst, mint, mflt, neighbours, rewards, term, trunc)
        _observe_tile(k, obs, ist, tiles)
        ep_int[_EP_AGENT, count] = k
        count += done
    _end_hybrid_episodes(
        count, auto_reset, ist, fst, ended, mint, tiles, obs, term,
        ep_int, ep_ret, ep_success, final_obs,
    )  # fmt: skip
    return count


@numba.njit(cache=True, parallel=True)
def _step_hybrid_parallel(
    actions, ist, fst, ended, mint, mflt, neighbours, tiles, auto_reset,
    obs, rewards, term, trunc, ep_int, ep_ret, ep_success, final_obs,
):  # fmt: skip
    status = _check_discrete(actions, ended, auto_reset)
    if status < 0:
        return status
    for k in numba.prange(actions.shape[0]):
        _grid_step(k, actions[k], ist, fst, mint, mflt, neighbours, rewards, term, trunc)
        _observe_tile(k, obs, ist, tiles)
    count = _list_ended(term, trunc, ep_int)
    _end_hybrid_episodes(
        count, auto_reset, ist, fst, ended, mint, tiles, obs, term,
        ep_int, ep_ret, ep_success, final_obs,
    )  # fmt: skip
    return count


@_serial_kernel
def _step_continuous(
    actions, ist, fst, ended, mint, mflt, walls, canvas, canvas_off, auto_reset,
    obs, rewards, term, trunc, ep_int, ep_ret, ep_success, final_obs,
):  # fmt: skip
    status = _check_continuous(actions, ended, auto_reset)
    if status < 0:
        return status
    count = 0
    for k in range(actions.shape[0]):
        done = _continuous_step(
            k, actions[k, 0], actions[k, 1], ist, fst, mint, mflt, walls, rewards, term, trunc
        )
        _observe_window(k, obs, ist, fst, mint, canvas, canvas_off)
        ep_int[_EP_AGENT, count] = k
        count += done
    _end_continuous_episodes(
        count, auto_reset, ist, fst, ended, mint, canvas, canvas_off, obs, term,
        ep_int, ep_ret, ep_success, final_obs,
    )  # fmt: skip
    return count


@numba.njit(cache=True, parallel=True)
def _step_continuous_parallel(
    actions, ist, fst, ended, mint, mflt, walls, canvas, canvas_off, auto_reset,
    obs, rewards, term, trunc, ep_int, ep_ret, ep_success, final_obs,
):  # fmt: skip
    status = _check_continuous(actions, ended, auto_reset)
    if status < 0:
        return status
    for k in numba.prange(actions.shape[0]):
        _continuous_step(
            k, actions[k, 0], actions[k, 1], ist, fst, mint, mflt, walls, rewards, term, trunc
        )
        _observe_window(k, obs, ist, fst, mint, canvas, canvas_off)
    count = _list_ended(term, trunc, ep_int)
    _end_continuous_episodes(
        count, auto_reset, ist, fst, ended, mint, canvas, canvas_off, obs, term,
        ep_int, ep_ret, ep_success, final_obs,
    )  # fmt: skip
    return count


@_serial_kernel
def _reset_kernel(agents, ist, fst, ended, mint):
    for n in range(agents.shape[0]):
        _reset_agent(agents[n], ist, fst, mint)
        ended[agents[n]] = False


@_serial_kernel
def _observe_all_discrete(ist, rows, out):
    for k in range(out.shape[0]):
        _observe_discrete(k, out, ist, rows)


@_serial_kernel
def _observe_all_hybrid(ist, tiles, out):
    for k in range(out.shape[0]):
        _observe_tile(k, out, ist, tiles)


@_serial_kernel
def _observe_all_continuous(ist, fst, mint, canvas, canvas_off, out):
    for k in range(out.shape[0]):
        _observe_window(k, out, ist, fst, mint, canvas, canvas_off)


# -----------------------------------------------------------------------------
# Public API


@dataclass(frozen=True)
class EndedEpisodes:
    """The episodes that ended in one :meth:`BatchEngine.step`, aligned with ``agents``.

    Only the agents whose episode ended in that step appear (often none), in
    the order of ``agents``; a whole run's scored episodes, one per agent, are
    gathered from successive steps into
    :class:`~amaze.evaluation.policy.EpisodeResults`, and the episode in
    progress of a :class:`~amaze.agents.simulation.Simulation` is counted by
    :class:`~amaze.agents.simulation.EpisodeCounters`.

    ``cumulative_reward`` is the reference's raw return ``R``; ``steps``,
    ``collisions``, ``backsteps`` its counters; ``success`` whether the goal was
    reached; ``path_length`` the maze's ``l``. :meth:`pretty_rewards` and
    :meth:`normalized_rewards` give both normalised scores.
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
        return pretty_rewards(
            self.cumulative_reward, self.path_length, self.dt, self.deadline_factor
        )

    def normalized_rewards(self) -> np.ndarray:
        """The paper's normalised reward ``R̄`` of each episode (1 for an optimal run)."""
        return normalized_rewards(
            self.success, self.steps, self.collisions, self.backsteps, self.path_length, self.dt
        )


@dataclass(frozen=True)
class StepResult:
    """What :meth:`BatchEngine.step` returns.

    Its arrays are fresh, the caller's to keep or change, except the empty
    ones of a step in which no episode ended (``final_observations`` and those
    of ``episodes``): they are shared between such steps, and read-only.

    ``observations`` (n, ...): the observation of every agent after the step
    (the first of its new episode for an agent that was auto-reset);
    ``rewards`` float64 (n,); ``terminated`` (goal reached) and ``truncated``
    (deadline) bool (n,); ``final_observations`` (len(episodes), ...): the last
    observation of each episode that ended, aligned with ``episodes.agents``;
    ``episodes``: those episodes (:class:`EndedEpisodes`).
    """

    observations: np.ndarray
    rewards: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray
    final_observations: np.ndarray
    episodes: EndedEpisodes

    @property
    def done(self) -> np.ndarray:
        """Agents whose episode ended in this step."""
        return self.terminated | self.truncated


def threads_may_pay_off(work: int, min_work: int = _PARALLEL_MIN_WORK) -> bool:
    """Whether multi-threaded numba kernels can beat serial ones at ``work`` per call at all.

    They need several numba threads and enough work (at least ``min_work``, in
    the caller's unit) to amortise a thread start-up and barrier per call.
    Whether they do beat them depends on the machine's load at the time; the
    engine finds out by timing both (:class:`~amaze.agents.kernel_choice.KernelChoice`).
    """
    return numba.get_num_threads() >= 2 and work >= min_work


def threads_pay_off(work: int, min_work: int = _PARALLEL_MIN_WORK) -> bool:
    """Whether multi-threaded numba kernels are the better default for ``work`` per call.

    :func:`threads_may_pay_off`, and idle cores: while other processes keep the
    cores busy (by the 1-minute load average, which counts this process too),
    a worker thread waits for a time slice at every barrier. The evolution
    package's batched policies decide once with this rule; the engine, whose
    steps are shorter, times both kernels instead.
    """
    if not threads_may_pay_off(work, min_work):
        return False
    try:
        load = os.getloadavg()[0]
    except (AttributeError, OSError):  # no load average on this platform
        return True
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return load < (cores or 1) - 0.5


def agent_bytes(robot: Robot | str) -> int:
    """About how many bytes the engine uses per agent of ``robot``.

    Its per-agent state (ten int32 and five float64 values, an "ended" flag), the
    compact buffers of ended episodes and their copies in a step, one step's
    actions, rewards and flags, and four observations: the buffer of last
    observations, the observations a step returns, its copy of the last
    observations of ended episodes, and those the caller still holds from the
    previous step. An observation is 8 float32 (discrete inputs) or ``v x v``
    bytes (images). Per-maze tables come on top but do not grow with agents.
    """
    robot = as_robot(robot)
    observation = 8 * 4 if robot.discrete_inputs else int(robot.vision) ** 2
    action = 8 if robot.discrete_outputs else 2 * 8
    state = _N_ISTATE * 4 + _N_FSTATE * 8 + 1
    ended_buffers = 2 * (_N_EP_INT * 8 + 8 + 1)
    step = action + 8 + 1 + 1
    return state + ended_buffers + step + 4 * observation


def max_agents(robot: Robot | str) -> int:
    """The largest number of agents of ``robot`` that one engine accepts.

    So many that their arrays (:func:`agent_bytes` each) fit in
    :data:`MAX_ENGINE_BYTES`: about 52 million ``DD``, 15 million ``CC15`` or
    one million ``H65`` agents.
    """
    return MAX_ENGINE_BYTES // agent_bytes(robot)


def check_n_agents(n_agents: object, robot: Robot | str, name: str = "n_agents") -> int:
    """``n_agents`` as an ``int`` in ``1 .. max_agents(robot)``, else :class:`OptionError`.

    Checked before anything is allocated: ``num_envs=10**12`` once asked numpy
    for 36 TiB. ``name`` is the option's name in the message (``num_envs`` for
    the vector environment).
    """
    robot = as_robot(robot)
    n = check_integer(name, n_agents, minimum=1, error=OptionError)
    limit = max_agents(robot)
    if n > limit:
        need = n * agent_bytes(robot) / 2**30
        raise OptionError(
            f"{name} {n} is too many for robot {robot}: the engine would need about"
            f" {need:,.0f} GiB, more than its {MAX_ENGINE_BYTES // 2**30} GiB limit"
            f" (at most {limit:,} agents)"
        )
    return n


def _build(cls: type[_Dataclass], **fields: object) -> _Dataclass:
    """An instance of the frozen dataclass ``cls`` with exactly its ``fields``.

    The generated ``__init__`` of a frozen dataclass sets each field through
    ``object.__setattr__``, which costs a few microseconds per engine step;
    filling the instance dictionary directly gives the same object.
    """
    instance = object.__new__(cls)
    instance.__dict__.update(fields)
    return instance


def _read_only(array: np.ndarray) -> np.ndarray:
    """``array``, made read-only: an empty result shared by many steps."""
    array.flags.writeable = False
    return array


def _maze_rows(tables: MazeTables) -> tuple[np.ndarray, np.ndarray]:
    """The per-maze rows that the step kernels read: int64 (m, 11) and float64 (m, 2).

    The integer row holds the maze's cell offset, size, start and end cells,
    path length and deadline in steps (columns ``_OFF`` ... ``_DEADLINE_STEPS``);
    the real row its deadline and finish reward (``_DEADLINE``, ``_FINISH``).
    """
    t = tables
    mint = np.ascontiguousarray(
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
                t.start,
                t.end,
                np.ceil(t.deadline).astype(np.int64),
            ],
            axis=1,
        ).astype(np.int64)
    )
    mflt = np.ascontiguousarray(np.stack([t.deadline, t.finish], axis=1))
    return mint, mflt


class BatchEngine:
    """``n_agents`` agents of one robot kind in a list of mazes, stepped together.

    ``mazes`` may be mazes, specs or maze strings (generated once, here).
    Agent ``k`` runs in maze ``assignment[k]`` (default ``k % len(mazes)``).
    Discrete and hybrid robots take actions ``0..3`` (E, N, W, S), int (n,);
    continuous robots take accelerations, real numbers (n, 2), clipped to the
    action space [-1, 1] (a NaN or an infinity is refused, see
    :mod:`amaze.agents.actions`). Observations are float32 (n, 8) for discrete
    robots and uint8 (n, v, v) images for hybrid and continuous ones.

    ``n_agents`` is an integer from 1 to :func:`max_agents` (the agents' arrays
    fit in :data:`MAX_ENGINE_BYTES`) and ``deadline_factor`` a number checked by
    :func:`~amaze.agents.rewards.check_deadline_factor`; both are checked before
    anything is allocated or generated (:class:`~amaze.errors.OptionError`).

    ``parallel`` True or False fixes the kernel family (multi-threaded or
    serial); by default (``None``) an engine whose batch is large enough for
    threads to pay off, when numba has several threads, times both families
    and runs the faster (:attr:`kernel_choice`, see the module docstring).
    Both give identical results.

    ``tables`` are the mazes' compiled tables when the caller has them already
    (:func:`~amaze.agents.tables.compile_mazes` of the same mazes, robot and
    deadline factor): engines of several sizes, or on several workers, then
    share one compilation (give the mazes as :class:`~amaze.maze.Maze` objects
    then, or they are generated again). Tables made for another robot, deadline
    factor or number of mazes are refused.
    """

    def __init__(
        self,
        mazes: Sequence[Maze | MazeSpec | str],
        robot: Robot | str,
        n_agents: int,
        *,
        assignment: np.ndarray | None = None,
        deadline_factor: float = DEFAULT_DEADLINE_FACTOR,
        auto_reset: bool = True,
        parallel: bool | None = None,
        tables: MazeTables | None = None,
    ) -> None:
        self.robot = as_robot(robot)
        self.n_agents = check_n_agents(n_agents, self.robot)
        self.deadline_factor = check_deadline_factor(deadline_factor)
        self.mazes = [as_maze(m) for m in mazes]
        self.tables: MazeTables = self._matching_tables(tables)
        self.auto_reset = bool(auto_reset)
        self.kind = self.robot.kind
        self.dt = self.tables.dt
        self._mint, self._mflt = _maze_rows(self.tables)
        self._allocate_agent_state()
        self._choose_kernels(parallel)
        self._build_empty_results()
        if assignment is None:
            assignment = np.arange(self.n_agents) % len(self.mazes)
        self._ist[:, _MAZE] = self._check_assignment(assignment, self.n_agents)
        self.reset()

    def _matching_tables(self, tables: MazeTables | None) -> MazeTables:
        """The mazes' compiled tables: ``tables`` when they fit, compiled here when absent.

        Tables given by the caller (shared between engines) must be of this
        engine's robot, deadline factor and number of mazes, or the steps would
        read another maze's walls: they are refused (:class:`OptionError`).
        """
        if tables is None:
            return compile_mazes(self.mazes, self.robot, self.deadline_factor)
        if (tables.robot, tables.deadline_factor, tables.n_mazes) != (
            self.robot, self.deadline_factor, len(self.mazes),
        ):  # fmt: skip
            raise OptionError(
                f"the tables are of {tables.n_mazes} mazes for robot {tables.robot} with deadline"
                f" factor {tables.deadline_factor}, not of {len(self.mazes)} for {self.robot}"
                f" with {self.deadline_factor}"
            )
        return tables

    def _allocate_agent_state(self) -> None:
        """Allocate the agents' state arrays and the buffers that a step fills.

        The integer and real states hold every agent's cell, clock and
        counters; the compact episode buffers collect the episodes that end in
        one step, which :meth:`step` copies out.
        """
        n = self.n_agents
        self._ist = np.zeros((n, _N_ISTATE), dtype=np.int32)
        self._fst = np.zeros((n, _N_FSTATE), dtype=np.float64)
        self._ended = np.zeros(n, dtype=np.bool_)
        self._obs_shape = (n, *self.observation_shape)
        self._action_shape = (n,)
        self._obs_dtype = self.observation_dtype
        # compact buffers of the episodes that end in one step (copied out by step)
        self._ep_int = np.zeros((_N_EP_INT, n), dtype=np.int64)
        self._ep_ret = np.zeros(n, dtype=np.float64)
        self._ep_success = np.zeros(n, dtype=np.bool_)
        self._final = np.zeros(self._obs_shape, dtype=self._obs_dtype)

    def _choose_kernels(self, parallel: bool | None) -> None:
        """Pick the robot kind's step kernels and the maze tables they read.

        A batch too small for threads to pay off runs the serial kernel
        without timing; otherwise ``parallel`` (or the timing, when ``None``)
        decides (:attr:`kernel_choice`).
        """
        t = self.tables
        if parallel is None and not threads_may_pay_off(self.n_agents * _WORK_PER_AGENT[self.kind]):
            parallel = False
        if self.kind == "discrete":
            kernels = (_step_discrete, _step_discrete_parallel)
            self._tables_args = (t.neighbours, np.ascontiguousarray(t.discrete_obs[:, 0]))
        elif self.kind == "hybrid":
            kernels = (_step_hybrid, _step_hybrid_parallel)
            self._tables_args = (t.neighbours, t.tiles)
        else:
            kernels = (_step_continuous, _step_continuous_parallel)
            self._tables_args = (t.walls, t.canvas, t.canvas_offset)
        #: The step kernel: serial or parallel, chosen by timing unless ``parallel`` says which.
        self.kernel_choice = KernelChoice(*kernels, parallel)

    def _build_empty_results(self) -> None:
        """Build what a step in which no episode ended returns besides its four arrays.

        Read-only empty arrays, made once and shared by every such step.
        """
        no_ints = _read_only(np.zeros((_N_EP_INT, 0), dtype=np.int64))
        self._no_episodes = _build(
            EndedEpisodes,
            agents=no_ints[_EP_AGENT],
            cumulative_reward=_read_only(np.zeros(0, dtype=np.float64)),
            steps=no_ints[_EP_STEPS],
            collisions=no_ints[_EP_COLL],
            backsteps=no_ints[_EP_BACK],
            success=_read_only(np.zeros(0, dtype=np.bool_)),
            path_length=no_ints[_EP_LEN],
            dt=self.dt,
            deadline_factor=self.deadline_factor,
        )
        self._no_final = _read_only(np.zeros((0, *self.observation_shape), self._obs_dtype))

    # -- description ----------------------------------------------------------

    @property
    def parallel(self) -> bool:
        """Whether the next step runs the parallel kernel (see :attr:`kernel_choice`)."""
        return self.kernel_choice.parallel

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
        return self._ist[:, _MAZE].astype(np.int64)

    @property
    def cells(self) -> np.ndarray:
        """int64 (n, 2): every robot's cell ``(i, j)``."""
        if self.kind == "continuous":
            return self._ist[:, [_CI, _CJ]].astype(np.int64)
        maze = self._ist[:, _MAZE]
        local = self._ist[:, _CELL].astype(np.int64) - self._mint[maze, _OFF]
        height = self._mint[maze, _H]
        return np.stack([local // height, local % height], axis=1)

    @property
    def arrival_sides(self) -> np.ndarray:
        """int64 (n,): the side (0..3, E N W S) of every robot's cell it came in by, -1 if none.

        The side an image robot's origin marker is drawn on: discrete and
        hybrid robots keep it through a step into a wall; a continuous robot's
        is the side of the cell it was in before (none in its start cell).
        """
        if self.kind != "continuous":
            return self._ist[:, _ARR].astype(np.int64) - 1
        di = self._ist[:, _PI].astype(np.int64) - self._ist[:, _CI]
        dj = self._ist[:, _PJ].astype(np.int64) - self._ist[:, _CJ]
        sides = np.full(self.n_agents, -1, dtype=np.int64)
        for side, (oi, oj) in enumerate(OFFSETS):
            sides[(di == oi) & (dj == oj)] = side
        return sides

    @property
    def positions(self) -> np.ndarray:
        """float64 (n, 2): every robot's position (cell centre + offset in continuous mode)."""
        if self.kind == "continuous":
            return self._fst[:, [_X, _Y]].copy()
        return self.cells.astype(np.float64) + 0.5

    @property
    def velocities(self) -> np.ndarray:
        """float64 (n, 2): every robot's velocity (zero for discrete actions)."""
        return self._fst[:, [_VX, _VY]].copy()

    @property
    def timesteps(self) -> np.ndarray:
        """int64 (n,): steps taken in the current episode."""
        return self._ist[:, _T].astype(np.int64)

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
        return a.astype(np.int32)

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
        _reset_kernel(agents, self._ist, self._fst, self._ended, self._mint)
        return self.observe()

    def observe(self) -> np.ndarray:
        """The current observation of every agent (a fresh array)."""
        out = np.empty(self._obs_shape, dtype=self._obs_dtype)
        t = self.tables
        if self.kind == "discrete":
            _observe_all_discrete(self._ist, self._tables_args[1], out)
        elif self.kind == "hybrid":
            _observe_all_hybrid(self._ist, t.tiles, out)
        else:
            _observe_all_continuous(
                self._ist, self._fst, self._mint, t.canvas, t.canvas_offset, out
            )
        return out

    def step(self, actions: np.ndarray) -> StepResult:
        """Apply one action per agent; see :class:`StepResult`.

        Raises :class:`~amaze.errors.ActionError` for actions of the wrong shape
        or type, discrete actions out of 0..3 and accelerations holding a NaN
        or an infinity (finite ones are clipped to [-1, 1]), and
        :class:`EpisodeEndedError` for an agent whose episode ended (without
        auto-reset); the state is then unchanged.
        """
        n = self.n_agents
        if self.kind == "continuous":
            a = continuous_actions(actions, n)
        else:
            try:
                a = np.asarray(actions)
            except (TypeError, ValueError):  # ragged lists and the like
                a = np.empty(0, dtype=object)
            if a.dtype != _INT64 or a.shape != self._action_shape:
                if a.shape != self._action_shape or not np.issubdtype(a.dtype, np.integer):
                    raise ActionError(
                        f"discrete actions must be {n} integers, got {a.shape} {a.dtype}"
                    )
                a = a.astype(np.int64)
        obs = np.empty(self._obs_shape, dtype=self._obs_dtype)
        rewards = np.empty(n, dtype=np.float64)
        term = np.empty(n, dtype=np.bool_)
        trunc = np.empty(n, dtype=np.bool_)
        count = self.kernel_choice(
            a, self._ist, self._fst, self._ended, self._mint, self._mflt, *self._tables_args,
            self.auto_reset,
            obs, rewards, term, trunc, self._ep_int, self._ep_ret, self._ep_success, self._final,
        )  # fmt: skip
        if count < 0:
            self._refuse(count, a)
        if count == 0:
            final, episodes = self._no_final, self._no_episodes
        else:
            ints = self._ep_int[:, :count].copy()
            final = self._final[:count].copy()
            episodes = _build(
                EndedEpisodes,
                agents=ints[_EP_AGENT],
                cumulative_reward=self._ep_ret[:count].copy(),
                steps=ints[_EP_STEPS],
                collisions=ints[_EP_COLL],
                backsteps=ints[_EP_BACK],
                success=self._ep_success[:count].copy(),
                path_length=ints[_EP_LEN],
                dt=self.dt,
                deadline_factor=self.deadline_factor,
            )
        return _build(
            StepResult,
            observations=obs,
            rewards=rewards,
            terminated=term,
            truncated=trunc,
            final_observations=final,
            episodes=episodes,
        )

    def _refuse(self, status: int, actions: np.ndarray) -> NoReturn:
        """Raise the error a kernel reported (it changed no state)."""
        if status == _BAD_ACTION:
            if self.kind == "continuous":
                raise ActionError(non_finite_actions_message(actions))
            bad = np.flatnonzero((actions < 0) | (actions > 3))
            raise ActionError(
                "discrete actions must be in 0..3 (E, N, W, S): agents"
                f" {bad[:10].tolist()} got {actions[bad[:10]].tolist()}"
            )
        raise EpisodeEndedError(
            f"agents {np.flatnonzero(self._ended)[:10].tolist()} ended their episode:"
            " reset them before stepping"
        )
