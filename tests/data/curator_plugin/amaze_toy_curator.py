"""A curator from outside the package, declared through the ``amaze.curators`` entry points."""

from amaze.curriculum.strategies import reseeded
from amaze.maze.spec import MazeSpec


class FirstBranchCurator:
    """Keeps branch 0; every branch gets the parent's maze with a new seed."""

    name = "first-branch"

    def __init__(self, context):
        self.context = context

    def select(self, candidates):
        return min(candidates, key=lambda c: c.branch)

    def generate(self, k, history):
        seeds = self.context.rng(history.stage, "generate").integers(0, 2**31, k)
        return reseeded(MazeSpec.from_string(history.mazes[0]), seeds)


NOT_A_CLASS = 42
