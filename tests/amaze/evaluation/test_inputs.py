"""The input-recognition test: enumeration, observations, scoring and CSV.

Its summary picture is tested in ``test_inputs_picture.py``.

The reference fixture ``inputs_evaluation_C1_L.25_T.5_always_east`` holds the
140 rows amaze-benchmarker 1.0 produced for a policy that always goes east, for
DD and H11 robots. The SHA-256 digests below were computed from the same
library (its ``_all_inputs`` and its image drawer) for further sign sets and
for the hybrid images, which the fixture does not store.
"""

from __future__ import annotations

import csv
import hashlib

import numpy as np
import pytest

from amaze.agents.observations import (
    ObservationError,
    cell_image,
    discrete_input,
    discrete_observation,
    draw_cell,
)
from amaze.errors import AmazeError
from amaze.evaluation.inputs import (
    CSV_COLUMNS,
    InputClass,
    InputRecognitionError,
    InputType,
    enumerate_inputs,
    evaluate_inputs,
    inputs_for_maze,
)
from amaze.maze.directions import OFFSETS, Direction
from amaze.maze.maze import Maze
from amaze.maze.signs import Sign, SignKind
from amaze.maze.spec import MazeSpec
from tests.amaze.conftest import load_reference

FIXTURE = load_reference()["inputs_evaluation_C1_L.25_T.5_always_east"]
SIGNS = (["1"], [".25"], [".5"])
MULTI = (["1", "point-.75"], [".25", "warning-.2"], [".5"])

# Computed with amaze-benchmarker 1.0: sha256 of the rows (Walls..Expected, joined
# by "," and "\n") of _all_inputs for MULTI, without / with empty intersections.
MULTI_ROWS_SHA256 = {
    False: "8401074ea4e3db8b79158eede35410eea1fa66a1582e23bfd3dbd0af1d376d9c",
    True: "da74662ffbc77f1f86c2dc1b4b42f8a1cdd8a84ebb52bb138cd44cd03dd37f33",
}
# ... and of its hybrid inputs for SIGNS, as uint8 round(255 x), shape (140, v, v).
HYBRID_IMAGES_SHA256 = {
    15: "6db66416a439a3ffec034c4b3cb4d95dd728e1ebd268b0e4d8ad5b4c72a08665",
    11: "f605e96718317aef65c8e9f46570bf5be0f7bf4a02414179cb464bc1b53a5dbb",
}
# Sign-less intersections for clues ["1"] (reference order): arrival and expected side.
EMPTY_INTERSECTION_ARRIVALS = "NWSNWSNWSEWSEWSEWSENSENSENSENWENWENW"
EMPTY_INTERSECTION_EXPECTED = "WSWSNNWNNWSWSEEWEENSNSEENEENWNWEENEE"


def always_east(observations: np.ndarray) -> np.ndarray:
    return np.zeros(len(observations), dtype=np.int64)


def expected_policy(inputs):
    return lambda observations: inputs.expected


def _walls_and_arrival(obs: np.ndarray) -> tuple[list[int], int | None]:
    walls = [int(w == 1.0) for w in obs[:4]]
    arrival = [d for d in range(4) if obs[d] == 0.5]
    return walls, (arrival[0] if arrival else None)


def trusting_policy(observations: np.ndarray) -> np.ndarray:
    """Follows any sign at an intersection, else goes the only new way (back from dead ends)."""
    actions = []
    for obs in observations:
        walls, arrival = _walls_and_arrival(obs)
        open_sides = [d for d in range(4) if not walls[d]]
        if len(open_sides) == 3 and obs[4:].any():
            actions.append(int(np.argmax(obs[4:])))
            continue
        new = [d for d in open_sides if d != arrival]
        actions.append(new[0] if new else arrival)
    return np.array(actions)


def value_reading_policy(trap_value: float):
    """Like ``trusting_policy``, but a sign of ``trap_value`` sends it the third way."""

    def policy(observations: np.ndarray) -> np.ndarray:
        actions = trusting_policy(observations)
        for k, obs in enumerate(observations):
            walls, arrival = _walls_and_arrival(obs)
            signs = obs[4:]
            if sum(walls) == 1 and np.isclose(signs.max(), trap_value):
                pointed = int(np.argmax(signs))
                actions[k] = next(
                    d for d in range(4) if not walls[d] and d not in (arrival, pointed)
                )
        return actions

    return policy


def rows_digest(rows) -> str:
    text = "\n".join(",".join(row[:7]) for row in rows)
    return hashlib.sha256(text.encode()).hexdigest()


# -- enumeration ------------------------------------------------------------------------


def test_reference_case_has_140_inputs_per_type_as_the_reference():
    inputs = enumerate_inputs("DD", *SIGNS)
    assert len(inputs) == 140 == FIXTURE["D"]["total"]
    result = evaluate_inputs(always_east, inputs)
    assert {"|".join(k): n for k, n in result.totals_per_type.items()} == FIXTURE["D"]["totals"]
    assert result.totals == {
        InputClass.EMPTY: 20,
        InputClass.LURE: 60,
        InputClass.CLUE: 36,
        InputClass.TRAP: 24,
    }


@pytest.mark.parametrize(
    ("clues", "lures", "traps"),
    [
        ([], [], []),
        (["1"], [], []),
        (["1", "point-.75"], [".25"], [".5"]),
        (["1", "point-.75"], [".25", "warning-.2", ".1"], [".5", "star-.4"]),
        ([], [".25"], [".5"]),
    ],
)
@pytest.mark.parametrize("empty", [False, True])
def test_count_follows_the_formula(clues, lures, traps, empty):
    n_c, n_l, n_t = len(clues), len(lures), len(traps)
    inputs = enumerate_inputs("DD", clues, lures, traps, empty_intersections=empty)
    expected = 8 * (1 + 3 * n_l) + 12 * (1 + 3 * n_l) + 36 * n_c + 24 * n_t + 36 * empty
    assert len(inputs) == expected
    types = inputs.input_types
    assert types.count(InputType.DEAD_END) == 8 * (1 + 3 * n_l)
    assert types.count(InputType.CORRIDOR) == 12 * (1 + 3 * n_l)
    assert inputs.classes.count(InputClass.CLUE) == 36 * n_c
    assert inputs.classes.count(InputClass.TRAP) == 24 * n_t
    assert inputs.classes.count(InputClass.EMPTY_INTERSECTION) == 36 * empty


@pytest.mark.parametrize("robot", ["DD", "H11"])
def test_rows_match_the_reference_for_an_always_east_policy(robot):
    fixture = FIXTURE["D" if robot == "DD" else "H11"]
    result = evaluate_inputs(always_east, enumerate_inputs(robot, *SIGNS))
    assert fixture["columns"] == list(CSV_COLUMNS)
    assert result.rows() == fixture["rows"]
    counts = {"|".join(k): n for k, n in result.counts_per_type.items()}
    assert counts == fixture["counts_action_east"]
    assert result.overall == pytest.approx(35 / 140)


@pytest.mark.parametrize("empty", [False, True])
def test_order_with_several_signs_of_each_kind_matches_the_reference(empty):
    inputs = enumerate_inputs("DD", *MULTI, empty_intersections=empty)
    result = evaluate_inputs(always_east, inputs)
    assert rows_digest(result.rows()) == MULTI_ROWS_SHA256[empty]


def test_empty_intersections_follow_the_reference_convention():
    inputs = enumerate_inputs("DD", ["1"], empty_intersections=True)
    empty = [c for c in inputs.cases if c.input_class is InputClass.EMPTY_INTERSECTION]
    assert "".join(c.arrival.name[0] for c in empty) == EMPTY_INTERSECTION_ARRIVALS
    assert "".join(c.expected.name[0] for c in empty) == EMPTY_INTERSECTION_EXPECTED
    assert all(c.sign is None and c.input_type is InputType.INTERSECTION for c in empty)


def test_every_case_is_a_sound_situation():
    inputs = enumerate_inputs("DD", *MULTI, empty_intersections=True)
    for case in inputs.cases:
        assert not case.walls[case.expected], case  # the correct way is open
        if case.arrival is not None:
            assert not case.walls[case.arrival], case
        if case.kind is SignKind.LURE:
            assert case.sign_direction != case.expected
        if case.kind is SignKind.CLUE:
            assert case.sign_direction == case.expected
        if case.kind is SignKind.TRAP:
            assert case.expected not in (case.sign_direction, case.arrival)
            assert not case.walls[case.sign_direction]
        if case.input_type is not InputType.DEAD_END and case.kind is not SignKind.CLUE:
            assert case.expected != case.arrival


# -- observations -----------------------------------------------------------------------


def test_discrete_inputs_equal_the_reference_apart_from_the_now_visible_signs():
    inputs = enumerate_inputs("DD", *SIGNS)
    obs = inputs.observations
    assert obs.dtype == np.float32
    assert obs.shape == (140, 8)
    assert FIXTURE["D"]["any_sign_visible"] is False
    without_signs = obs.copy()
    without_signs[:, 4:] = 0
    np.testing.assert_array_equal(without_signs, np.array(FIXTURE["D"]["observations"]))


def test_discrete_inputs_show_each_sign_in_the_slot_of_its_direction():
    inputs = enumerate_inputs("DD", *MULTI)
    seen = set()
    for case, obs in zip(inputs.cases, inputs.observations, strict=True):
        signs = obs[4:]
        if case.sign is None:
            assert not signs.any()
            continue
        seen.add(case.kind)
        expected = np.zeros(4, dtype=np.float32)
        expected[case.sign_direction] = case.sign.value
        np.testing.assert_array_equal(signs, expected)
        walls = np.array(case.walls, dtype=np.float32)
        if case.arrival is not None:
            walls[case.arrival] = 0.5
        np.testing.assert_array_equal(obs[:4], walls)
    assert seen == {SignKind.CLUE, SignKind.LURE, SignKind.TRAP}


@pytest.mark.parametrize("vision", [15, 11])
def test_hybrid_images_equal_the_reference(vision):
    inputs = enumerate_inputs(f"H{vision}", *SIGNS)
    assert inputs.observations.dtype == np.uint8
    assert inputs.observations.shape == (140, 1, vision, vision)
    digest = hashlib.sha256(np.ascontiguousarray(inputs.observations[:, 0]).tobytes())
    assert digest.hexdigest() == HYBRID_IMAGES_SHA256[vision]


def _lookup(inputs):
    table: dict = {}
    for k, case in enumerate(inputs.cases):
        key = (case.walls, case.arrival, case.kind, case.sign, case.sign_direction)
        table.setdefault(key, []).append(k)
    return table


@pytest.mark.parametrize("robot", ["DD", "H15", "H7"])
def test_inputs_equal_what_an_agent_sees_in_a_maze(robot):
    maze = Maze.from_string("M10_10x10_C1_l.2_L.25_t.5_T.5")
    inputs = inputs_for_maze(maze, robot, empty_intersections=True)
    table = _lookup(inputs)
    vision = inputs.robot.vision

    def key(cell, arrival):
        walls = tuple(int(w) for w in maze.walls[cell])
        placed = maze.sign_at(cell)
        if placed is None:
            return (walls, Direction(arrival), None, None, None)
        return (walls, Direction(arrival), placed.kind, placed.sign, placed.direction)

    def seen(cell, arrival):
        if vision is None:
            return discrete_observation(maze, cell, arrival)
        return np.rint(cell_image(maze, cell, vision, arrival) * 255).astype(np.uint8)[None]

    # Every sign, seen from the way the solution enters its cell, is in the set.
    for placed in maze.signs:
        previous = maze.solution[placed.solution_index - 1]
        arrival = int(
            Direction(OFFSETS.index((previous[0] - placed.cell[0], previous[1] - placed.cell[1])))
        )
        assert key(placed.cell, arrival) in table, placed
    # Wherever a cell's content is in the set, the set shows what the agent sees there.
    matched = 0
    for i in range(maze.width):
        for j in range(maze.height):
            for arrival in (d for d in range(4) if not maze.walls[i, j, d]):
                for k in table.get(key((i, j), arrival), []):
                    np.testing.assert_array_equal(inputs.observations[k], seen((i, j), arrival))
                    matched += 1
    assert matched > 150


# -- scoring ----------------------------------------------------------------------------


@pytest.mark.parametrize("robot", ["DD", "H15"])
@pytest.mark.parametrize("empty", [False, True])
def test_a_policy_giving_the_expected_actions_scores_one_everywhere(robot, empty):
    inputs = enumerate_inputs(robot, *MULTI, empty_intersections=empty)
    result = evaluate_inputs(expected_policy(inputs), inputs)
    assert result.success.all()
    assert set(result.rates.values()) == {1.0}
    assert set(result.rates_per_type.values()) == {1.0}
    assert result.overall == 1.0
    assert result.class_average == 1.0
    assert (InputClass.EMPTY_INTERSECTION in result.rates) is empty


def test_trusting_every_sign_fails_every_trap_and_nothing_else():
    result = evaluate_inputs(trusting_policy, enumerate_inputs("DD", *SIGNS))
    assert result.rates == {
        InputClass.EMPTY: 1.0,
        InputClass.LURE: 1.0,
        InputClass.CLUE: 1.0,
        InputClass.TRAP: 0.0,
    }
    assert result.counts[InputClass.TRAP] == 0
    assert result.overall == pytest.approx(116 / 140)
    assert result.class_average == pytest.approx(0.75)


def test_discrete_agents_can_tell_traps_from_clues_by_their_lightness():
    inputs = enumerate_inputs("DD", *SIGNS)
    result = evaluate_inputs(value_reading_policy(0.5), inputs)
    assert result.overall == 1.0


def test_always_east_summary():
    result = evaluate_inputs(always_east, enumerate_inputs("DD", *SIGNS))
    summary = result.summary()
    assert summary["n_inputs"] == 140
    assert summary["counts"] == {"empty": 5, "lure": 15, "clue": 9, "trap": 6}
    assert summary["rates_per_type"]["Intersection|TRAP"] == pytest.approx(0.25)
    assert summary["overall"] == pytest.approx(0.25)


def test_the_policy_is_called_once_on_a_copy_after_a_reset():
    inputs = enumerate_inputs("H11", *SIGNS)
    calls = []

    class Recorder:
        def reset(self, n_agents):
            calls.append(("reset", n_agents))

        def __call__(self, observations):
            calls.append(("call", observations.shape))
            observations[:] = 0  # must not spoil the set
            return np.ones(len(observations), dtype=np.int32)

    result = evaluate_inputs(Recorder(), inputs)
    assert calls == [("reset", 140), ("call", (140, 1, 11, 11))]
    assert inputs.observations.any()
    assert not inputs.observations.flags.writeable
    assert (result.actions == 1).all()


@pytest.mark.parametrize(
    ("actions", "message"),
    [
        (np.zeros(139, dtype=int), "139"),
        (np.full(140, 4), "4"),
        (np.full(140, -1), "-1"),
        (np.zeros(140), "float64"),
    ],
)
def test_bad_policy_outputs_raise(actions, message):
    inputs = enumerate_inputs("DD", *SIGNS)
    with pytest.raises(InputRecognitionError, match=message):
        evaluate_inputs(lambda observations: actions, inputs)


# -- construction and errors --------------------------------------------------------------


def test_inputs_for_a_maze_use_its_sign_types():
    reference = enumerate_inputs("DD", ["1"], [".25"], [".5"])
    text = "M4_10x10_C1_l.25_L.25_t.5_T.5"
    for maze in (text, MazeSpec.from_string(text), Maze.from_string(text)):
        assert inputs_for_maze(maze, "DD").cases == reference.cases
    # No lure probability: the maze has no lures, and neither has its test.
    assert len(inputs_for_maze("M4_10x10_C1", "DD")) == 8 + 12 + 36


def test_signs_may_be_given_as_objects_or_strings():
    a = enumerate_inputs("DD", [Sign("point", 0.75)], [Sign(value=0.25)])
    b = enumerate_inputs("DD", ["point-.75"], [".25"])
    assert a.cases == b.cases
    np.testing.assert_array_equal(a.observations, b.observations)


@pytest.mark.parametrize("robot", ["CC", "C11", "CC15"])
def test_continuous_robots_raise(robot):
    with pytest.raises(InputRecognitionError, match="continuous") as error:
        enumerate_inputs(robot, *SIGNS)
    assert isinstance(error.value, AmazeError)
    assert isinstance(error.value, ValueError)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"clues": "1"}, "clues"),
        ({"lures": [0.25]}, "0.25"),
        ({"traps": ["nope-.5"]}, "nope"),
        ({"robot": "XX"}, "XX"),
    ],
)
def test_bad_arguments_raise(kwargs, message):
    arguments = {"robot": "DD"} | kwargs
    with pytest.raises(AmazeError, match=message):
        enumerate_inputs(**arguments)


def test_inputs_for_maze_rejects_other_objects():
    with pytest.raises(InputRecognitionError, match="42"):
        inputs_for_maze(42, "DD")


# -- the low-level input builders -----------------------------------------------------------


def test_discrete_input_builds_the_8_floats():
    obs = discrete_input([1, 0, 0, 1], arrival=2, sign_value=0.5, sign_direction=1)
    np.testing.assert_array_equal(obs, np.float32([1, 0, 0.5, 1, 0, 0.5, 0, 0]))
    assert obs.dtype == np.float32
    np.testing.assert_array_equal(discrete_input((0, 1, 1, 1)), np.float32([0, 1, 1, 1] + [0] * 4))


def test_builders_match_the_maze_readers():
    maze = Maze.from_string("M10_10x10_C1_l.2_L.25_t.5_T.5")
    for placed in maze.signs:
        i, j = placed.cell
        walls = maze.walls[i, j].astype(int)
        arrival = next(d for d in range(4) if not walls[d])
        np.testing.assert_array_equal(
            discrete_input(walls, arrival, placed.sign.value, placed.direction),
            discrete_observation(maze, placed.cell, arrival),
        )
        np.testing.assert_array_equal(
            draw_cell(walls, 15, arrival, placed.sign, placed.direction),
            cell_image(maze, placed.cell, 15, arrival),
        )


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: discrete_input([1, 1, 1]), r"\[1, 1, 1\]"),
        (lambda: discrete_input([1, 2, 0, 0]), r"\[1, 2, 0, 0\]"),
        (lambda: discrete_input([1, 0, 0, 0], arrival=0), "arrival side 0"),
        (lambda: discrete_input([1, 0, 0, 0], arrival=5), "arrival 5"),
        (lambda: discrete_input([1, 0, 0, 0], sign_value=0.5), "sign_direction=None"),
        (lambda: discrete_input([1, 0, 0, 0], sign_value=1.5, sign_direction=0), "1.5"),
        (lambda: discrete_input([1, 0, 0, 0], sign_value=0.5, sign_direction=7), "7"),
        (lambda: draw_cell([1, 0, 0, 0], 14), "14"),
        (lambda: draw_cell([1, 0, 0, 0], 3), "vision 3"),
        (lambda: draw_cell([1, 0, 0, 0], 11, sign="1", sign_direction=0), "'1'"),
        (lambda: draw_cell([1, 0, 0, 0], 11, sign=Sign()), "sign_direction=None"),
    ],
)
def test_builders_reject_bad_cells(call, message):
    with pytest.raises(ObservationError, match=message) as error:
        call()
    assert isinstance(error.value, AmazeError)


# -- files ----------------------------------------------------------------------------------


def test_csv_has_the_reference_columns_and_rows(tmp_path):
    result = evaluate_inputs(always_east, enumerate_inputs("DD", *SIGNS))
    path = result.write_csv(tmp_path / "out" / "inputs_recognition.csv")
    with path.open(newline="") as stream:
        lines = list(csv.reader(stream))
    assert lines[0] == list(CSV_COLUMNS)
    assert lines[1:] == FIXTURE["D"]["rows"]
