"""A curriculum run refuses what it can tell was changed, and the failures of its curator.

Tampering the loop can detect (a decision changed under a branch in training
or under finished results, impossible figures, another config) is refused by
name before training goes on; a steps budget too small for a branch is refused
before the folder is written; a curator that raises, whatever it raises, ends
the run with one error naming it.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from amaze.errors import AmazeError
from amaze.runs.decisions import DECISIONS_FILE
from tests.amaze.runs.test_curriculum import CONFIG, Interrupted
from tests.amaze.runs.toy_curriculum import ToyLearner, ToyRun
from tests.run_folders import snapshot


def _edit_decisions(out: Path, index: int, **changes: object) -> None:
    path = out / DECISIONS_FILE
    lines = [json.loads(line) for line in path.read_text().splitlines()]
    lines[index].update(changes)
    path.write_text("".join(json.dumps(line) + "\n" for line in lines))


def _edit_json(path: Path, **changes: object) -> None:
    path.write_text(json.dumps({**json.loads(path.read_text()), **changes}))


@pytest.fixture(scope="module")
def killed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A run killed inside stage 2's branch 0, after one of its checkpoints."""
    out = tmp_path_factory.mktemp("killed") / "run"
    original = ToyLearner.train
    calls = {"n": 0}

    def dying(self, mazes, budget_steps, *, budget_seconds=None, checkpoint=None, progress=None):
        def checkpoint_then_die() -> None:
            checkpoint()
            calls["n"] += 1
            if calls["n"] == 9:  # stage 0: 2 chunks, stage 1: 2 x 3; the 9th: stage 2, branch 0
                raise Interrupted

        return original(self, mazes, budget_steps, checkpoint=checkpoint_then_die)

    ToyLearner.train = dying
    try:
        with pytest.raises(Interrupted):
            ToyRun.fresh(CONFIG, out)
    finally:
        ToyLearner.train = original
    assert (out / "stages/stage-2/branch-0/checkpoint/toy.json").is_file()
    assert (out / "stages/stage-2/branch-0/branch.json").is_file()
    return out


@pytest.fixture(scope="module")
def finished(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("finished") / "run"
    ToyRun.fresh(CONFIG, out)
    (out / "summary.json").unlink()  # as if killed while writing its pictures
    return out


def _refused(source: Path, tmp_path: Path, tamper, words: str) -> None:
    out = tmp_path / "run"
    shutil.copytree(source, out)
    tamper(out)
    before = snapshot(out)
    with pytest.raises(AmazeError, match=words):
        ToyRun.resume(out)
    assert snapshot(out) == before


def test_a_killed_run_resumes_when_nothing_was_changed(killed: Path, tmp_path: Path) -> None:
    out = tmp_path / "run"
    shutil.copytree(killed, out)
    assert ToyRun.resume(out).summary["env_steps"] == 6000


def test_another_maze_for_the_branch_in_training_is_refused(killed: Path, tmp_path: Path) -> None:
    def tamper(out: Path) -> None:
        generate = json.loads((out / DECISIONS_FILE).read_text().splitlines()[4])
        mazes = generate["mazes"]
        _edit_decisions(out, 4, mazes=[mazes[1], mazes[1]])

    _refused(killed, tmp_path, tamper, r"branch\.json'.*training_mazes")


def test_another_parent_for_the_branch_in_training_is_refused(killed: Path, tmp_path: Path) -> None:
    def tamper(out: Path) -> None:
        choice = json.loads((out / DECISIONS_FILE).read_text().splitlines()[3])["choice"]
        _edit_decisions(out, 3, choice=1 - choice)

    _refused(killed, tmp_path, tamper, r"parent_lineage .* changed since")


def test_another_budget_for_the_branch_in_training_is_refused(killed: Path, tmp_path: Path) -> None:
    def tamper(out: Path) -> None:
        _edit_json(out / "stages/stage-1/branch-1/result.json", env_steps=1000, lineage_steps=2000)

    _refused(killed, tmp_path, tamper, r"budget_steps .* changed since")


def test_a_changed_choice_under_finished_results_is_refused(finished: Path, tmp_path: Path) -> None:
    def tamper(out: Path) -> None:
        choice = json.loads((out / DECISIONS_FILE).read_text().splitlines()[3])["choice"]
        _edit_decisions(out, 3, choice=1 - choice)

    _refused(finished, tmp_path, tamper, r"descends from lineage .* but .* chose branch")


@pytest.mark.parametrize(
    ("changes", "words"),
    [
        ({"env_steps": -(10**11)}, "env_steps -100000000000 is not a non-negative integer"),
        ({"lineage_steps": 10}, "lineage_steps 10 is less than env_steps"),
        ({"seconds": float("nan")}, "seconds nan is not a finite number"),
        ({"stage": 2}, "lineage .* is not that of branch 1 of stage 2"),
        ({"lineage": [0, 0, 0]}, "lineage"),
        ({"converged": "yes"}, "converged 'yes'"),
        ({"time": {"training": -1}}, "time training -1"),
    ],
)
def test_impossible_figures_in_a_result_are_refused(
    finished: Path, tmp_path: Path, changes: dict, words: str
) -> None:
    def tamper(out: Path) -> None:
        _edit_json(out / "stages/stage-1/branch-1/result.json", **changes)

    _refused(finished, tmp_path, tamper, words)


def test_a_changed_config_is_refused_but_a_raised_budget_extends(
    finished: Path, tmp_path: Path
) -> None:
    _refused(
        finished,
        tmp_path,
        lambda out: _edit_json(out / "config.json", seed=8),
        r"result\.json' was written under another config\.json",
    )
    out = tmp_path / "extended"
    shutil.copytree(finished, out)
    _edit_json(out / "config.json", budget_steps=7000)
    assert ToyRun.resume(out).summary["budget_steps"] == 7000


def test_a_budget_too_small_for_a_branch_is_refused_before_the_folder_is_written(
    tmp_path: Path,
) -> None:
    with pytest.raises(AmazeError, match=r"gives each branch 0 steps .* give budget_steps >= 20"):
        ToyRun.fresh({**CONFIG, "stages": 10, "budget_steps": 10}, tmp_path / "run")
    assert not (tmp_path / "run").exists()


class _Curator:
    """A curator that fails as a plug-in might, in the method named ``fails``."""

    name = "random"

    def __init__(self, fails: str, problem: BaseException) -> None:
        self.fails, self.problem = fails, problem

    def select(self, candidates):
        if self.fails == "select":
            raise self.problem
        return candidates[0]

    def generate(self, k, history):
        if self.fails == "generate":
            raise self.problem
        return [history.mazes[0]] * k


@pytest.mark.parametrize(
    ("fails", "problem", "words"),
    [
        ("init", RuntimeError("bug"), r"being built \(RuntimeError: bug\)"),
        ("select", SystemExit(0), r"selecting \(SystemExit: 0\)"),
        (
            "generate",
            OSError("no such thing /x"),
            r"generating mazes \(OSError: no such thing /x\)",
        ),
        ("generate", ZeroDivisionError(), r"generating mazes \(ZeroDivisionError\)"),
    ],
)
def test_whatever_a_curator_raises_ends_the_run_with_an_error_naming_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, fails: str, problem: BaseException, words: str
) -> None:
    def make(name, context):
        if fails == "init":
            raise problem
        return _Curator(fails, problem)

    monkeypatch.setattr("amaze.runs.decisions.make_curator", make)
    with pytest.raises(AmazeError, match=f"curator 'random' failed {words}"):
        ToyRun.fresh(CONFIG, tmp_path / "run")
