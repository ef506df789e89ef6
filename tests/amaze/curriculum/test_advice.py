"""Advisors (``--advisor``): proposals with their reasons, what was accepted, and ``follow``."""

from __future__ import annotations

import dataclasses
import io

import numpy as np
import pytest

from amaze.curriculum.advice import (
    MazeReason,
    Proposal,
    changed_fields,
    check_advice,
    make_advisor,
    propose_generate,
    propose_select,
    seen_by,
)
from amaze.curriculum.curators import CuratorError, MazeResults, make_curator
from amaze.curriculum.difficulty import difficulty
from amaze.curriculum.distance import maze_distance
from amaze.curriculum.edens import CRITERIA, EdensCurator
from amaze.curriculum.follow import FollowCurator
from amaze.curriculum.human import (
    PERSON_VALIDATION,
    TerminalCurator,
    describe_proposal,
    person_validation,
)
from amaze.evaluation.suite import PAPER_TRAINING_MAZE
from amaze.maze import MazeSpec
from tests.amaze.curriculum.test_curators import candidate, context, history

TARGET = PAPER_TRAINING_MAZE
PARENT = "M3_7x7_U"


def advised(name: str = "careful", seed: int = 0, **options):
    """The context of a curator advised by edens."""
    return dataclasses.replace(context(TARGET, seed, **options), advisor="edens")


def stage_candidates() -> list:
    """Three candidates of stage 1, each played on an advisor's validation mazes."""
    edens = make_advisor("edens", context(TARGET))
    validation = [
        MazeResults(maze, tuple(i < b for i in range(4)), (0.5 * b,) * 4, (10,) * 4)
        for b, maze in enumerate(edens.validation[:3])
    ]
    return [
        dataclasses.replace(
            candidate(PARENT, branch=b, reached=4 - b), validation=tuple(validation[b:])
        )
        for b in range(3)
    ]


# -- the reasons of a proposal ---------------------------------------------------------


def test_changed_fields_names_each_group_that_differs() -> None:
    assert changed_fields(PARENT, PARENT) == ()
    assert changed_fields(PARENT, "M4_7x7_U") == ("seed",)
    assert changed_fields(PARENT, "M3_9x7_NE_U") == ("size", "start")
    assert changed_fields(PARENT, "M3_7x7_C1_l.5_L.25") == ("unicursive", "clue", "lure", "p_lure")


def test_an_edens_generate_proposal_gives_each_maze_its_operators_distance_and_difficulty() -> None:
    advisor = make_advisor("edens", context(TARGET))
    proposal = propose_generate(advisor, "edens", 3, history(candidate(PARENT)), TARGET)
    assert proposal.kind == "generate" and proposal.advisor == "edens"
    assert len(proposal.mazes) == len(proposal.reasons) == 3
    assert proposal.reasons[0] == MazeReason(
        PARENT, (), maze_distance(MazeSpec.from_string(PARENT), MazeSpec.from_string(TARGET)),
        difficulty(MazeSpec.from_string(PARENT)),
    )  # fmt: skip
    for reason in proposal.reasons[1:]:
        assert reason.operators  # a mutant names the operators that made it
    # the same mazes as the advisor's own generate, the same as an unadvised edens would make
    assert list(proposal.mazes) == advisor.generate(3, history(candidate(PARENT)))


def test_the_mutants_operators_are_those_edens_applied() -> None:
    edens = EdensCurator(context(TARGET))
    for seed in range(5):
        mutant, operators = edens.mutate_explained(PARENT, np.random.default_rng(seed), 3)
        assert mutant == edens.mutate(PARENT, np.random.default_rng(seed), 3)
        assert len(operators) >= 3  # one per step, add_clue with intersections


def test_a_curator_without_an_account_of_its_mazes_is_explained_by_the_fields_that_changed() -> (
    None
):
    advisor = make_advisor("careful", context(TARGET))
    proposal = propose_generate(advisor, "careful", 3, history(candidate(PARENT)), TARGET)
    for maze, reason in zip(proposal.mazes, proposal.reasons, strict=True):
        assert reason.operators == changed_fields(PARENT, maze)


def test_a_select_proposal_gives_the_pick_the_front_and_every_candidates_criteria() -> None:
    advisor = make_advisor("edens", context(TARGET))
    candidates = stage_candidates()
    proposal = propose_select(advisor, "edens", candidates)
    assert proposal.choice == advisor.select(candidates).branch
    assert proposal.choice in proposal.front
    assert [row["branch"] for row in proposal.criteria] == [0, 1, 2]
    for row in proposal.criteria:
        assert set(row) == {"branch", *CRITERIA, "extinct"}
    # a curator without explain_select: its pick alone, the candidates' figures
    careful = propose_select(make_advisor("careful", context(TARGET)), "careful", candidates)
    assert careful.front == (careful.choice,) == (0,)
    assert careful.criteria[0]["success_rate"] == 1.0


def test_a_proposal_reads_back_from_its_decision_line() -> None:
    advisor = make_advisor("edens", context(TARGET))
    proposals = [
        propose_generate(advisor, "edens", 3, history(candidate(PARENT)), TARGET),
        propose_select(advisor, "edens", stage_candidates()),
    ]
    for proposal in proposals:
        back = Proposal.from_dict(proposal.to_dict(), proposal.kind)
        assert back.to_dict() == proposal.to_dict()


@pytest.mark.parametrize(
    ("kind", "data", "words"),
    [
        ("select", [], "not a JSON object"),
        ("select", {"advisor": 3}, "advisor 3"),
        ("select", {"advisor": "edens", "choice": "1", "front": [], "criteria": []}, "choice"),
        ("select", {"advisor": "edens", "choice": 1, "front": ["a"], "criteria": []}, "front"),
        ("generate", {"advisor": "edens", "mazes": [1], "reasons": []}, "mazes"),
        ("generate", {"advisor": "edens", "mazes": ["M1_5x5"], "reasons": []}, "one reason"),
    ],
)
def test_a_bad_proposal_in_a_decision_line_is_refused_by_name(kind, data, words) -> None:
    with pytest.raises(ValueError, match=words):
        Proposal.from_dict(data, kind)


def test_accepted_says_whether_the_decision_took_the_proposal() -> None:
    select = Proposal("edens", "select", choice=2, front=(1, 2))
    assert select.accepted(2) is True and select.accepted(1) is False
    generate = Proposal("edens", "generate", mazes=("M1_5x5", "M2_5x5", "M3_5x5"))
    assert generate.accepted(["M2_5x5", "M1_5x5", "M9_5x5"]) == [True, True, False]
    assert generate.accepted(["M9_5x5"] * 3) == [False] * 3


# -- who advises whom --------------------------------------------------------------------


def test_an_advisors_streams_are_its_own() -> None:
    decider = context(TARGET)
    advisor = dataclasses.replace(decider, role="advisor")
    assert decider.rng(1, "generate").integers(2**31) != advisor.rng(1, "generate").integers(2**31)
    # ... so edens advising makes other mazes than edens deciding, and always the same ones
    parent = history(candidate(PARENT))
    as_advisor = make_advisor("edens", decider).generate(3, parent)
    assert as_advisor == make_advisor("edens", advised()).generate(3, parent)
    assert as_advisor != make_curator("edens", decider).generate(3, parent)


@pytest.mark.parametrize("name", ["human", "follow"])
def test_a_person_or_a_follower_cannot_advise(name: str) -> None:
    with pytest.raises(CuratorError, match=f"advisor '{name}' cannot advise"):
        make_advisor(name, context(TARGET))


def test_a_curator_that_takes_no_advice_is_refused_an_advisor() -> None:
    class Deaf:
        name = "deaf"

    with pytest.raises(CuratorError, match="curator 'deaf' takes no advice: --advisor edens"):
        check_advice(Deaf(), "deaf", "edens")
    check_advice(Deaf(), "deaf", None)  # no advisor: nothing to refuse
    check_advice(make_curator("careful", context(TARGET)), "careful", "edens")


@pytest.mark.parametrize("name", ["random", "interpolation", "human"])
def test_curators_without_options_refuse_any_naming_their_role(name: str) -> None:
    with pytest.raises(CuratorError, match=f"curator '{name}': unknown option.s. x .it takes none"):
        make_curator(name, context(TARGET, x=1))
    if name != "human":  # a person never advises
        with pytest.raises(CuratorError, match=f"advisor '{name}': unknown option.s. x"):
            make_advisor(name, context(TARGET, x=1))


def test_an_advisors_unknown_option_is_named_as_the_advisors() -> None:
    with pytest.raises(CuratorError, match=r"advisor 'edens': unknown option\(s\) x"):
        make_advisor("edens", context(TARGET, x=1))


def test_each_curator_sees_its_own_validation_mazes_only() -> None:
    edens = make_advisor("edens", context(TARGET))
    candidates = stage_candidates()
    person = TerminalCurator(context(TARGET))
    played = [
        dataclasses.replace(
            c, validation=c.validation + tuple(
                MazeResults(m, (False,) * 4, (0.0,) * 4, (5,) * 4) for m in person.validation
            )
        )
        for c in candidates
    ]  # fmt: skip
    assert [c.validation for c in seen_by(edens, played)] == [c.validation for c in candidates]
    assert all(len(c.validation) == PERSON_VALIDATION for c in seen_by(person, played))
    assert seen_by(object(), played) == played  # no validation mazes: sees everything


def test_a_person_sees_the_same_family_mazes_with_or_without_an_advisor() -> None:
    alone, with_advice = person_validation(context(TARGET)), person_validation(advised("human"))
    assert alone == with_advice and len(alone) == PERSON_VALIDATION
    target = MazeSpec.from_string(TARGET)
    for maze in alone:
        spec = MazeSpec.from_string(maze)
        assert (spec.width, spec.height, spec.clue) == (target.width, target.height, target.clue)


# -- follow --------------------------------------------------------------------------------


def proposal_for(k: int = 3) -> Proposal:
    mazes = ("M11_9x9_U", "M12_9x9_U", "M13_9x9_U")[:k]
    return Proposal("edens", "generate", mazes=mazes, reasons=())


def test_follow_needs_an_advisor() -> None:
    with pytest.raises(CuratorError, match="curator 'follow' follows an advisor's proposals"):
        make_curator("follow", context(TARGET))


@pytest.mark.parametrize(
    ("options", "words"),
    [({"p": 1.5}, "follow p 1.5"), ({"p": "half"}, "follow p"), ({"base": "human"}, "base 'human'"),
     ({"base": "follow"}, "base 'follow'"), ({"q": 1}, "unknown option.s. q")],
)  # fmt: skip
def test_follows_options_are_checked(options: dict, words: str) -> None:
    with pytest.raises(CuratorError, match=words):
        make_curator("follow", advised(**options))


def test_follow_with_p_1_takes_every_proposal_and_with_p_0_none() -> None:
    parent = history(candidate(PARENT))
    candidates = stage_candidates()
    always = make_curator("follow", advised(p=1))
    assert always.generate(3, parent, advice=proposal_for()) == list(proposal_for().mazes)
    pick = Proposal("edens", "select", choice=2, front=(2,))
    assert always.select(candidates, advice=pick).branch == 2
    never = make_curator("follow", advised(p=0))
    careful = make_curator("careful", context(TARGET))
    assert never.generate(3, parent, advice=proposal_for()) == careful.generate(3, parent)
    assert never.select(candidates, advice=pick) is careful.select(candidates)


def test_follow_draws_from_the_runs_seed_and_follows_about_p_of_the_time() -> None:
    def draws(seed: int) -> list[bool]:
        follower = make_curator("follow", advised(seed=seed, p=0.5))
        assert isinstance(follower, FollowCurator)
        return [follower.follows(stage, kind) for stage in range(1, 101) for kind in ("g", "s")]

    assert draws(3) == draws(3)
    assert draws(3) != draws(4)
    assert 70 < sum(draws(3)) < 130


def test_follow_passes_the_other_options_to_its_base() -> None:
    follower = make_curator("follow", advised(p=0.5, base="risky", unfair=0.0))
    assert isinstance(follower, FollowCurator)
    assert follower.base.name == "risky" and follower.base.unfair == 0.0


# -- the person at a terminal ----------------------------------------------------------------


def test_the_terminal_shows_the_proposal_with_its_reasons_and_an_empty_line_takes_it() -> None:
    out = io.StringIO()
    person = TerminalCurator(advised("human"), input=io.StringIO("\n\n\n"), output=out)
    reasons = (
        MazeReason("M11_9x9_U", (), 4.0, 3.5),
        MazeReason("M12_9x9_U", ("size_up", "seed", "seed"), 3.25, 3.75),
    )
    proposal = Proposal("edens", "generate", mazes=("M11_9x9_U", "M12_9x9_U"), reasons=reasons)
    assert person.generate(2, history(candidate(PARENT)), advice=proposal) == list(proposal.mazes)
    shown = out.getvalue()
    assert "advisor edens proposes:" in shown
    assert "M12_9x9_U  (size_up, seed x2; distance to the target 3.25, difficulty 3.75)" in shown
    assert "the parent's maze, unchanged" in shown
    pick = Proposal(
        "edens", "select", choice=1, front=(1, 2),
        criteria=({"branch": 0, "difficulty_reached": 0.5}, {"branch": 1, "extinct": False}),
    )  # fmt: skip
    candidates = stage_candidates()
    assert person.select(candidates, advice=pick).branch == 1  # the empty line
    shown = out.getvalue()
    assert "advisor edens proposes branch 1 (front: 1, 2)" in shown
    assert "branch 0: difficulty_reached 0.500" in shown and "[empty: 1, the advisor's]" in shown
    # a person's answer overrides it
    other = TerminalCurator(advised("human"), input=io.StringIO("2\n"), output=io.StringIO())
    assert other.select(candidates, advice=pick).branch == 2


def test_describe_proposal_is_plain_lines() -> None:
    lines = describe_proposal(Proposal("edens", "select", choice=0, front=(0,), criteria=()))
    assert lines == ["advisor edens proposes branch 0 (front: 0)"]
