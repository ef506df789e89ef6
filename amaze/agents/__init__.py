"""Agents in mazes: robots, what they perceive, how they are rewarded, and how they move.

Above the maze core, below environments and evaluation:

* :mod:`~amaze.agents.robot`: robot strings (``DD``, ``H15``, ``CC15``);
* :mod:`~amaze.agents.actions`: the continuous-action contract (clip to [-1, 1],
  refuse NaN and infinities);
* :mod:`~amaze.agents.observations`: discrete inputs and cell images;
* :mod:`~amaze.agents.rewards`: the reference's rewards, ``pretty_reward`` and the paper's R̄;
* :mod:`~amaze.agents.simulation`: one agent, the readable definition;
* :mod:`~amaze.agents.tables`, :mod:`~amaze.agents.engine`: compiled per-cell tables
  and the batch engine (many agents x many mazes), cross-checked with the simulation;
* :mod:`~amaze.agents.trajectories`: pictures and animations of episodes.
* :mod:`~amaze.agents.agent_file`: the ``.npz`` + JSON format of saved agents (no pickle),
  shared by the trainers.

The batch engine imports numba; import it from :mod:`amaze.agents.engine`.
"""

from amaze.agents.rewards import RewardScheme, normalized_reward, pretty_reward
from amaze.agents.robot import Robot, as_robot
from amaze.agents.simulation import Simulation

__all__ = ["RewardScheme", "Robot", "Simulation", "as_robot", "normalized_reward", "pretty_reward"]
