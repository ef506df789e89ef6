"""Property-based tests of the string grammar and of the generator's invariants."""

from __future__ import annotations

import math
import warnings
from collections import Counter, deque
from itertools import pairwise

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from amaze.errors import MazeStringError, MazeStringWarning
from amaze.maze.maze import Maze
from amaze.maze.signs import BUILTIN_SHAPES, Sign
from amaze.maze.spec import MazeSpec, StartLocation

FAST = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])

values = st.sampled_from([1.0, 0.5, 0.25, 0.75, 0.125, 0.3, 0.05, 0.9, 1e-3])
signs = st.builds(Sign, shape=st.sampled_from(BUILTIN_SHAPES), value=values)
probabilities = st.one_of(st.none(), st.sampled_from([0.0, 0.1, 0.25, 0.5, 0.75, 1.0, 0.125]))


@st.composite
def specs(draw, max_size: int = 12) -> MazeSpec:
    return MazeSpec(
        width=draw(st.integers(2, max_size)),
        height=draw(st.integers(2, max_size)),
        seed=draw(st.integers(0, 2**40)),
        start=draw(st.sampled_from(list(StartLocation))),
        rotated=draw(st.booleans()),
        unicursive=draw(st.booleans()),
        clue=tuple(draw(st.lists(signs, max_size=3))),
        lure=tuple(draw(st.lists(signs, max_size=3))),
        p_lure=draw(probabilities),
        trap=tuple(draw(st.lists(signs, max_size=2))),
        p_trap=draw(probabilities),
    )


@FAST
@given(specs())
def test_print_parse_roundtrip(spec):
    text = spec.to_string()
    again = MazeSpec.from_string(text)
    assert again == spec
    assert again.to_string() == text


@FAST
@given(specs(), st.randoms(use_true_random=False))
def test_token_order_does_not_matter(spec, rng):
    tokens = spec.to_string().split("_")
    # Signs of one kind keep their relative order (it decides type indices).
    rng.shuffle(tokens)
    by_kind = {k: [t for t in spec.to_string().split("_") if t[0] == k] for k in "CLT"}
    tokens = [by_kind[t[0]].pop(0) if t[0] in "CLT" else t for t in tokens]
    assert MazeSpec.from_string(" ".join(tokens)) == spec


def generate_quietly(spec: MazeSpec) -> Maze:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MazeStringWarning)
        return Maze.generate(spec)


def reachable(maze: Maze, origin) -> set:
    seen, queue = {origin}, deque([origin])
    while queue:
        i, j = queue.popleft()
        for d, (di, dj) in enumerate(((1, 0), (0, 1), (-1, 0), (0, -1))):
            if not maze.walls[i, j, d] and (i + di, j + dj) not in seen:
                seen.add((i + di, j + dj))
                queue.append((i + di, j + dj))
    return seen


@FAST
@given(specs(max_size=15))
def test_generated_mazes_are_perfect_and_solvable(spec):
    maze = generate_quietly(spec)
    w, h, walls = maze.width, maze.height, maze.walls
    assert {(w, h), (h, w)} >= {(spec.width, spec.height)}
    # Borders are walled and both sides of every inner wall agree.
    assert walls[-1, :, 0].all() and walls[:, -1, 1].all()
    assert walls[0, :, 2].all() and walls[:, 0, 3].all()
    assert (walls[:-1, :, 0] == walls[1:, :, 2]).all()
    assert (walls[:, :-1, 1] == walls[:, 1:, 3]).all()
    # The solution is a walkable simple path from start to end.
    assert maze.solution[0] == maze.start and maze.solution[-1] == maze.end
    assert len(set(maze.solution)) == maze.path_length
    for a, b in pairwise(maze.solution):
        d = {(1, 0): 0, (0, 1): 1, (-1, 0): 2, (0, -1): 3}[(b[0] - a[0], b[1] - a[1])]
        assert not walls[a][d]
    # Start and end are opposite corners.
    assert maze.end == (w - 1 - maze.start[0], h - 1 - maze.start[1])
    openings = (4 * w * h - int(walls.sum())) // 2
    if spec.unicursive:
        assert reachable(maze, maze.start) == set(maze.solution)
    else:
        assert openings == w * h - 1  # a spanning tree: perfect maze
        assert len(reachable(maze, maze.start)) == w * h


def within(count: int, expected: float) -> bool:
    return math.floor(expected) <= count <= math.ceil(expected)


@FAST
@given(specs(max_size=20))
def test_sign_counts_are_within_bounds(spec):
    maze = generate_quietly(spec)
    n = maze.n_intersections
    if spec.unicursive:
        assert n == 0 and not maze.clues and not maze.traps
    n_traps = len(maze.traps)
    if spec.p_trap and spec.trap:
        assert within(n_traps, n * spec.p_trap)
    else:
        assert n_traps == 0
    if spec.clue:
        assert len(maze.clues) == n - n_traps
    else:
        assert not maze.clues
    if spec.p_lure and spec.lure:
        assert within(len(maze.lures), (maze.path_length - n - 1) * spec.p_lure)
    else:
        assert not maze.lures
    # Sign types are dealt evenly (§3.6-3.7): the lures' among the lures; the
    # clues' among all n intersections, before traps replace n_traps of them.
    if maze.lures:
        uses = Counter(p.sign_index for p in maze.lures)
        share = len(maze.lures) / len(spec.lure)
        assert all(within(uses[k], share) for k in range(len(spec.lure)))
    if maze.clues:
        uses = Counter(p.sign_index for p in maze.clues)
        share = n / len(spec.clue)
        assert all(
            math.floor(share) - n_traps <= uses[k] <= math.ceil(share)
            for k in range(len(spec.clue))
        )
    assert len({p.cell for p in maze.signs}) == len(maze.signs)
    assert all(p.cell not in (maze.end,) for p in maze.signs)


grammar_alphabet = st.sampled_from([*"MURCLTlt0123456789x._-SNWE ", "point", "arrow", "__"])


@settings(max_examples=300, deadline=None)
@given(st.lists(grammar_alphabet, max_size=14).map("".join))
def test_fuzzed_strings_only_raise_the_documented_error(text):
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", MazeStringWarning)
            spec = MazeSpec.from_string(text)
    except MazeStringError:
        return
    assert MazeSpec.from_string(spec.to_string()) == spec


@settings(max_examples=200, deadline=None)
@given(st.text(max_size=20))
def test_arbitrary_text_only_raises_the_documented_error(text):
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", MazeStringWarning)
            MazeSpec.from_string(text)
    except MazeStringError:
        pass
