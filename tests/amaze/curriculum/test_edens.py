"""The EDEnS-style curator: validation mazes, the Pareto pick, alternatives, a whole toy run."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from amaze.curriculum.curators import (
    Candidate,
    CuratorContext,
    CuratorError,
    History,
    MazeResults,
    make_curator,
)
from amaze.curriculum.difficulty import difficulty
from amaze.curriculum.distance import maze_distance
from amaze.curriculum.edens import EdensCurator, pareto_front
from amaze.curriculum.validation import reserved_seeds, validation_mazes
from amaze.evaluation.suite import PAPER_TRAINING_MAZE, standard_suite
from amaze.maze.spec import MazeSpec
from tests.amaze.runs.toy_curriculum import ToyRun

TARGET = "M5_12x12_C1_l.25_L.25_t.5_T.5"


def context(**options) -> CuratorContext:
    return CuratorContext(target=TARGET, seed=3, stages=4, branches=3, options=options)


def results(maze: str, success: tuple[bool, ...], reward: float) -> MazeResults:
    return MazeResults(maze, success, (reward,) * 4, (10,) * 4)


def candidate(
    branch: int, maze: str, own: tuple[bool, ...], validation: tuple[bool, ...], reward: float
) -> Candidate:
    return Candidate(
        stage=2,
        branch=branch,
        mazes=(maze,),
        own=(results(maze, own, 0.0),),
        others=(),
        lineage=(0, 0, branch),
        env_steps=100,
        seconds=0.1,
        converged=False,
        lineage_steps=300,
        validation=(results("M9_12x12_C1", validation, reward),),
    )


def test_validation_mazes_are_the_targets_family_never_the_suites() -> None:
    mazes = validation_mazes(PAPER_TRAINING_MAZE, 50, seed=0)
    assert mazes == validation_mazes(PAPER_TRAINING_MAZE, 50, seed=0)
    assert mazes != validation_mazes(PAPER_TRAINING_MAZE, 50, seed=1)
    target = MazeSpec.from_string(PAPER_TRAINING_MAZE)
    seeds = [MazeSpec.from_string(m).seed for m in mazes]
    assert len(set(seeds)) == 50
    suite = {MazeSpec.from_string(m).seed for m in standard_suite().maze_strings(False)}
    assert len(suite) == 18 and suite <= reserved_seeds()
    assert not set(seeds) & reserved_seeds()
    for maze in mazes:
        assert (
            MazeSpec.from_string(maze).to_string().split("_")[1:]
            == (target.to_string().split("_")[1:])
        )


def test_the_pareto_front_by_hand() -> None:
    # One maze for all: the difficulty reached is the same, validation decides.
    a = candidate(0, "M1_5x5_U", (True,) * 4, (True, False, False, False), -1.0)
    b = candidate(1, "M1_5x5_U", (True,) * 4, (True, True, False, False), -2.0)
    c = candidate(2, "M1_5x5_U", (True,) * 4, (True, False, False, False), -1.5)  # a beats it
    d = candidate(3, "M1_5x5_U", (True,) * 4, (True, True, False, False), -2.0)  # b's equal
    criteria = EdensCurator.criteria
    assert pareto_front([a, b, c, d], criteria) == [a, b, d]
    assert pareto_front([c], criteria) == [c]


def test_difficulty_reached_counts_only_what_was_solved() -> None:
    hard, easy = "M1_12x12_C1_t.5_T.5", "M1_5x5_U"
    solved = candidate(0, easy, (True,) * 4, (False,) * 4, -5.0)
    half = candidate(1, hard, (True, True, False, False), (False,) * 4, -5.0)
    assert EdensCurator.criteria(solved)[2] == pytest.approx(difficulty(easy))
    assert EdensCurator.criteria(half)[2] == pytest.approx(difficulty(hard) / 2)


def test_select_rejects_extinct_alternatives_and_picks_from_the_front() -> None:
    curator = EdensCurator(context())
    extinct = candidate(0, "M1_12x12_C1", (False,) * 4, (True,) * 4, 1.0)
    alive = candidate(1, "M2_5x5_U", (True,) * 4, (False,) * 4, -5.0)
    assert curator.select([extinct, alive]) is alive
    both_dead = [extinct, candidate(1, "M2_5x5_U", (False,) * 4, (False,) * 4, -5.0)]
    assert curator.select(both_dead) is extinct  # all extinct: judged anyway
    front = [
        candidate(0, "M1_5x5_U", (True,) * 4, (True, False, False, False), -1.0),
        candidate(1, "M2_5x5_U", (True,) * 4, (True, True, False, False), -2.0),
    ]
    picks = {make_curator("edens", context()).select(front).branch for _ in range(3)}
    assert len(picks) == 1  # seeded: the same pick every time
    seeds = {
        EdensCurator(CuratorContext(TARGET, seed, 4, 3)).select(front).branch for seed in range(20)
    }
    assert seeds == {0, 1}  # and each front member can be picked


def test_generate_keeps_the_parents_maze_for_branch_0_and_mutates_the_others() -> None:
    curator = EdensCurator(context())
    parent = candidate(1, "M7_8x8_C1_l.25_L.25", (True,) * 4, (False,) * 4, -3.0)
    history = History(stage=3, parent=parent, stages=())
    mazes = curator.generate(3, history)
    assert mazes == curator.generate(3, history)
    assert mazes[0] == parent.mazes[0]
    for mutant in mazes[1:]:
        spec = MazeSpec.from_string(mutant)
        assert mutant != parent.mazes[0]
        assert spec.to_string() == mutant
        assert max(spec.width, spec.height) <= 12  # the target's side by default


def _fields(maze: str) -> dict:
    """A maze's fields but its walls and start corner (what the family is made of)."""
    spec = MazeSpec.from_string(maze)
    return {
        name: getattr(spec, name)
        for name in ("width", "height", "unicursive", "clue", "lure", "trap", "p_lure", "p_trap")
    }


def test_a_directed_step_is_neutral_or_comes_closer_to_the_target() -> None:
    curator = EdensCurator(context())
    rng = np.random.default_rng(5)
    spec = MazeSpec.from_string("M7_5x5_U")
    for _ in range(300):
        mutant = curator.directed_step(spec, rng)
        same_family = _fields(mutant.to_string()) == _fields(spec.to_string())
        closer = maze_distance(mutant, TARGET) < maze_distance(spec, TARGET)
        assert mutant != spec and (same_family or closer)
        spec = mutant
    # Walking on, the maze reaches the target's family and stays in it.
    assert _fields(spec.to_string()) == _fields(TARGET)


def test_directed_intersections_come_with_the_targets_clue() -> None:
    curator = EdensCurator(context())
    # A unicursive maze with lures and traps (dormant): turning intersections on
    # would leave traps and no clue, unless the clue comes with them.
    unicursive = MazeSpec.from_string("M7_9x9_U_l.25_L.25_t.5_T.5")
    for seed in range(40):
        mutant = curator.directed_step(unicursive, np.random.default_rng(seed))
        assert mutant.unicursive or mutant.clue, mutant.to_string()
    walk, rng = MazeSpec.from_string("M7_5x5_U"), np.random.default_rng(8)
    for _ in range(200):
        walk = curator.directed_step(walk, rng)
        assert walk.unicursive or walk.clue, walk.to_string()


def test_undirected_mutants_may_move_away_from_the_target() -> None:
    directed = EdensCurator(context())
    free = EdensCurator(context(directed=False))
    parent = candidate(1, TARGET, (True,) * 4, (False,) * 4, -3.0)
    history = History(stage=3, parent=parent, stages=())
    assert all(_fields(m) == _fields(TARGET) for m in directed.generate(3, history))
    away = [m for m in free.generate(9, history)[1:] if _fields(m) != _fields(TARGET)]
    assert away  # the target's mutants leave its family without direction


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"directed": "yes"}, "edens directed 'yes'"),
        ({"validaton": 3}, "unknown option.*validaton"),
        ({"validation": 0}, "edens validation"),
        ({"mutations": 9}, "edens mutations"),
        ({"max_size": 101}, "edens max_size"),
    ],
)
def test_bad_options_are_refused_by_name(options: dict, message: str) -> None:
    with pytest.raises(CuratorError, match=message):
        EdensCurator(context(**options))


def test_an_edens_run_plays_every_candidate_on_the_validation_mazes(tmp_path: Path) -> None:
    config = {
        "regime": "edens",
        "stages": 3,
        "budget_steps": 3000,
        "target": "M5_8x8_C1",
        "curator_options": {"validation": 2},
    }
    result = ToyRun.fresh(config, tmp_path / "run")
    assert (result.summary["curator"], result.summary["branches"]) == ("edens", 3)
    curator = EdensCurator(CuratorContext("M5_8x8_C1", 0, 3, 3, options={"validation": 2}))
    for path in (tmp_path / "run").glob("stages/stage-*/branch-*/result.json"):
        validation = json.loads(path.read_text())["validation"]
        assert [r["maze"] for r in validation] == curator.validation
        assert all(len(r["success"]) == 4 for r in validation)
    lines = (tmp_path / "run" / "decisions.jsonl").read_text().splitlines()
    selects = [json.loads(line) for line in lines if '"select"' in line]
    assert "validation_success_rate" in selects[-1]["candidates"][0]
    generated = [json.loads(line) for line in lines if '"generate"' in line]
    chosen = selects[1]["choice"]  # the select before stage 2
    assert generated[2]["mazes"][0] == generated[1]["mazes"][chosen]  # branch 0: unchanged


def test_the_edens_regime_takes_only_the_edens_curator() -> None:
    from tests.amaze.runs.toy_curriculum import ToyConfig

    with pytest.raises(ValueError, match="the edens regime's curator is edens"):
        ToyConfig.from_dict({"regime": "edens", "curator": "careful"})
    assert ToyConfig.from_dict({"regime": "edhucat", "curator": "edens"}).branches == 3
