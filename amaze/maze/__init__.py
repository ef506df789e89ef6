"""The maze core: maze strings, generation, placed signs, metrics, descriptions and pictures.

The lowest layer of ``amaze``: it knows nothing of agents. A maze flows as
``string --MazeSpec.from_string--> MazeSpec --Maze.generate--> Maze``:

* :mod:`~amaze.maze.spec`: the maze-string grammar (:class:`MazeSpec`);
* :mod:`~amaze.maze.generation`: walls, solution and placed signs, bit-identical
  to amaze-benchmarker 1.0;
* :mod:`~amaze.maze.maze`: the immutable :class:`Maze` and its classes;
* :mod:`~amaze.maze.signs`, :mod:`~amaze.maze.sign_images`: sign types, placed
  signs and their pictures;
* :mod:`~amaze.maze.directions`: E/N/W/S and cells;
* :mod:`~amaze.maze.metrics`: Surprisingness, Deceptiveness;
* :mod:`~amaze.maze.description`: ``amaze inspect`` / ``amaze stats`` records;
* :mod:`~amaze.maze.render`: maze pictures.
"""

from amaze.maze.directions import Cell, Direction
from amaze.maze.maze import Maze, MazeClass, as_maze, as_mazes, rotations
from amaze.maze.signs import PlacedSign, Sign, SignKind, register_custom_signs
from amaze.maze.spec import MazeSpec, StartLocation

__all__ = [
    "Cell",
    "Direction",
    "Maze",
    "MazeClass",
    "MazeSpec",
    "PlacedSign",
    "Sign",
    "SignKind",
    "StartLocation",
    "as_maze",
    "as_mazes",
    "register_custom_signs",
    "rotations",
]
