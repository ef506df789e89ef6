"""amaze: reference-compatible AMaze mazes, their metrics, rendering and command-line tools.

Quick start::

    from amaze import Maze
    maze = Maze.from_string("M4_20x20_C1_l.25_L.25_t.5_T.5")
    maze.stats(), maze.maze_class.label

The same string gives the same maze as amaze-benchmarker 1.0 (walls, solution
and placed signs). See ``amaze.spec`` for the string grammar. Importing the
package registers the gymnasium environment ``AMaze-v0`` (``amaze.gym_env``).
"""

from amaze.directions import Direction
from amaze.errors import AmazeError, MazeStringError, MazeStringWarning, SignError
from amaze.maze import Maze, MazeClass, PlacedSign
from amaze.signs import Sign, SignKind, register_custom_signs
from amaze.spec import MazeSpec, StartLocation

__version__ = "0.1.0"


def _register_gymnasium_environments() -> None:
    from amaze.gym_env import register_environments

    register_environments()


_register_gymnasium_environments()

__all__ = [
    "AmazeError",
    "Direction",
    "Maze",
    "MazeClass",
    "MazeSpec",
    "MazeStringError",
    "MazeStringWarning",
    "PlacedSign",
    "Sign",
    "SignError",
    "SignKind",
    "StartLocation",
    "register_custom_signs",
]
