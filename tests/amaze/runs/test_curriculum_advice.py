"""A curriculum with an advisor: proposals first, recorded with what was accepted."""

from __future__ import annotations

import io
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from amaze.agents.robot import as_robot
from amaze.curriculum import curators
from amaze.errors import AmazeError
from amaze.runs.decisions import DECISIONS_FILE
from tests.amaze.runs.test_curriculum import CONFIG, Interrupted, choices, decisions
from tests.amaze.runs.toy_curriculum import ToyConfig, ToyLearner, ToyRun
from tests.run_folders import snapshot

ADVISED = {**CONFIG, "curator": "careful", "advisor": "edens", "stages": 4}


def proposals(folder: Path) -> list[tuple]:
    """Each decision's proposal and whether it was accepted (None where there was none)."""
    return [(d.get("proposal"), d.get("accepted")) for d in decisions(folder)]


def without_seconds(proposal: dict | None) -> dict | None:
    return None if proposal is None else {k: v for k, v in proposal.items() if k != "seconds"}


@pytest.fixture(scope="module")
def advised(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("advised") / "run"
    ToyRun.fresh(ADVISED, out)
    return out


def test_every_asked_decision_records_the_advisors_proposal_and_what_was_accepted(
    advised: Path,
) -> None:
    records = decisions(advised)
    # stage 0's trivial maze and a select between one candidate ask nobody: no proposal
    assert ["proposal" in d for d in records] == [False, False, True, True, True, True, True, True]
    for d in records[2:]:
        proposal = d["proposal"]
        assert proposal["advisor"] == "edens" and d["curator"] == "careful"
        if d["kind"] == "select":
            assert d["accepted"] is (d["choice"] == proposal["choice"])
            assert proposal["choice"] in proposal["front"]
            assert [row["branch"] for row in proposal["criteria"]] == [0, 1]
            assert {"validation_success_rate", "difficulty_reached"} <= set(proposal["criteria"][0])
        else:
            assert d["accepted"] == [maze in d["mazes"] for maze in proposal["mazes"]]
            assert len(proposal["reasons"]) == len(proposal["mazes"]) == 2
            for reason in proposal["reasons"]:
                assert {"maze", "operators", "distance", "difficulty"} == set(reason)
    # careful decides by its own rules: the same curriculum as careful alone
    alone = advised.parent / "alone"
    ToyRun.fresh({**ADVISED, "advisor": None}, alone)
    assert choices(alone) == choices(advised)
    assert all("proposal" not in d for d in decisions(alone))


def test_the_summary_says_how_often_the_advice_was_taken(advised: Path) -> None:
    records = [d for d in decisions(advised) if "proposal" in d]
    picks = [d["accepted"] for d in records if d["kind"] == "select"]
    kept = [k for d in records if d["kind"] == "generate" for k in d["accepted"]]
    summary = json.loads((advised / "summary.json").read_text())
    assert summary["advisor"] == "edens"
    assert summary["advice"] == {
        "selections": len(picks),
        "selections_taken": sum(picks),
        "selections_taken_share": sum(picks) / len(picks),
        "mazes_proposed": len(kept),
        "mazes_kept": sum(kept),
        "mazes_kept_share": sum(kept) / len(kept),
    }
    assert len(picks) == 3 and len(kept) == 6


def test_the_proposals_are_the_same_whoever_decides(advised: Path, tmp_path: Path) -> None:
    """A person (at a terminal, here scripted), careful or random: the same first proposal."""
    first = [without_seconds(p) for p, _ in proposals(advised)[2:4]]
    runs = {
        "random": {**ADVISED, "curator": "random"},
        "follow": {**ADVISED, "curator": "follow", "curator_options": {"p": 0.5}},
        "human": {**ADVISED, "curator": "human", "stages": 2},
        "always": {**ADVISED, "curator": "follow", "curator_options": {"p": 1}, "stages": 2},
    }
    # the person takes the advice for the mazes (empty lines), then picks branch 1
    answers = io.StringIO("\n\n1\n")
    with pytest.MonkeyPatch.context() as patch:
        # agents whose results on a maze do not depend on the other mazes played with it
        patch.setattr(ToyLearner, "agent", lambda self: Reflex(self.seed % 1000))
        patch.setattr("sys.stdin", answers)
        patch.setattr("sys.stdout", io.StringIO())
        for name, config in runs.items():
            ToyRun.fresh(config, tmp_path / name)
    for name in runs:
        seen = [without_seconds(p) for p, _ in proposals(tmp_path / name)[2:3]]
        assert seen == first[:1], name
    # The person took the proposed mazes, as the follower with p = 1: the same candidates, and
    # the same proposal for the final choice, though the person's candidates were also played
    # on the person's family mazes (the advisor judges by its own).
    person, follower = (proposals(tmp_path / name)[3][0] for name in ("human", "always"))
    assert without_seconds(person) == without_seconds(follower)
    human = decisions(tmp_path / "human")
    played = {
        name: json.loads((tmp_path / name / "stages/stage-1/branch-0/result.json").read_text())
        for name in ("human", "always")
    }
    assert len(played["human"]["validation"]) == 2 * len(played["always"]["validation"])
    assert human[2]["accepted"] == [True, True]  # empty lines took the proposal
    assert human[2]["mazes"] == human[2]["proposal"]["mazes"]
    assert human[3]["choice"] == 1
    assert human[3]["accepted"] is (human[3]["proposal"]["choice"] == 1)


def test_follow_takes_every_proposal_with_p_1_and_none_with_p_0(
    advised: Path, tmp_path: Path
) -> None:
    ToyRun.fresh({**ADVISED, "curator": "follow", "curator_options": {"p": 1}}, tmp_path / "p1")
    for d in decisions(tmp_path / "p1")[2:]:
        assert d["accepted"] in (True, [True, True]), d
    ToyRun.fresh({**ADVISED, "curator": "follow", "curator_options": {"p": 0}}, tmp_path / "p0")
    assert choices(tmp_path / "p0") == choices(advised)  # careful's own decisions
    half = {**ADVISED, "curator": "follow", "curator_options": {"p": 0.5}, "stages": 8}
    ToyRun.fresh({**half, "budget_steps": 16000}, tmp_path / "half")
    taken = [d["accepted"] for d in decisions(tmp_path / "half")[2:]]
    assert True in taken or [True, True] in taken
    assert False in taken or any(t != [True, True] for t in taken if isinstance(t, list))


def test_a_killed_advised_run_resumes_to_the_same_decisions_and_proposals(
    advised: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls = {"n": 0}
    original = ToyLearner.train

    def dying(self, mazes, budget_steps, *, budget_seconds=None, checkpoint=None, progress=None):
        def checkpoint_then_die() -> None:
            checkpoint()
            calls["n"] += 1
            if calls["n"] == 5:  # inside stage 2, after its decisions
                raise Interrupted

        return original(self, mazes, budget_steps, checkpoint=checkpoint_then_die)

    monkeypatch.setattr(ToyLearner, "train", dying)
    out = tmp_path / "run"
    with pytest.raises(Interrupted):
        ToyRun.fresh(ADVISED, out)
    asked = len(decisions(out))
    assert 2 < asked < 8
    monkeypatch.setattr(ToyLearner, "train", original)
    ToyRun.resume(out)
    assert choices(out) == choices(advised)
    expected = [(without_seconds(p), a) for p, a in proposals(advised)]
    assert [(without_seconds(p), a) for p, a in proposals(out)] == expected
    for branch in sorted(advised.glob("stages/stage-*/branch-*")):
        relative = branch.relative_to(advised)
        assert (out / relative / "agent/toy.json").read_text() == (
            branch / "agent/toy.json"
        ).read_text()


@pytest.mark.parametrize("decider", ["careful", "follow"])
def test_a_replay_reaches_the_same_agent_without_asking_the_advisor(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, decider: str
) -> None:
    """Accepted or overridden, a replay makes the recorded decisions and the same agent."""
    config = {**ADVISED, "curator": decider}
    if decider == "follow":
        config["curator_options"] = {"p": 0.5}
    source = tmp_path / "source"
    ToyRun.fresh(config, source)
    accepted = [d.get("accepted") for d in decisions(source)]
    assert True in accepted or [True, True] in accepted or decider == "careful"

    def never(*args, **kwargs):
        raise AssertionError("a replay never asks the curator nor its advisor")

    for method in ("generate", "select", "explain_generate", "explain_select"):
        monkeypatch.setattr(f"amaze.curriculum.edens.EdensCurator.{method}", never)
    monkeypatch.setattr("amaze.curriculum.strategies.CarefulCurator.generate", never)
    monkeypatch.setattr("amaze.curriculum.strategies.CarefulCurator.select", never)
    again = tmp_path / "again"
    ToyRun.replay(source, again)
    assert choices(again) == choices(source)
    assert proposals(again) == proposals(source)
    assert (again / "agent.json").read_text() == (source / "agent.json").read_text()
    for branch in sorted(source.glob("stages/stage-*/branch-*")):
        relative = branch.relative_to(source)
        assert (again / relative / "agent/toy.json").read_text() == (
            branch / "agent/toy.json"
        ).read_text()


def _edit(out: Path, index: int, **changes: object) -> None:
    path = out / DECISIONS_FILE
    lines = path.read_text().splitlines()
    data = json.loads(lines[index])
    data.update(changes)
    lines[index] = json.dumps(data)
    path.write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize(
    ("index", "changes", "message"),
    [
        (3, {"accepted": "yes"}, "line 4: accepted 'yes' is not true or false"),
        (2, {"accepted": [True]}, "line 3: accepted .* per proposed maze"),
        (3, {"proposal": {"advisor": "edens", "choice": "0"}}, "line 4: proposal choice '0'"),
        (2, {"proposal": 7}, "line 3: proposal 7 is not a JSON object"),
    ],
)
def test_a_damaged_proposal_is_refused_by_name_and_nothing_changes(
    advised: Path, tmp_path: Path, index: int, changes: dict, message: str
) -> None:
    out = tmp_path / "run"
    shutil.copytree(advised, out)
    (out / "summary.json").unlink()
    _edit(out, index, **changes)
    before = snapshot(out)
    with pytest.raises(AmazeError, match=f"decisions file .*{message}"):
        ToyRun.resume(out)
    assert snapshot(out) == before


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"regime": "direct", "advisor": "edens", "only": True},
         "advisor .*'edens' has no effect in the direct regime: it is for edhucat"),
        ({"regime": "edens", "advisor": "edens", "only": True},
         "advisor .*'edens' has no effect in the edens regime: it is for edhucat"),
        ({"regime": "interpolation", "advisor": "edens", "only": True},
         "advisor .*'edens' has no effect in the interpolation regime"),
        ({"stages": 1}, "advisor 'edens' has no effect with 1 stage: the curator makes no"),
        ({"advisor": "human"}, "advisor 'human' cannot advise"),
        ({"advisor": "follow"}, "advisor 'follow' cannot advise"),
        ({"advisor": "nobody"}, "unknown advisor 'nobody' .*edens"),
        ({"advisor": None, "advisor_options": {"validation": 2}}, "advisor_options .* without an"),
        ({"advisor": None, "curator": "follow"}, "curator 'follow' follows an advisor's"),
        ({"advisor_options": [1]}, "advisor_options \\[1\\] is not a JSON object"),
    ],
)  # fmt: skip
def test_an_advisor_without_effect_or_a_bad_one_is_refused(changes: dict, message: str) -> None:
    only = changes.pop("only", False)
    with pytest.raises(AmazeError, match=message):
        ToyConfig.from_dict(changes if only else {**ADVISED, **changes})


def test_an_advisor_for_a_curator_that_takes_no_advice_is_refused_before_the_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(
        curators.BUILTIN_CURATORS, "deaf", "tests.amaze.runs.test_curriculum_advice:DeafCurator"
    )
    with pytest.raises(AmazeError, match="curator 'deaf' takes no advice: --advisor edens would"):
        ToyRun.fresh({**ADVISED, "curator": "deaf"}, tmp_path / "run")
    assert not (tmp_path / "run").exists()


def test_an_advisors_bad_option_is_named_as_the_advisors(tmp_path: Path) -> None:
    with pytest.raises(AmazeError, match=r"advisor 'edens': unknown option\(s\) x"):
        ToyRun.fresh({**ADVISED, "advisor_options": {"x": 1}}, tmp_path / "run")


def test_an_advisor_that_fails_is_named_as_the_advisor(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def broken(*args, **kwargs):
        raise RuntimeError("out of ideas")

    monkeypatch.setattr("amaze.curriculum.edens.EdensCurator.explain_generate", broken)
    with pytest.raises(
        AmazeError, match=r"advisor 'edens' failed proposing mazes \(RuntimeError: out of ideas"
    ):
        ToyRun.fresh(ADVISED, tmp_path / "run")


class Reflex:
    """A deterministic agent: its action is a function of what it sees (and its seed)."""

    def __init__(self, seed: int) -> None:
        self.robot = as_robot("DD")
        self.seed = seed

    def reset(self, n_agents: int | None = None) -> None:
        pass

    def __call__(self, observations: np.ndarray) -> np.ndarray:
        flat = np.asarray(observations, dtype=np.float64).reshape(len(observations), -1)
        weights = np.arange(1, flat.shape[1] + 1) * (self.seed + 3)
        return (np.rint(flat @ weights).astype(np.int64) + self.seed) % 4


class DeafCurator:
    """A plug-in curator from before advice: it would never see a proposal."""

    name = "deaf"

    def __init__(self, context) -> None:
        self.context = context

    def select(self, candidates):
        return candidates[0]

    def generate(self, k, history):
        return [history.mazes[0]] * k
