"""Slipping robots: a training episode's actions replaced, now and then, by random ones.

With ``slip`` p, every step of every training episode the robot *slips* with
probability p: its action is replaced by one drawn uniformly from the four
(E, N, W, S), as on FrozenLake's slippery ice. A slip may walk the robot into
a wall, into a side branch or back the way it came; the network must then
find its way on from where it stands.

Why: in a maze played from its start, a memoryless agent that never errs
never enters a cell of the solution path from the goal's side, so the
situation "a clue pointing back the way I came" never arises, and nothing
selects the right answer there (follow the clue). Most of the input-recognition
errors of co-evolved DD agents are exactly these. Slips put agents off the
path, and the agents that read the clues back to it reach the goal sooner.
The agents never see the input-recognition inputs: they only play mazes. At
600 M env steps, 5 seeds, slips of 0.3 lift co-evolution's median input
recognition from 0.914 to 1.000; at 20 s they cost suite success, so they
are off by default (docs/regimes/coevolution.md, "Measured").

**Common random numbers.** The slips of a generation are drawn per *episode*
(maze and rotation) and step, not per agent: every individual playing
episode m slips at the same steps and its slips take the same actions.
Individuals are compared under the same luck, and a population cut into parts
(:meth:`SlippingPopulation.subset`, as the Ray backend does) slips exactly as
the whole. The draws come from ``numpy.random.default_rng(seed)``, a fresh
generator at each ``reset``: the co-evolution loop seeds generation ``g`` of
a run of seed ``s`` with ``(s, g)``, so a resumed run slips as one never
interrupted.

Validation (the champion's choice), the suite, the unseen mazes and input
recognition are played without slips.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from amaze.evaluation.controllers import N_ACTIONS  # E, N, W, S: what a slip draws from
from amaze.validation import check_number
from evolution import EvolutionConfigError
from evolution.population import PopulationPolicy

__all__ = ["SlippingPopulation", "check_slip"]


def check_slip(value: object) -> float:
    """``value`` as a slip probability in [0, 1), or :class:`EvolutionConfigError` naming it."""
    slip = check_number("slip", value, minimum=0, error=EvolutionConfigError)
    if slip >= 1:
        raise EvolutionConfigError(f"slip {value!r} must be below 1 (1: every action random)")
    return float(slip)


class SlippingPopulation:
    """``population`` whose actions slip with probability ``probability`` (module docstring).

    A population policy of :mod:`evolution.population` itself: ``P``
    individuals, ``M = n_agents // P`` episodes each, agent ``k`` in episode
    ``k % M``. ``seed`` is anything :func:`numpy.random.default_rng` takes
    (ints or a tuple of ints); the same seed gives the same slips.
    """

    def __init__(
        self, population: PopulationPolicy | Any, probability: float, seed: int | Sequence[int]
    ) -> None:
        robot = getattr(population, "robot", None)
        if robot is None or not robot.discrete_outputs:
            raise EvolutionConfigError(f"slips need a robot with discrete actions, not {robot}")
        self.population = population
        self.probability = check_slip(probability)
        self.seed = seed
        self.robot = robot
        self.n_policies = int(getattr(population, "n_policies", 1))
        self._episodes = 0
        self._rng: np.random.Generator | None = None

    def __len__(self) -> int:
        return self.n_policies

    def __repr__(self) -> str:
        return f"SlippingPopulation({self.population!r}, {self.probability}, seed={self.seed})"

    def subset(self, indices: Sequence[int] | np.ndarray) -> SlippingPopulation:
        """Individuals ``indices``, slipping as they do in the whole population."""
        return SlippingPopulation(self.population.subset(indices), self.probability, self.seed)

    def reset(self, n_agents: int) -> None:
        """Start a run: the slips start again from the seed."""
        self.population.reset(n_agents)
        self._episodes = int(n_agents) // self.n_policies
        self._rng = np.random.default_rng(self.seed)

    def retire(self, agents: np.ndarray) -> None:
        """Pass the retirements on (a slipped action of a retired agent is never scored)."""
        retire = getattr(self.population, "retire", None)
        if callable(retire):
            retire(agents)

    def __call__(self, observations: np.ndarray) -> np.ndarray:
        """The population's actions, those of the step's slipping episodes replaced."""
        if self._rng is None:
            raise EvolutionConfigError("a slipping population plays from a reset(n_agents)")
        actions = np.asarray(self.population(observations))
        slips = self._rng.random(self._episodes) < self.probability
        drawn = self._rng.integers(0, N_ACTIONS, self._episodes)
        by_individual = actions.reshape(self.n_policies, self._episodes)  # (P, M): rows share slips
        return np.where(slips, drawn, by_individual).astype(actions.dtype).reshape(-1)
