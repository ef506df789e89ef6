"""Rewards: the per-step reward of the reference code and both normalised scores.

Per-step rewards (``docs/reference-behaviour.md`` §4.2, §4.5), with ``l`` the path length
and ``dt`` the time step (1 for discrete actions, 0.1 for continuous ones):

==========  =========  ==========================================
event       reward     note
==========  =========  ==========================================
time step   ``-dt``    every step
collision   ``-0.2``   bumping into a wall (once per step)
backward    ``-0.1``   re-entering the cell just left
finish      ``2l-1``   on the step that reaches the goal (not at the deadline)
==========  =========  ==========================================

An optimal discrete run earns ``R = l``. (The paper's Table 2 swaps the
collision and backward values; we keep the code's, which produced the
published runs.)

Two normalisations of an episode:

* :func:`pretty_reward`: the reference's ``normalized_reward()``, a linear
  rescale of ``R`` to [-1, 1] between the worst run and the optimal one, rounded
  to 3 decimals;
* :func:`normalized_reward`: the paper's ``R̄`` (Table 2): +2 for reaching the goal,
  ``-dt/(l-1)`` per step, -0.01 per collision, -0.02 per backward step. An
  optimal run scores exactly 1; this is the score of the paper's result tables.

The deadline factor is bounded (:func:`check_deadline_factor`): a finite number
in [:data:`MIN_DEADLINE_FACTOR`, :data:`MAX_DEADLINE_FACTOR`].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from amaze.errors import OptionError
from amaze.validation import check_integer, check_number

TIMESTEP_PENALTY = -1.0  # times dt
COLLISION_PENALTY = -0.2
BACKWARD_PENALTY = -0.1
DEFAULT_DEADLINE_FACTOR = 4.0
#: The smallest deadline factor: the deadline is then ``l / dt`` steps, time for the
#: optimal discrete path (``l - 1`` moves) and never less than one step.
MIN_DEADLINE_FACTOR = 1.0
#: The largest deadline factor, 250 times the default: even the longest path (the
#: 10^4 cells of a 100x100 maze) with continuous actions then gives a deadline of
#: 10^8 steps, which the engine's 32-bit step counters hold.
MAX_DEADLINE_FACTOR = 1000.0

PAPER_FINISH = 2.0
PAPER_COLLISION = -0.01
PAPER_BACKWARD = -0.02


def check_deadline_factor(value: object) -> float:
    """``value`` as a deadline factor: a finite number in [1, 1000], else :class:`OptionError`.

    Why these bounds:

    * NaN and infinities are refused: an infinite factor gives an episode that
      never ends for an agent that never reaches the goal, and NaN gives NaN
      normalised rewards (``"pretty_reward": NaN``, which is not JSON);
    * zero and negative factors are refused: the deadline would be reached
      before the first step (the environment refused that step), and the
      worst return ``minimal_reward`` would be positive, so that
      :func:`pretty_reward` left [-1, 1] (11 for a factor of -1);
    * the minimum is 1, not just above 0: below it, a deadline shorter than the
      optimal path makes the goal unreachable (the optimum that
      :func:`pretty_reward` maps to 1 could never be attained) and, once it is
      shorter than one step, the one step taken costs far more than
      ``minimal_reward`` assumes (a factor of 0.01 gives -1.45 on a 5x5 maze);
    * the maximum, :data:`MAX_DEADLINE_FACTOR`, keeps every deadline within
      the engine's step counters (the default, 4, is the paper's).

    An episode lasts ``ceil(deadline)`` steps, and :func:`pretty_reward`
    assumes ``deadline`` steps of the worst kind: when ``factor * l / dt`` is
    not a whole number, a run that bumps until the deadline still scores below
    -1 (``docs/reference-behaviour.md`` §4.7); with whole factors, discrete
    robots never do.
    """
    return check_number(
        "deadline_factor",
        value,
        minimum=MIN_DEADLINE_FACTOR,
        maximum=MAX_DEADLINE_FACTOR,
        error=OptionError,
    )


@dataclass(frozen=True)
class RewardScheme:
    """The reward constants of one maze and time step.

    ``path_length`` is a positive integer, ``dt`` a positive number and
    ``deadline_factor`` checked by :func:`check_deadline_factor`
    (:class:`~amaze.errors.OptionError` otherwise).

    >>> scheme = RewardScheme(path_length=10, dt=0.1)
    >>> scheme.finish, scheme.deadline, scheme.optimal_reward
    (19.0, 400.0, 10.0)
    """

    path_length: int
    dt: float
    deadline_factor: float = DEFAULT_DEADLINE_FACTOR

    def __post_init__(self) -> None:
        check_integer("path_length", self.path_length, minimum=1, error=OptionError)
        check_number("dt", self.dt, minimum=0.0, strict_minimum=True, error=OptionError)
        object.__setattr__(self, "deadline_factor", check_deadline_factor(self.deadline_factor))

    @property
    def timestep(self) -> float:
        return TIMESTEP_PENALTY * self.dt

    @property
    def collision(self) -> float:
        return COLLISION_PENALTY

    @property
    def backward(self) -> float:
        return BACKWARD_PENALTY

    @property
    def finish(self) -> float:
        return 2.0 * self.path_length - 1.0

    @property
    def deadline(self) -> float:
        """Number of steps after which the episode is truncated."""
        return self.deadline_factor * self.path_length / self.dt

    @property
    def optimal_reward(self) -> float:
        return float(self.path_length)

    @property
    def minimal_reward(self) -> float:
        """The reference's lower bound: every step a collision or a backward step."""
        worst = self.timestep + min(self.backward, self.collision)
        return self.deadline_factor * self.path_length * worst / self.dt


def pretty_reward(cumulative_reward: float, scheme: RewardScheme) -> float:
    """The reference's normalised reward: ``R`` rescaled to [-1, 1], 3 decimals."""
    r_max, r_min = scheme.optimal_reward, scheme.minimal_reward
    return round(2.0 * (cumulative_reward - r_min) / (r_max - r_min) - 1.0, 3)


def normalized_reward(
    success: bool, steps: int, collisions: int, backsteps: int, path_length: int, dt: float
) -> float:
    """The paper's normalised cumulative reward ``R̄`` (1 for an optimal run).

    >>> normalized_reward(True, steps=90, collisions=0, backsteps=0, path_length=10, dt=0.1)
    1.0
    >>> normalized_reward(True, steps=90, collisions=2, backsteps=0, path_length=10, dt=0.1)
    0.98
    """
    return (
        PAPER_FINISH * bool(success)
        - dt * steps / (path_length - 1)
        + PAPER_COLLISION * collisions
        + PAPER_BACKWARD * backsteps
    )


def pretty_rewards(
    cumulative_reward: np.ndarray, path_length: np.ndarray, dt: float, deadline_factor: float
) -> np.ndarray:
    """:func:`pretty_reward` of many episodes at once (the same floats, element by element)."""
    scheme = RewardScheme(1, dt, deadline_factor)  # checks dt and the deadline factor
    length = np.asarray(path_length, dtype=np.float64)
    worst = scheme.timestep + min(scheme.backward, scheme.collision)
    r_min = scheme.deadline_factor * length * worst / scheme.dt
    values = 2.0 * (np.asarray(cumulative_reward, dtype=np.float64) - r_min) / (length - r_min)
    return round_like_python(values - 1.0, 3)


def round_like_python(values: np.ndarray, decimals: int) -> np.ndarray:
    """Python's ``round(v, decimals)`` of every value: the same floats, in array code.

    ``numpy.round`` differs from it for some values (it rounds ``v * 10**decimals``,
    which carries a rounding error, instead of ``v``), and a loop of ``round``
    costs a third of a microsecond per value. Here ``rint(v * 10**d) / 10**d`` is
    exact (a correctly rounded quotient of two exact floats is the float nearest
    the decimal, as ``round`` gives) wherever the product's error cannot change
    which integer is nearest: everywhere but within a few ulps of a half-way
    point, and for non-finite or huge values, which go to ``round`` itself.
    """
    values = np.asarray(values, dtype=np.float64)
    if values.size < _FEW_VALUES:
        return np.array([round(v, decimals) for v in values.tolist()], dtype=np.float64)
    scale = 10.0**decimals
    scaled = values * scale
    nearest = np.rint(scaled)
    result = nearest / scale
    with np.errstate(invalid="ignore"):  # inf - inf: NaN, not sure
        margin = np.abs(np.abs(scaled - nearest) - 0.5)
    # the product's error is at most half an ulp, below |scaled| * 2**-52; from
    # |scaled| = 2**47 on, nothing is sure (nor are NaN and infinities)
    sure = margin > np.abs(scaled) * 2.0**-48
    if not sure.all():
        for k in np.flatnonzero(~sure).tolist():
            result.flat[k] = round(float(values.flat[k]), decimals)
    return result


# below this many values, a loop of round is faster than array code
_FEW_VALUES = 20


def normalized_rewards(
    success: np.ndarray,
    steps: np.ndarray,
    collisions: np.ndarray,
    backsteps: np.ndarray,
    path_length: np.ndarray,
    dt: float,
) -> np.ndarray:
    """:func:`normalized_reward` of many episodes at once (the same floats, element by element)."""
    return (
        PAPER_FINISH * np.asarray(success, dtype=bool).astype(np.float64)
        - dt * np.asarray(steps, dtype=np.float64) / (np.asarray(path_length, np.float64) - 1)
        + PAPER_COLLISION * np.asarray(collisions, dtype=np.float64)
        + PAPER_BACKWARD * np.asarray(backsteps, dtype=np.float64)
    )
