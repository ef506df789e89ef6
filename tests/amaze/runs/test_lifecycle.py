"""The shared run lifecycle (fresh, resume, finish) and command skeleton, on a toy trainer.

The toy trainer counts steps, writes one progress row per step and a
checkpoint every other step; its agent is the seeded random controller. A
"kill" is an exception raised mid-run after a row was written but before the
next checkpoint, which is what a real kill leaves behind.
"""

from __future__ import annotations

import argparse
import errno
import gc
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import pytest

from amaze.errors import AmazeError
from amaze.evaluation.controllers import RandomController
from amaze.runs.anytime import Spent
from amaze.runs.command import TrainingCommand
from amaze.runs.config import RunConfig, option
from amaze.runs.folder import write_json
from amaze.runs.lifecycle import Run, frozen_heap
from tests.run_folders import snapshot


class CountingError(AmazeError):
    """Bad input to the toy trainer."""


@dataclass
class CountingConfig(RunConfig):
    error = CountingError
    options_field = "extra"

    steps: int = option(6, "steps to count")
    factor: float = option(1.5, "what each step adds")
    mazes: list[str] = option(default_factory=lambda: ["M0_5x5_U"], help="mazes to draw")
    verbose: bool = option(False, "say more")
    extra: dict[str, Any] = option(default_factory=dict, help="options", command_line=False)

    def validate(self) -> CountingConfig:
        super().validate()
        if isinstance(self.steps, bool) or not isinstance(self.steps, int) or self.steps < 1:
            raise CountingError(f"steps {self.steps!r} is not a positive integer")
        return self


class _Killed(Exception):
    pass


class CountingRun(Run):
    config_class = CountingConfig
    progress_fields = ("step", "total")
    position_field = "step"
    checkpoint_files = ("state.json",)
    outputs = ("summary.json", "progress.csv")
    #: Raise after writing this step's row (before its checkpoint): a kill.
    kill_at: ClassVar[int | None] = None
    config: CountingConfig

    def start(self) -> None:
        self.step, self.total = 0, 0.0

    def restore(self) -> int | None:
        state = self.checkpoints / "state.json"
        if not state.exists():
            return None
        saved = json.loads(state.read_text())
        self.step, self.total = saved["step"], saved["total"]
        return self.step

    def train(self, progress: str) -> None:
        while self.step < self.config.steps:
            self.step += 1
            self.total += self.config.factor
            self.progress.append({"step": self.step, "total": self.total})
            if self.step == type(self).kill_at:
                raise _Killed
            if self.step % 2 == 0:
                write_json(
                    self.checkpoints / "state.json", {"step": self.step, "total": self.total}
                )

    def final_agent(self) -> RandomController:
        return RandomController(self.config.robot, seed=self.config.seed)

    def spent(self) -> Spent:
        return Spent(self.step, self.step, 0.0)

    def figures(self) -> dict[str, Any]:
        return {"env_steps": self.step, "seconds": 0.0, "total": self.total}

    agent_file = "agent.json"

    def save_agent(self, agent: RandomController, path: Path) -> None:
        write_json(path, {"controller": "random", "seed": agent.seed})

    def agent_figures(self) -> dict[str, Any]:
        return {"agent_rule": "final", "agent_steps": self.step, "agent_untrained": False}

    def trajectory_mazes(self) -> list[tuple[str, str]]:
        return [(f"maze-{i}", maze) for i, maze in enumerate(self.config.mazes)]


def _rows(out: Path) -> list[str]:
    return (out / "progress.csv").read_text().splitlines()


def test_fresh_run_writes_the_whole_folder(tmp_path: Path) -> None:
    result = CountingRun.fresh({"steps": 4, "seed": 3}, tmp_path / "run")
    out = tmp_path / "run"
    assert json.loads((out / "config.json").read_text())["steps"] == 4
    assert _rows(out) == ["step,total", "1,1.5", "2,3.0", "3,4.5", "4,6.0"]
    summary = json.loads((out / "summary.json").read_text())
    assert summary == result.summary and result.env_steps == 4 and summary["total"] == 6.0
    for key in ("success_rate", "normalized_reward", "input_recognition"):
        assert key in summary  # the standard suite, through the one evaluation protocol
    assert (out / "trajectories" / "maze-0.png").stat().st_size > 0
    assert result.out == out and isinstance(result.agent, RandomController)


def test_resume_after_a_kill_equals_an_uninterrupted_run(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    whole = CountingRun.fresh({"steps": 7}, tmp_path / "whole")
    monkeypatch.setattr(CountingRun, "kill_at", 5)
    with pytest.raises(_Killed):
        CountingRun.fresh({"steps": 7}, tmp_path / "killed")
    killed = tmp_path / "killed"
    assert len(_rows(killed)) == 6 and not (killed / "summary.json").exists()
    monkeypatch.setattr(CountingRun, "kill_at", None)
    resumed = CountingRun.resume(killed)
    # row 5, written after the last checkpoint (step 4), is dropped and written again
    assert _rows(killed) == _rows(tmp_path / "whole")
    assert resumed.summary == whole.summary


def test_resume_without_a_checkpoint_starts_over(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(CountingRun, "kill_at", 1)
    with pytest.raises(_Killed):
        CountingRun.fresh({"steps": 3}, tmp_path / "run")
    monkeypatch.setattr(CountingRun, "kill_at", None)
    CountingRun.resume(tmp_path / "run")
    assert _rows(tmp_path / "run") == ["step,total", "1,1.5", "2,3.0", "3,4.5"]


def test_an_existing_run_is_never_written_over(tmp_path: Path) -> None:
    CountingRun.fresh({"steps": 2}, tmp_path / "run")
    before = snapshot(tmp_path / "run")
    with pytest.raises(CountingError, match="already holds a run"):
        CountingRun.fresh({"steps": 5}, tmp_path / "run")
    assert snapshot(tmp_path / "run") == before


def test_bad_config_fails_before_anything_is_written(tmp_path: Path) -> None:
    with pytest.raises(CountingError, match="steps 0"):
        CountingRun.fresh({"steps": 0}, tmp_path / "run")
    with pytest.raises(CountingError, match="'colour'"):
        CountingRun.fresh({"colour": "red"}, tmp_path / "run")
    with pytest.raises(CountingError, match="robot 'XX'"):
        CountingRun.fresh({"robot": "XX"}, tmp_path / "run")
    assert not (tmp_path / "run").exists()


def test_resume_says_what_a_folder_without_a_run_is(tmp_path: Path) -> None:
    with pytest.raises(CountingError, match=r"'.*missing' does not exist"):
        CountingRun.resume(tmp_path / "missing")
    (tmp_path / "file").write_text("x")
    with pytest.raises(CountingError, match="is not a folder"):
        CountingRun.resume(tmp_path / "file")
    for seed in (3, 4):
        (tmp_path / "replicates" / f"seed-{seed}").mkdir(parents=True)
        (tmp_path / "replicates" / f"seed-{seed}" / "config.json").write_text("{}")
    with pytest.raises(CountingError, match=r"holds replicates \(seed-3, seed-4\).*seed-3"):
        CountingRun.resume(tmp_path / "replicates")


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (None, "holds no run"),
        (b"{not json", "is not JSON"),
        (b"\xff\xfe\x00binary", "is not UTF-8 text"),
        (b"[1, 2]", "does not hold a JSON object"),
        (b'{"steps": "many"}', "steps 'many'"),
        (b'{"steps": 2, "shape": 1}', "'shape'"),
    ],
)
def test_resume_refuses_a_bad_config_naming_it(
    tmp_path: Path, content: bytes | None, message: str
) -> None:
    out = tmp_path / "run"
    out.mkdir()
    if content is not None:
        (out / "config.json").write_bytes(content)
    before = snapshot(out)
    with pytest.raises(CountingError, match=message):
        CountingRun.resume(out)
    assert snapshot(out) == before


# -- the command skeleton --------------------------------------------------------

COMMAND = TrainingCommand(
    prog="amaze-count", description="Count.", module="no.such.module", run_class=CountingRun
)


def test_config_fields_drive_the_command_line(tmp_path: Path, capsys) -> None:
    help_text = COMMAND.parser().format_help()
    for flag, words in [
        ("--steps", "steps to count (default: 6)"),
        ("--factor", "what each step adds"),
        ("--mazes", "mazes to draw"),
        ("--verbose", "say more"),
        ("--robot", "robot"),
        ("--seed", "seed"),
    ]:
        assert flag in help_text and words in " ".join(help_text.split())
    assert "--extra" not in help_text  # nested options come through --config only
    out = tmp_path / "run"
    argv = ["--steps", "3", "--factor", "2", "--mazes", "M0_5x5_U, M1_5x5_U", "--verbose"]
    assert COMMAND.main([*argv, "--out", str(out), "--no-progress"]) == 0
    saved = json.loads((out / "config.json").read_text())
    assert saved["steps"] == 3 and saved["factor"] == 2.0 and saved["verbose"] is True
    assert saved["mazes"] == ["M0_5x5_U", "M1_5x5_U"]
    printed = capsys.readouterr().out.splitlines()
    assert printed[0].startswith("3 env steps")
    assert printed[1] == "agent: agent.json (rule final, found at 3 env steps)"
    assert printed[-1].startswith(f"run folder: {out}")


def test_a_config_file_is_a_whole_config_or_the_options(tmp_path: Path) -> None:
    args = COMMAND.parser().parse_args(["--steps", "9"])
    whole = tmp_path / "whole.json"
    whole.write_text(json.dumps({"steps": 4, "factor": 3.0}))
    assert CountingConfig.from_file_and_arguments(args, str(whole)) == {"steps": 9, "factor": 3.0}
    options = tmp_path / "options.json"
    options.write_text(json.dumps({"depth": 2}))
    data = CountingConfig.from_file_and_arguments(args, str(options))
    assert data == {"extra": {"depth": 2}, "steps": 9}


@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (["--steps", "x"], "invalid int value: 'x'"),
        (["--steps", "0", "--out", "{out}"], "steps 0"),
        (["--nope"], "unrecognized arguments: --nope"),
        ([], "--out is required"),
        (["--resume", "{out}"], "does not exist"),
        (["--config", "{missing}", "--out", "{out}"], "does not exist"),
        (["--replicates", "0", "--out", "{out}"], "--replicates 0"),
    ],
)
def test_command_errors_are_one_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], words: str
) -> None:
    paths = {"out": str(tmp_path / "run"), "missing": str(tmp_path / "missing.json")}
    assert COMMAND.main([a.format(**paths) for a in argv]) == 2
    captured = capsys.readouterr()
    lines = captured.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and words in lines[0]
    assert captured.out == "" and not (tmp_path / "run").exists()


def test_an_unwritable_folder_is_one_error_line(tmp_path: Path, capsys) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    assert COMMAND.main(["--out", str(blocker / "run")]) == 2
    assert capsys.readouterr().err.startswith("error: ")


def test_adjust_command_line_hook_sees_the_arguments() -> None:
    class Adjusted(CountingConfig):
        @classmethod
        def adjust_command_line(cls, data: dict, args: argparse.Namespace) -> dict:
            return {**data, "factor": 0.5} if args.verbose else data

    parser = argparse.ArgumentParser()
    Adjusted.add_arguments(parser)
    assert Adjusted.from_file_and_arguments(parser.parse_args(["--verbose"]), None) == {
        "verbose": True,
        "factor": 0.5,
    }


@pytest.mark.parametrize(
    ("code", "words"),
    [(errno.EROFS, "Read-only file system"), (errno.ENOSPC, "No space left on device")],
)
def test_an_unwritable_disk_is_one_error_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys, code: int, words: str
) -> None:
    import amaze.runs.folder

    def refuse(path, data):
        raise OSError(code, os.strerror(code), str(path))

    monkeypatch.setattr(amaze.runs.folder, "write_bytes", refuse)
    assert COMMAND.main(["--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: {words}: ") and "config.json" in err[0]


class _FreezeWatchingRun(CountingRun):
    """Records how many objects the garbage collector left out while it trained."""

    frozen: ClassVar[list[int]] = []

    def train(self, progress: str) -> None:
        type(self).frozen.append(gc.get_freeze_count())
        super().train(progress)


def test_training_runs_with_the_set_up_frozen_out_of_the_collector(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    assert gc.get_freeze_count() == 0
    _FreezeWatchingRun.fresh({"steps": 4}, tmp_path / "run")
    monkeypatch.setattr(CountingRun, "kill_at", 3)
    with pytest.raises(_Killed):
        _FreezeWatchingRun.fresh({"steps": 4}, tmp_path / "killed")
    assert gc.get_freeze_count() == 0  # given back, on an error too
    monkeypatch.setattr(CountingRun, "kill_at", None)
    _FreezeWatchingRun.resume(tmp_path / "killed")
    assert len(_FreezeWatchingRun.frozen) == 3 and min(_FreezeWatchingRun.frozen) > 1000
    assert gc.get_freeze_count() == 0
    with frozen_heap():
        garbage: list[object] = []
        garbage.append(garbage)  # a cycle made meanwhile is still collected
        del garbage
        assert gc.collect() >= 1


def test_progress_without_a_terminal_is_a_plain_line_at_least_every_period() -> None:
    import io
    import time

    from amaze.runs.progress import Progress

    stream = io.StringIO()
    with Progress(1000, "steps", "demo", mode="lines", every=0.05, stream=stream) as shown:
        for done in range(0, 1001, 100):
            shown.update(done, best="0.5")
            time.sleep(0.02)
    lines = stream.getvalue().splitlines()
    assert lines[0].endswith("demo: 0% of 1,000 steps; 0.0s elapsed; started")
    assert lines[-1].split("] ")[1].startswith("demo: 100% of 1,000 steps;")
    assert lines[-1].endswith("done; best 0.5")
    assert 3 <= len(lines) <= 8  # about one a period between the first and the last
    assert any("ETA" in line for line in lines[1:-1])
    quiet = io.StringIO()
    with Progress(10, "steps", "demo", mode="off", stream=quiet) as shown:
        shown.update(5)
    assert quiet.getvalue() == ""
