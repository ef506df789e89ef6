"""amaze: reference-compatible AMaze mazes, agents in them, and how agents are scored.

Quick start::

    from amaze import Maze
    maze = Maze.from_string("M4_20x20_C1_l.25_L.25_t.5_T.5")
    maze.stats(), maze.maze_class.label

The same string gives the same maze as amaze-benchmarker 1.0 (walls, solution
and placed signs); ``docs/reference-behaviour.md`` lists every deliberate
difference. Importing the package registers the gymnasium environment
``AMaze-v0``.

The package is layered (``docs/architecture.md``); each layer may import only
the layers below it, and ``make test`` checks that:

* :mod:`amaze.maze`: maze strings, generation, signs, metrics, pictures;
* :mod:`amaze.agents`: robots, observations, rewards, the simulation, the batch engine;
* :mod:`amaze.envs`: the gymnasium environment and its native vector env;
* :mod:`amaze.evaluation`: the policy protocol, controllers, input recognition,
  the evaluation suite and protocol;
* :mod:`amaze.curriculum`: which mazes an agent meets, stage after stage;
* :mod:`amaze.runs`: run folders and the training-command skeleton;
* :mod:`amaze.cli`: the ``amaze`` command.

The names most used are importable from ``amaze`` itself; the heavier modules
behind some of them (the batch engine, the evaluation protocol, the metrics)
are loaded on first use.
"""

from importlib import import_module
from typing import Any

from amaze.errors import AmazeError, MazeStringError, MazeStringWarning, SignError
from amaze.maze import (
    Direction,
    Maze,
    MazeClass,
    MazeSpec,
    PlacedSign,
    Sign,
    SignKind,
    StartLocation,
    register_custom_signs,
    rotations,
)

__version__ = "0.1.0"

#: Names importable from ``amaze`` whose modules load on first use.
_LAZY = {
    "BatchEngine": "amaze.agents.engine",
    "Simulation": "amaze.agents.simulation",
    "as_robot": "amaze.agents.robot",
    "Evaluator": "amaze.evaluation.protocol",
    "evaluate": "amaze.evaluation.protocol",
    "compute_metrics": "amaze.maze.metrics",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'amaze' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *_LAZY])


def _register_gymnasium_environments() -> None:
    from amaze.envs.gym_env import register_environments

    register_environments()


_register_gymnasium_environments()

__all__ = [
    "AmazeError",
    "BatchEngine",
    "Direction",
    "Evaluator",
    "Maze",
    "MazeClass",
    "MazeSpec",
    "MazeStringError",
    "MazeStringWarning",
    "PlacedSign",
    "Sign",
    "SignError",
    "SignKind",
    "Simulation",
    "StartLocation",
    "as_robot",
    "compute_metrics",
    "evaluate",
    "register_custom_signs",
    "rotations",
]
