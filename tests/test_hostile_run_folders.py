"""Hostile and damaged files in run folders: no file runs code, every command refuses cleanly.

Each test runs :func:`tools.fuzz_resume.fuzz` (see its docstring) on a small run
of one trainer and regime: every file of the folder replaced by the pickle
that once ran a shell command through the checkpoint reader, then seeded
draws of hostile and damaged content, given to ``--resume``, ``--replay`` and
``amaze run --controller``. A try passes when the command ends with exit 0 or
with exactly one ``error:`` line and exit 2, and no marker file appeared
(the payloads create one only if code from the file ran).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.run_folders import load_tool

pytestmark = pytest.mark.slow

fuzz_resume = load_tool("fuzz_resume")

TRAINERS = sorted(fuzz_resume.RUNS)


@pytest.mark.parametrize("trainer", TRAINERS)
def test_no_file_of_a_run_folder_runs_code_on_resume(trainer: str, tmp_path: Path) -> None:
    report = fuzz_resume.fuzz(trainer, None, kind="pickle-generator-ctor", scratch=tmp_path)
    assert not report.failures, report.failures
    assert report.counts["refused"] >= 1  # the checkpoint, at least, is read and refused


@pytest.mark.parametrize("trainer", TRAINERS)
def test_hostile_and_damaged_files_end_in_one_error_line(trainer: str, tmp_path: Path) -> None:
    report = fuzz_resume.fuzz(trainer, 12, seed=1, scratch=tmp_path)
    assert not report.failures, report.failures


@pytest.mark.parametrize("trainer", ["evolve-edhucat", "train-edhucat"])
def test_a_replay_of_a_hostile_run_folder_runs_no_code(trainer: str, tmp_path: Path) -> None:
    report = fuzz_resume.fuzz(trainer, 10, mode="replay", hostile=True, seed=2, scratch=tmp_path)
    assert not report.failures, report.failures


@pytest.mark.parametrize("trainer", ["evolve-edhucat", "train"])
def test_no_file_of_a_run_folder_runs_code_as_a_controller(trainer: str, tmp_path: Path) -> None:
    report = fuzz_resume.fuzz(
        trainer, None, mode="controller", kind="pickle-reduce", scratch=tmp_path
    )
    assert not report.failures, report.failures
    assert report.counts["refused"] == sum(report.counts.values())


@pytest.mark.parametrize(
    ("trainer", "kind"),
    [
        ("train-edhucat", "sb3-env-module"),
        ("train-coevolution", "sb3-env-module"),
        ("evolve-coevolution", "npz-huge-array"),
        ("train", "zip-declared-gigabytes"),
    ],
)
def test_every_file_of_a_run_folder_edited_to_attack_its_reader_is_refused(
    trainer: str, kind: str, tmp_path: Path
) -> None:
    """Each file of the folder in turn, edited as ``kind`` says (files of other kinds kept)."""
    report = fuzz_resume.fuzz(trainer, None, kind=kind, scratch=tmp_path)
    assert not report.failures, report.failures
    assert report.counts["refused"] >= 1
