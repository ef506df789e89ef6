"""Folders written whole: a kill at any moment leaves the old folder or the new one."""

from __future__ import annotations

import csv
import json
import os
from pathlib import Path

import pytest

from amaze.runs.folder import settled_folder, write_folder, write_rows
from tests.amaze.runs.test_curriculum import CONFIG, choices
from tests.amaze.runs.toy_curriculum import ToyError, ToyLearner, ToyRun


class Killed(Exception):
    pass


def _two_files(version: int, die_between: bool = False):
    def fill(folder: Path) -> None:
        (folder / "first.txt").write_text(str(version))
        if die_between:
            raise Killed
        (folder / "second.txt").write_text(str(version))

    return fill


def _read(folder: Path) -> tuple[str, str]:
    return (folder / "first.txt").read_text(), (folder / "second.txt").read_text()


def test_a_folder_killed_while_written_keeps_its_old_content(tmp_path: Path) -> None:
    folder = tmp_path / "checkpoint"
    write_folder(folder, _two_files(1))
    with pytest.raises(Killed):
        write_folder(folder, _two_files(2, die_between=True))
    assert _read(settled_folder(folder)) == ("1", "1")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["checkpoint"]


def test_a_first_folder_killed_while_written_is_not_there(tmp_path: Path) -> None:
    folder = tmp_path / "checkpoint"
    with pytest.raises(Killed):
        write_folder(folder, _two_files(1, die_between=True))
    assert not settled_folder(folder).exists()
    assert list(tmp_path.iterdir()) == []


def test_a_kill_between_the_renames_leaves_the_new_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    folder = tmp_path / "checkpoint"
    write_folder(folder, _two_files(1))
    renames = {"n": 0}
    real_replace = os.replace

    def replace_then_die(source, target) -> None:
        renames["n"] += 1
        if renames["n"] == 2:  # the old folder is aside, the new one not yet in place
            raise Killed
        real_replace(source, target)

    monkeypatch.setattr(os, "replace", replace_then_die)
    with pytest.raises(Killed):
        write_folder(folder, _two_files(2))
    monkeypatch.undo()
    assert not folder.exists()
    assert _read(settled_folder(folder)) == ("2", "2")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["checkpoint"]


def test_a_run_killed_while_saving_a_two_file_learner_resumes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The learner's files disagree nowhere after a kill between them (both trainers write two)."""
    finished = tmp_path / "finished"
    ToyRun.fresh(CONFIG, finished)
    original_save, original_load = ToyLearner.save, ToyRun.load_learner
    saves = {"n": 0, "die_at": 3}

    def save_in_two(self, folder) -> None:
        (Path(folder) / "count.json").write_text(json.dumps(self.trained))
        saves["n"] += 1
        if saves["n"] == saves["die_at"]:
            raise Killed
        original_save(self, folder)

    def load_both(self, folder):
        learner = original_load(self, folder)
        count = Path(folder) / "count.json"
        if not count.exists() or json.loads(count.read_text()) != learner.trained:
            raise ToyError(f"the files of {str(folder)!r} disagree")
        return learner

    monkeypatch.setattr(ToyLearner, "save", save_in_two)
    monkeypatch.setattr(ToyRun, "load_learner", load_both)
    out = tmp_path / "run"
    with pytest.raises(Killed):
        ToyRun.fresh(CONFIG, out)
    saves["die_at"] = None
    ToyRun.resume(out)
    assert choices(out) == choices(finished)
    assert not list(out.rglob(".*.tmp")) and not list(out.rglob(".*.old"))


def test_write_rows_writes_csv_whole_and_in_place(tmp_path: Path) -> None:
    path = tmp_path / "deep" / "rows.csv"
    rows = [{"agent": "a, b", "score": 0.5}, {"agent": "c", "score": 1}]
    assert write_rows(path, rows) == path
    with path.open(newline="", encoding="utf-8") as stream:
        assert list(csv.DictReader(stream)) == [
            {"agent": "a, b", "score": "0.5"},
            {"agent": "c", "score": "1"},
        ]
    write_rows(path, rows[1:])  # replaced, not appended; no temporary file left
    assert path.read_text(encoding="utf-8").splitlines() == ["agent,score", "c,1"]
    assert sorted(p.name for p in path.parent.iterdir()) == ["rows.csv"]
