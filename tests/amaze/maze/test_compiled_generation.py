"""The compiled generator against the readable definition, part for part."""

from __future__ import annotations

import random
import warnings

import numpy as np
import pytest

from amaze.errors import MazeStringWarning
from amaze.maze import compiled_generation, generation
from amaze.maze.maze import Maze
from amaze.maze.spec import MazeSpec
from tests.amaze.conftest import load_reference

REFERENCE = load_reference()
FIXTURE_STRINGS = [m["input"] for m in REFERENCE["mazes"] + REFERENCE["bulk_mazes"]]
SIGNS = ["1", ".5", ".25", "arrow", "star-.3", "point-.75", "warning-.5"]


def _spec(text: str) -> MazeSpec:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MazeStringWarning)
        return MazeSpec.from_string(text)


def assert_same_parts(spec: MazeSpec) -> None:
    definition, compiled = generation.generate(spec), compiled_generation.generate(spec)
    label = spec.to_string()
    assert compiled.walls.shape == definition.walls.shape, label
    assert compiled.walls.dtype == np.bool_ and compiled.walls.flags.c_contiguous
    assert np.array_equal(compiled.walls, definition.walls), label
    for field in ("start", "end", "solution", "intersections", "clues", "lures", "traps"):
        assert getattr(compiled, field) == getattr(definition, field), (field, label)


def random_strings(count: int, seed: int) -> list[str]:
    """Maze strings over every corner, rotation mode, size, sign mix and probability."""
    rng = random.Random(seed)
    strings = []
    for _ in range(count):
        tokens = [
            f"M{rng.randrange(10 ** rng.randint(1, 25))}",
            f"{rng.randint(2, 24)}x{rng.randint(2, 24)}",
            rng.choice(["SW", "SE", "NE", "NW"]),
        ]
        tokens += ["U"] * (rng.random() < 0.2) + ["R"] * (rng.random() < 0.3)
        tokens += [f"C{rng.choice(SIGNS)}" for _ in range(rng.choice([0, 1, 1, 2, 3]))]
        for probability, kind in (("l", "L"), ("t", "T")):
            if rng.random() < 0.8:
                tokens.append(f"{probability}{rng.choice(['.1', '.25', '.5', '.9', '1', '.33'])}")
            tokens += [f"{kind}{rng.choice(SIGNS)}" for _ in range(rng.choice([0, 1, 1, 2]))]
        strings.append("_".join(tokens))
    return strings


@pytest.mark.parametrize("text", FIXTURE_STRINGS)
def test_fixtures(text):
    assert_same_parts(_spec(text))


@pytest.mark.parametrize("part", range(4))
def test_random_specs(part):
    specs = [_spec(text) for text in random_strings(400, seed=part)]
    kinds = {(s.rotated, s.unicursive, int(s.start), bool(s.lure), bool(s.trap)) for s in specs}
    assert len(kinds) > 40  # the mix really covers the options
    for spec in specs:
        assert_same_parts(spec)


@pytest.mark.parametrize(
    "text",
    [
        "M0_2x2",
        "M1_2x2_NE_C1_l1_L.5_t1_T.5",
        "M7_100x3_SE_C1_l.5_L.5_t.5_T.5",
        "M7_3x100_NW_R_C1_l.5_L.5_t.5_T.5",
        "M123456789012_100x100_C1_l.1_L.5_t.3_T.25",
        "M99_60x60_C1_C.5_l.5_L.25_L.75_t1_T.3_T.6",
        "M5_30x30_U_C1_l.5_L.25",
    ],
)
def test_edge_sizes_and_many_signs(text):
    assert_same_parts(_spec(text))


def test_maze_generate_uses_the_compiled_generator():
    spec = _spec("M3_12x9_NE_C1_l.4_L.25_t.5_T.5")
    maze, parts = Maze.generate(spec), compiled_generation.generate(spec)
    assert np.array_equal(maze.walls, parts.walls)
    assert maze.signs == tuple(parts.clues + parts.lures + parts.traps)
