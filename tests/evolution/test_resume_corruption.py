"""``amaze-evolve --resume`` on damaged run folders: one ``error:`` line naming the file, exit 2,
and nothing in the folder changed (every file is checked before anything is written).
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path

import pytest

from amaze.runs.checkpoint import write_checkpoint
from evolution.checkpoint import evolution_codec
from evolution.cli import main
from evolution.run import EvolveConfig, _State, evolve
from tests.run_folders import RANDOM, directory, missing, refused_resume, snapshot, truncate, write

CONFIG = {
    "algo": "cmaes",
    "mazes": ["M0_5x5_U", "M1_5x5_C1"],
    "budget_steps": None,
    "max_generations": 3,
    "checkpoint_seconds": 0,
    "algorithm": {"population_size": 6},
}


@pytest.fixture(scope="module")
def finished_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("evolve") / "run"
    evolve(CONFIG, out)
    (out / "summary.json").unlink()  # as if killed after its last checkpoint
    return out


class _Payload:
    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return (Path.touch, (self.marker,))


def _edit_csv(change: Callable[[list[str]], list[str]]) -> Callable[[Path], None]:
    def edit(path: Path) -> None:
        lines = path.read_text().splitlines()
        path.write_text("\n".join(change(lines)) + "\n")

    return edit


def _old_version(path: Path) -> None:
    write_checkpoint(path, _State(algorithm=None, version=1), evolution_codec(_State))


def _foreign(path: Path) -> None:
    write_checkpoint(path, {"generation": 3}, evolution_codec(_State))


def _pickled(path: Path) -> None:
    import pickle

    path.write_bytes(pickle.dumps({"generation": 3}))


CASES = {
    # config.json
    "config missing": ("config.json", missing, "holds no run"),
    "config empty": ("config.json", write(b""), "is not JSON"),
    "config truncated": ("config.json", truncate, "is not JSON"),
    "config random bytes": ("config.json", write(RANDOM), "is not UTF-8 text"),
    "config directory": ("config.json", directory, "is a directory"),
    "config not an object": ("config.json", write(b"[1, 2]"), "does not hold a JSON object"),
    "config wrong type": ("config.json", write(b'{"seed": "zero"}'), "seed 'zero'"),
    "config unknown key": ("config.json", write(b'{"colour": 1}'), "'colour'"),
    # progress.csv
    "progress missing": ("progress.csv", missing, "no row at generation 3"),
    "progress empty": ("progress.csv", write(b""), "header"),
    "progress truncated": ("progress.csv", truncate, "progress.csv"),
    "progress random bytes": ("progress.csv", write(RANDOM), "not text"),
    "progress directory": ("progress.csv", directory, "is a directory"),
    "progress wrong header": (
        "progress.csv",
        _edit_csv(lambda lines: ["gen,steps", *lines[1:]]),
        "header",
    ),
    "progress garbage row": (
        "progress.csv",
        _edit_csv(lambda lines: [*lines, "garbage"]),
        "1 values",
    ),
    "progress bad generation": (
        "progress.csv",
        _edit_csv(lambda lines: [lines[0], "x" + lines[1][1:], *lines[2:]]),
        "generation 'x'",
    ),
    "progress going back": (
        "progress.csv",
        _edit_csv(lambda lines: [lines[0], lines[2], lines[1], lines[3]]),
        "goes back",
    ),
    # checkpoints/state.npz
    "checkpoint missing": ("checkpoints/state.npz", missing, "is missing"),
    "checkpoint empty": ("checkpoints/state.npz", write(b""), "is empty"),
    "checkpoint truncated": ("checkpoints/state.npz", truncate, "is damaged"),
    "checkpoint random bytes": ("checkpoints/state.npz", write(RANDOM), "not an amaze checkpoint"),
    "checkpoint directory": ("checkpoints/state.npz", directory, "is a directory"),
    "checkpoint wrong type": ("checkpoints/state.npz", _foreign, "does not hold a _State"),
    "checkpoint old version": ("checkpoints/state.npz", _old_version, "version 1"),
    "checkpoint a pickle": ("checkpoints/state.npz", _pickled, "is a pickle"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_a_damaged_file_is_refused_by_name_and_nothing_changes(
    finished_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], case: str
) -> None:
    name, damage, words = CASES[case]
    line = refused_resume(main, finished_run, tmp_path / "run", name, damage, capsys)
    assert Path(name).name in line and words in line, line


def test_a_checkpoint_with_a_code_payload_runs_nothing(
    finished_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    shutil.copytree(finished_run, out)
    marker = tmp_path / "marker"
    import pickle

    (out / "checkpoints" / "state.npz").write_bytes(pickle.dumps(_Payload(marker)))
    before = snapshot(out)
    assert main(["--resume", str(out)]) == 2
    assert "is a pickle" in capsys.readouterr().err
    assert not marker.exists() and snapshot(out) == before


def test_an_intact_folder_resumes(finished_run: Path, tmp_path: Path) -> None:
    out = tmp_path / "run"
    shutil.copytree(finished_run, out)
    assert main(["--resume", str(out), "--no-progress"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["generations"] == 3
    assert EvolveConfig.from_dict(json.loads((out / "config.json").read_text())).algo == "cmaes"


@pytest.mark.parametrize(
    ("content", "words"),
    [
        ({"progress.csv": "generation,steps\n"}, "not empty and holds no run"),
        ({"agent.npz": "old"}, "not empty and holds no run"),
    ],
)
def test_a_folder_that_is_not_a_run_is_never_written_over(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], content: dict, words: str
) -> None:
    out = tmp_path / "old"
    out.mkdir()
    for name, text in content.items():
        (out / name).write_text(text)
    before = snapshot(out)
    argv = ["--mazes", "M0_5x5_U", "--max-generations", "1", "--out", str(out)]
    assert main(argv) == 2
    assert words in capsys.readouterr().err
    assert snapshot(out) == before


def test_out_on_a_file_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    target = tmp_path / "file"
    target.write_text("keep me")
    assert main(["--mazes", "M0_5x5_U", "--max-generations", "1", "--out", str(target)]) == 2
    assert "is not a folder" in capsys.readouterr().err
    assert target.read_text() == "keep me"
