"""The curriculum loop of amaze.runs.curriculum, with a toy learner: decisions, budgets, resume."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import pytest

from amaze.curriculum import curators
from amaze.curriculum.interpolation import curriculum
from amaze.curriculum.learner import branch_seed
from amaze.curriculum.regimes import (
    MAX_OPEN_STAGES,
    OPEN_EPOCHS,
    branch_allowance,
    branch_seconds,
    curriculum_over,
)
from amaze.errors import AmazeError
from amaze.runs.branches import BranchProgress
from amaze.runs.decisions import DECISIONS_FILE, DecisionLog, decision_sequence
from tests.amaze.runs.toy_curriculum import ToyConfig, ToyLearner, ToyRun
from tests.run_folders import snapshot

TARGET = "M5_8x8_C1"
CONFIG = {
    "regime": "edhucat",
    "curator": "random",
    "stages": 3,
    "branches": 2,
    "budget_steps": 6000,
    "target": TARGET,
}


def decisions(folder: Path) -> list[dict]:
    lines = (folder / DECISIONS_FILE).read_text().splitlines()
    return [json.loads(line) for line in lines]


def choices(folder: Path) -> list[tuple]:
    """The decisions without their times: what the curriculum was."""
    return [
        (d["stage"], d["kind"], d.get("choice"), tuple(d.get("mazes", ())))
        for d in decisions(folder)
    ]


@pytest.fixture(scope="module")
def finished(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("curriculum") / "run"
    ToyRun.fresh(CONFIG, out)
    return out


def test_a_run_records_every_decision_in_the_loops_order(finished: Path) -> None:
    records = decisions(finished)
    assert [(d["stage"], d["kind"]) for d in records] == decision_sequence(3)
    assert records[0]["mazes"] == ["M5_5x5_U"]  # the trivial first maze
    assert records[1]["forced"] is True  # one candidate after the first stage
    for record in records:
        assert record["curator"] == "random"
        assert record["time"].endswith("+00:00")
    generated = [d for d in records if d["kind"] == "generate" and d["stage"] > 0]
    assert all(len(d["mazes"]) == 2 for d in generated)
    assert all(m.endswith("_8x8_C1") for d in generated for m in d["mazes"])
    select = records[3]
    assert [c["branch"] for c in select["candidates"]] == [0, 1]
    assert {"success_rate", "normalized_reward", "overall_success_rate", "env_steps"} <= set(
        select["candidates"][0]
    )


def test_the_budget_is_split_as_the_paper_does_and_handed_on(finished: Path) -> None:
    rows = [json.loads((p / "result.json").read_text()) for p in _branches(finished)]
    steps = {(r["stage"], r["branch"]): r["env_steps"] for r in rows}
    assert steps[(0, 0)] == 6000 // 6 == branch_allowance(6000, 0, 0, 3, 2)
    # Stage 0 trained one agent: the unused slot is handed on to later stages.
    assert steps[(1, 0)] == steps[(1, 1)] == (6000 - 1000) // 4
    assert steps[(2, 0)] == steps[(2, 1)] == (6000 - 1000 - 2 * 1250) // 2
    summary = json.loads((finished / "summary.json").read_text())
    assert summary["env_steps"] == sum(steps.values()) == 6000
    assert [s["stage"] for s in summary["curriculum"]] == [0, 1, 2]
    assert summary["final_lineage"][0] == 0 and len(summary["final_lineage"]) == 3


def test_the_run_folder_holds_stages_progress_and_pictures(finished: Path) -> None:
    assert len(_branches(finished)) == 1 + 2 * 2
    for branch in _branches(finished):
        assert (branch / "agent" / "toy.json").is_file()
        assert (branch / "trajectory.png").is_file()
        assert not (branch / "checkpoint").exists()
    rows = (finished / "progress.csv").read_text().splitlines()
    assert len(rows) == 1 + 5
    assert (finished / "curriculum.png").stat().st_size > 1000
    assert len(list((finished / "trajectories").glob("target-rotation-*.png"))) == 4


def test_branches_copy_the_selected_agent_with_their_own_seed(finished: Path) -> None:
    records = decisions(finished)
    chosen = records[3]["choice"]
    for branch in range(2):
        agent = json.loads(
            (finished / f"stages/stage-2/branch-{branch}/agent/toy.json").read_text()
        )
        assert agent["seed"] == branch_seed(0, 2, branch)
        # Trained on the trivial maze, its stage-1 parent's maze, then its own.
        assert agent["trained"] == 1000 + 1250 + 1250
    assert json.loads((finished / "summary.json").read_text())["final_lineage"][1] == chosen


def test_the_interpolation_regime_is_the_loop_with_one_branch(tmp_path: Path) -> None:
    result = ToyRun.fresh(
        {"regime": "interpolation", "stages": 4, "budget_steps": 4000, "target": TARGET},
        tmp_path / "run",
    )
    assert result.summary["curator"] == "interpolation"
    assert result.summary["branches"] == 1
    plan = [spec.to_string() for spec in curriculum(TARGET, 4)]
    generated = [d["mazes"][0] for d in decisions(tmp_path / "run") if d["kind"] == "generate"]
    assert generated == plan
    assert [s["env_steps"] for s in result.summary["curriculum"]] == [1000] * 4


class Interrupted(Exception):
    pass


def test_a_run_killed_mid_branch_resumes_to_the_same_curriculum(
    tmp_path: Path, finished: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls = {"n": 0}
    original = ToyLearner.train

    def dying(self, mazes, budget_steps, *, budget_seconds=None, checkpoint=None, progress=None):
        def checkpoint_then_die() -> None:
            checkpoint()
            calls["n"] += 1
            if calls["n"] == 4:  # inside stage 1, branch 0, after a checkpoint
                raise Interrupted

        return original(self, mazes, budget_steps, checkpoint=checkpoint_then_die)

    monkeypatch.setattr(ToyLearner, "train", dying)
    out = tmp_path / "run"
    with pytest.raises(Interrupted):
        ToyRun.fresh(CONFIG, out)
    assert (out / "stages/stage-1/branch-0/checkpoint/toy.json").is_file()
    monkeypatch.setattr(ToyLearner, "train", original)
    result = ToyRun.resume(out)
    assert choices(out) == choices(finished)
    assert result.summary["env_steps"] == 6000
    assert len((out / "progress.csv").read_text().splitlines()) == 6
    for branch in _branches(finished):
        relative = branch.relative_to(finished)
        assert (out / relative / "agent/toy.json").read_text() == (
            branch / "agent/toy.json"
        ).read_text()


def test_the_loop_reports_each_branchs_progress_live(tmp_path: Path) -> None:
    heard: list[BranchProgress] = []

    class Watched(ToyRun):
        def branch_progress(self, progress: BranchProgress) -> None:
            heard.append(progress)

    Watched.fresh(CONFIG, tmp_path / "run")
    # The first branch is allowed 6000 / (2 x 3) steps, spent in chunks of 500.
    first = [(p.steps, p.done) for p in heard if (p.stage, p.branch) == (0, 0)]
    assert first == [(0, False), (500, False), (1000, False), (1000, True)]
    assert {p.budget_steps for p in heard if p.stage == 0} == {1000}
    done = [(p.stage, p.branch) for p in heard if p.done]
    assert done == [(0, 0), (1, 0), (1, 1), (2, 0), (2, 1)]
    # a resumed run reports the branches it finds finished
    heard.clear()
    (tmp_path / "run/summary.json").unlink()
    Watched.resume(tmp_path / "run")
    assert [(p.stage, p.branch) for p in heard if p.done] == done
    assert not [p for p in heard if not p.done]


def test_a_replay_makes_the_recorded_decisions_without_the_curator(
    tmp_path: Path, finished: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def no_curator(self, *args):
        raise AssertionError("a replay never asks the curator")

    monkeypatch.setattr("amaze.curriculum.strategies.RandomCurator.generate", no_curator)
    monkeypatch.setattr("amaze.curriculum.strategies.RandomCurator.select", no_curator)
    result = ToyRun.replay(finished, tmp_path / "replay")
    assert choices(tmp_path / "replay") == choices(finished)
    assert all(d["replayed"] for d in decisions(tmp_path / "replay"))
    assert result.summary["replay_of"] == str(finished)
    assert (tmp_path / "replay" / "replay.jsonl").is_file()


def test_an_unfinished_or_direct_run_cannot_be_replayed(tmp_path: Path, finished: Path) -> None:
    unfinished = tmp_path / "unfinished"
    unfinished.mkdir()
    (unfinished / "config.json").write_bytes((finished / "config.json").read_bytes())
    lines = (finished / DECISIONS_FILE).read_text().splitlines(keepends=True)
    (unfinished / DECISIONS_FILE).write_text("".join(lines[:3]))
    with pytest.raises(AmazeError, match="3 of the 6 decisions"):
        ToyRun.replay(unfinished, tmp_path / "new")
    direct = tmp_path / "direct"
    direct.mkdir()
    (direct / "config.json").write_text(json.dumps({"regime": "direct"}))
    with pytest.raises(AmazeError, match="records no decisions"):
        ToyRun.replay(direct, tmp_path / "new2")
    assert not (tmp_path / "new").exists() and not (tmp_path / "new2").exists()


def _damaged(line: int, text: str):
    def damage(path: Path) -> None:
        lines = path.read_text().splitlines()
        lines[line] = text
        path.write_text("\n".join(lines) + "\n")

    return damage


def _appended(path: Path) -> None:
    lines = path.read_text().splitlines()
    path.write_text("\n".join([*lines, lines[-1]]) + "\n")


def _record(line: int, **changes):
    def damage(path: Path) -> None:
        lines = path.read_text().splitlines()
        data = json.loads(lines[line])
        data.update(changes)
        lines[line] = json.dumps(data)
        path.write_text("\n".join(lines) + "\n")

    return damage


@pytest.mark.parametrize(
    ("damage", "message"),
    [
        (_damaged(2, "{not json"), "line 3: is not JSON"),
        (_damaged(2, "[1, 2]"), "line 3: not a JSON object"),
        (_record(2, kind="select"), "line 3: stage 1 kind 'select'"),
        (_record(2, mazes=["M5_8x8_X9"]), "line 3: .*not a list of 2 maze strings"),
        (_record(2, mazes=["M5_8x8_C1", "M1_1000x8_C1"]), "line 3: .*bad maze"),
        (_record(3, choice=2), "line 4: choice 2 is not one of the 2 branches"),
        (_record(3, choice="0"), "line 4: choice '0' is not a branch number"),
        (_record(1, seconds=None), "line 2: seconds None"),
        (_appended, "line 7: one decision too many"),
    ],
)
def test_a_damaged_decisions_file_is_refused_by_name_and_nothing_changes(
    tmp_path: Path, finished: Path, damage, message: str
) -> None:
    out = tmp_path / "run"
    _copy(finished, out)
    (out / "summary.json").unlink()
    damage(out / DECISIONS_FILE)
    before = snapshot(out)
    with pytest.raises(AmazeError, match=f"decisions file .*{DECISIONS_FILE}.*{message}"):
        ToyRun.resume(out)
    assert snapshot(out) == before


def test_a_damaged_branch_result_is_refused_by_name(tmp_path: Path, finished: Path) -> None:
    out = tmp_path / "run"
    _copy(finished, out)
    (out / "summary.json").unlink()
    result = out / "stages/stage-1/branch-1/result.json"
    data = json.loads(result.read_text())
    del data["lineage"]
    result.write_text(json.dumps(data))
    before = snapshot(out)
    with pytest.raises(AmazeError, match=r"branch result .*branch-1/result\.json.* damaged"):
        ToyRun.resume(out)
    assert snapshot(out) == before


def test_resume_of_a_finished_run_redoes_nothing(tmp_path: Path, finished: Path) -> None:
    out = tmp_path / "run"
    _copy(finished, out)
    before = choices(out)
    result = ToyRun.resume(out)
    assert choices(out) == before
    assert result.summary["env_steps"] == 6000


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        (
            {"regime": "direct", "curator": "careful"},
            "curator .* 'careful' has no effect in the direct regime",
        ),
        (
            {"regime": "direct", "curator": None, "stages": 3},
            "stages .* 3 has no effect in the direct regime",
        ),
        ({"regime": "interpolation", "curator": "random"}, "interpolation regime's curator"),
        ({"curator": "nobody"}, "unknown curator 'nobody' .*careful"),
        ({"stages": -1}, "stages"),
        ({"regime": "interpolation", "curator": None, "stages": 0}, "interpolation has a fixed"),
        ({"rehearsal": 65}, "rehearsal"),
        ({"epochs": 5}, "epochs 5 is for open-ended curricula"),
        ({"stages": 0, "epochs": 0}, "epochs"),
        (
            {"regime": "direct", "curator": None, "stages": None, "branches": None, "rehearsal": 2},
            "rehearsal .* 2 has no effect",
        ),
        ({"branches": 65}, "branches"),
        ({"target": "M5_8x8_Q"}, "target 'M5_8x8_Q'"),
        ({"curator_options": [1]}, "curator_options"),
        ({"regime": "curricular"}, "regime 'curricular'"),
        ({"regime": "coevolution"}, "regime 'coevolution' is not run by this trainer"),
        (
            {"coevolution": {"batch": 2}},
            "coevolution .* has no effect in the edhucat regime: it is for coevolution",
        ),
    ],
)
def test_bad_regime_fields_are_refused_naming_the_value(changes: dict, message: str) -> None:
    with pytest.raises(AmazeError, match=message):
        ToyConfig.from_dict({**CONFIG, **changes})


def test_a_curriculum_config_records_its_defaults() -> None:
    config = ToyConfig.from_dict({"regime": "edhucat"})
    assert (config.curator, config.stages, config.branches) == ("careful", 10, 3)
    assert config.rehearsal == 0 and not config.open_ended  # the paper's loop
    edens = ToyConfig.from_dict({"regime": "edens"})
    assert (edens.stages, edens.branches, edens.rehearsal, edens.open_ended) == (0, 3, 7, True)
    assert edens.epochs == OPEN_EPOCHS and config.epochs is None
    direct = ToyConfig.from_dict({})
    assert (direct.curator, direct.stages, direct.branches) == (None, None, None)


class MisbehavingCurator:
    """Generates one maze too few, or selects something that is not a candidate."""

    name = "misbehaving"

    def __init__(self, context) -> None:
        self.mode = context.options.get("mode")

    def select(self, candidates):
        return "the best one" if self.mode == "select" else candidates[0]

    def generate(self, k, history):
        return ["M1_5x5_U"] * (k - 1 if self.mode == "generate" else k)


@pytest.mark.parametrize(
    ("mode", "message"),
    [
        ("generate", "curator 'misbehaving' generated .*not a list of 2 maze strings"),
        ("select", "curator 'misbehaving' selected 'the best one', not one of the candidates"),
    ],
)
def test_a_misbehaving_curator_stops_the_run_with_a_clear_error(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, mode: str, message: str
) -> None:
    monkeypatch.setitem(
        curators.BUILTIN_CURATORS,
        "misbehaving",
        "tests.amaze.runs.test_curriculum:MisbehavingCurator",
    )
    config = {**CONFIG, "curator": "misbehaving", "curator_options": {"mode": mode}}
    with pytest.raises(AmazeError, match=message):
        ToyRun.fresh(config, tmp_path / "run")
    # What was decided before the error is kept, and the run can resume.
    assert decisions(tmp_path / "run")[0]["kind"] == "generate"


def test_the_decision_log_appends_whole_lines(tmp_path: Path, finished: Path) -> None:
    log = DecisionLog(tmp_path / DECISIONS_FILE)
    recorded = DecisionLog(finished / DECISIONS_FILE).read(3, 2, AmazeError)
    for decision in recorded[:3]:
        log.append(decision)
    assert log.read(3, 2, AmazeError) == recorded[:3]
    assert (tmp_path / DECISIONS_FILE).read_text().count("\n") == 3


def _branches(folder: Path) -> list[Path]:
    return sorted(p.parent for p in folder.glob("stages/stage-*/branch-*/result.json"))


def _copy(source: Path, target: Path) -> None:
    import shutil

    shutil.copytree(source, target)


def test_branches_that_share_a_maze_keep_their_own_results_on_resume(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(
        curators.BUILTIN_CURATORS,
        "misbehaving",
        "tests.amaze.runs.test_curriculum:MisbehavingCurator",
    )
    out = tmp_path / "run"
    ToyRun.fresh({**CONFIG, "curator": "misbehaving"}, out)  # every branch: M1_5x5_U
    run = ToyRun(out, ToyRun.read_config(out))
    for branch in range(2):
        folder = out / f"stages/stage-2/branch-{branch}"
        data = json.loads((folder / "result.json").read_text())
        candidate = run._read_candidate(folder)
        assert candidate.own[0].to_dict() == data["results"][branch]
        assert [r.to_dict() for r in candidate.others] == [data["results"][1 - branch]]


@dataclass
class TimedConfig(ToyConfig):
    budget_steps: int | None = None
    budget_seconds: float | None = 4.0


class TimedRun(ToyRun):
    config_class = TimedConfig


def test_a_seconds_budget_is_shared_like_steps_from_what_branches_took(tmp_path: Path) -> None:
    out = tmp_path / "run"
    config = {**CONFIG, "budget_steps": None, "budget_seconds": 4.0, "final_training": False}
    result = TimedRun.fresh(config, out)
    assert result.summary["budget_seconds"] == 4.0
    spent = 0.0
    for stage in range(3):
        folders = sorted(out.glob(f"stages/stage-{stage}/branch-*"))
        expected = branch_seconds(4.0, spent, stage, 3, 2)
        for folder in folders:
            given = json.loads((folder / "agent/toy.json").read_text())["budget_seconds"]
            assert given == pytest.approx(expected, abs=1e-12)
            spent += json.loads((folder / "result.json").read_text())["seconds"]
    assert result.summary["seconds"] == pytest.approx(spent, abs=1e-6)


def test_a_replay_resumes_from_its_own_copy_of_the_decisions(
    tmp_path: Path, finished: Path
) -> None:
    import shutil

    source = tmp_path / "source"
    shutil.copytree(finished, source)
    out = tmp_path / "replay"
    ToyRun.replay(source, out)
    (out / "summary.json").unlink()
    shutil.rmtree(source)  # the replayed run is gone: its copy in the folder is enough
    assert choices(ToyRun.resume(out).out) == choices(finished)


def test_each_branch_says_where_its_time_went(finished: Path) -> None:
    summary = json.loads((finished / "summary.json").read_text())
    parts = ("training", "loading_and_saving", "evaluation", "picture")
    assert set(summary["time"]) == set(parts)
    total = 0.0
    for branch in _branches(finished):
        result = json.loads((branch / "result.json").read_text())
        assert set(result["time"]) == set(parts)
        assert sum(result["time"].values()) == pytest.approx(result["seconds"], abs=0.01)
        total += result["seconds"]
    assert sum(summary["time"].values()) == pytest.approx(total, abs=0.01)
    assert summary["seconds"] == pytest.approx(total, abs=0.01)


# -- open-ended stages and rehearsal ---------------------------------------------------

OPEN = {**CONFIG, "stages": 0, "rehearsal": 2}


@pytest.fixture(scope="module")
def open_ended(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("open") / "run"
    ToyRun.fresh(OPEN, out)
    return out


@pytest.mark.slow
def test_an_open_ended_run_plays_epochs_until_its_budget_is_spent(open_ended: Path) -> None:
    summary = json.loads((open_ended / "summary.json").read_text())
    # Each branch may spend an epoch, 6000 // (2 * 100) = 30 steps: stage 0 trains one
    # agent (30), 99 stages of two (5940); 30 are left, under 1 % of the budget: over.
    assert OPEN_EPOCHS == 100
    assert branch_allowance(6000, 0, 0, 0, 2) == 30
    assert summary["stages"] == 0 and summary["stages_played"] == 100
    assert summary["env_steps"] == 5970
    rows = [json.loads((p / "result.json").read_text()) for p in _branches(open_ended)]
    steps = {(r["stage"], r["branch"]): r["env_steps"] for r in rows}
    assert set(steps.values()) == {30}
    assert branch_allowance(6000, 5950, 99, 0, 2) == 25  # what is left, when less
    sequence = [(d["stage"], d["kind"]) for d in decisions(open_ended)]
    assert sequence == decision_sequence(0)[: 2 * 100] and sequence[-1] == (100, "select")


def test_an_open_ended_branch_rehearses_its_lineages_mazes(open_ended: Path) -> None:
    made = decisions(open_ended)
    own = {}  # stage -> the selected branch's maze, from the decisions alone
    for decision in made:
        if decision["kind"] == "generate":
            mazes = decision["mazes"]
        else:
            own[decision["stage"] - 1] = mazes[decision["choice"]]
    for folder in _branches(open_ended):
        result = json.loads((folder / "result.json").read_text())
        stage, maze = result["stage"], result["mazes"][0]
        lineage = []
        for earlier in range(stage - 1, -1, -1):
            if own[earlier] not in lineage:
                lineage.append(own[earlier])
        expected = [maze, *[m for m in lineage if m != maze][:2]]
        assert result["training_mazes"] == expected
    assert any(len(json.loads((f / "result.json").read_text())["training_mazes"]) == 3
               for f in _branches(open_ended))  # fmt: skip


@pytest.mark.slow
def test_an_open_ended_run_resumes_and_replays_to_the_same_curriculum(
    tmp_path: Path, open_ended: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls = {"n": 0}
    original = ToyLearner.train

    def dying(self, mazes, budget_steps, *, budget_seconds=None, checkpoint=None, progress=None):
        calls["n"] += 1
        if calls["n"] == 117:  # a branch of stage 58
            raise Interrupted
        return original(self, mazes, budget_steps, checkpoint=checkpoint)

    monkeypatch.setattr(ToyLearner, "train", dying)
    out = tmp_path / "run"
    with pytest.raises(Interrupted):
        ToyRun.fresh(OPEN, out)
    monkeypatch.setattr(ToyLearner, "train", original)
    ToyRun.resume(out)
    assert choices(out) == choices(open_ended)
    replay = ToyRun.replay(open_ended, tmp_path / "replay")
    assert choices(tmp_path / "replay") == choices(open_ended)
    assert replay.summary["stages_played"] == 100
    unfinished = tmp_path / "unfinished"
    unfinished.mkdir()
    (unfinished / "config.json").write_bytes((open_ended / "config.json").read_bytes())
    (unfinished / DECISIONS_FILE).write_bytes((open_ended / DECISIONS_FILE).read_bytes())
    with pytest.raises(AmazeError, match="unfinished open-ended run"):
        ToyRun.replay(unfinished, tmp_path / "new")


def test_an_open_ended_run_ends_once_its_seconds_are_spent(tmp_path: Path) -> None:
    out = tmp_path / "run"
    result = TimedRun.fresh({**OPEN, "budget_steps": None, "budget_seconds": 0.6}, out)
    summary = result.summary
    assert 0.6 * 0.99 <= summary["seconds"] < 0.6 + 1.0  # spent, give or take the last stage
    assert summary["stages_played"] >= 2
    spent = 0.0
    for stage in range(summary["stages_played"]):
        expected = branch_seconds(0.6, spent, stage, 0, 2)
        assert expected <= 0.6 / (2 * OPEN_EPOCHS)  # an epoch at most
        for folder in sorted(out.glob(f"stages/stage-{stage}/branch-*")):
            given = json.loads((folder / "agent/toy.json").read_text())["budget_seconds"]
            assert given == pytest.approx(expected, abs=1e-12)
            spent += json.loads((folder / "result.json").read_text())["seconds"]


def test_when_a_curriculum_is_over() -> None:
    assert curriculum_over(3, 3) and not curriculum_over(2, 3)  # a fixed number of stages
    assert curriculum_over(5, 0, [(None, 10.0), (100.0, 99.5)])  # under 1 % left
    assert not curriculum_over(5, 0, [(None, 10.0), (100.0, 98.0)])
    assert not curriculum_over(0, 0, [(100.0, 100.0)])  # stage 0 always plays
    assert curriculum_over(MAX_OPEN_STAGES, 0, [(100.0, 0.0)])
    with pytest.raises(ValueError, match="stage 400"):
        branch_allowance(100, 0, MAX_OPEN_STAGES, 0, 2)
    assert branch_allowance(1000, 100, MAX_OPEN_STAGES - 1, 0, 2) == 450  # the last shares all


class _EarlyLearner(ToyLearner):
    """Converges after half its allowance, leaving the rest of the budget unspent."""

    def train(self, mazes, budget_steps, *, budget_seconds=None, checkpoint=None, progress=None):
        outcome = super().train(mazes, budget_steps // 2, checkpoint=checkpoint, progress=progress)
        return type(outcome)(outcome.env_steps, outcome.seconds, True)

    def branch(self, seed):
        return _EarlyLearner(seed, self.trained)


class _EarlyRun(ToyRun):
    def new_learner(self, seed):
        return _EarlyLearner(seed)

    def load_learner(self, folder):
        toy = super().load_learner(folder)
        return _EarlyLearner(toy.seed, toy.trained, toy.session)


def test_final_training_spends_what_the_stages_left_on_the_lineages_mazes(
    tmp_path: Path,
) -> None:
    out = tmp_path / "run"
    summary = _EarlyRun.fresh(CONFIG, out).summary
    stages = sum(s["env_steps"] for s in summary["curriculum"])
    assert stages < 6000 * 0.7  # every branch converged on half its allowance
    final = summary["final_training"]
    lineage = summary["final_mazes"] + [
        m for m in final["mazes"] if m not in summary["final_mazes"]
    ]
    assert final["mazes"] == lineage and len(final["mazes"]) == 3  # one maze a stage
    trained = json.loads((out / "stages/final/agent/toy.json").read_text())
    assert final["env_steps"] == (6000 - stages) // 2  # it converged too, on half of what was left
    assert summary["env_steps"] == stages + final["env_steps"]
    assert summary["agent_rule"].endswith("then trained on its lineage's mazes")
    assert json.loads((out / "agent.json").read_text())["seed"] == trained["seed"] % 1000
    assert summary["stopped_early"].startswith("the final agent converged on its lineage's mazes")
    off = _EarlyRun.fresh({**CONFIG, "final_training": False}, tmp_path / "off").summary
    assert off["final_training"] is None and off["env_steps"] == stages
    assert "final_training is off" in off["stopped_early"]
    (out / "summary.json").unlink()  # resumed after its final training: nothing is redone
    assert _EarlyRun.resume(out).summary["env_steps"] == summary["env_steps"]
