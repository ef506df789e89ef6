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
* :func:`paper_reward`: the paper's ``R̄`` (Table 2): +2 for reaching the goal,
  ``-dt/(l-1)`` per step, -0.01 per collision, -0.02 per backward step. An
  optimal run scores exactly 1; this is the score of the paper's result tables.
"""

from __future__ import annotations

from dataclasses import dataclass

TIMESTEP_PENALTY = -1.0  # times dt
COLLISION_PENALTY = -0.2
BACKWARD_PENALTY = -0.1
DEFAULT_DEADLINE_FACTOR = 4.0

PAPER_FINISH = 2.0
PAPER_COLLISION = -0.01
PAPER_BACKWARD = -0.02


@dataclass(frozen=True)
class RewardScheme:
    """The reward constants of one maze and time step."""

    path_length: int
    dt: float
    deadline_factor: float = DEFAULT_DEADLINE_FACTOR

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


def paper_reward(
    success: bool, steps: int, collisions: int, backsteps: int, path_length: int, dt: float
) -> float:
    """The paper's normalised cumulative reward ``R̄`` (1 for an optimal run)."""
    return (
        PAPER_FINISH * bool(success)
        - dt * steps / (path_length - 1)
        + PAPER_COLLISION * collisions
        + PAPER_BACKWARD * backsteps
    )
