"""Ablations from ``runs.csv`` files: medians, differences, intervals, and bad files refused."""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import pytest

from experiments.ablation import (
    AblationError,
    ablation_report,
    between_studies,
    read_runs_csv,
    within_runs,
)
from experiments.cli import main
from experiments.report_runs import RUN_COLUMNS


def _write(
    folder: Path, success: list[float], shift: float = 0.0, treatment: str = "t/ppo/p"
) -> Path:
    """A study folder whose runs.csv holds one treatment, a run per success value."""
    folder.mkdir(parents=True)
    out = io.StringIO()
    writer = csv.DictWriter(out, fieldnames=RUN_COLUMNS, restval="")
    writer.writeheader()
    for seed, value in enumerate(success):
        writer.writerow(
            {
                "treatment": treatment,
                "seed": seed,
                "success_rate": value,
                "normalized_reward": -value,
                "input_recognition": 0.7,
                "paper_input_recognition": 0.6,
                "paper_suite_success_rate": value + shift,
                "paper_suite_normalized_reward": -value,
            }
        )
    (folder / "runs.csv").write_text(out.getvalue())
    return folder


def test_a_variant_moves_the_medians_by_what_it_changed(tmp_path: Path) -> None:
    base = _write(tmp_path / "base", [0.2, 0.25, 0.3, 0.22, 0.28, 0.24, 0.26, 0.21, 0.29, 0.23])
    variant = _write(tmp_path / "lr", [v + 0.3 for v in [0.2, 0.25, 0.3, 0.22, 0.28, 0.24, 0.26,
                                                         0.21, 0.29, 0.23]])  # fmt: skip
    records = between_studies(read_runs_csv(base), read_runs_csv(variant), "lr")
    success = next(r for r in records if r["metric"] == "success (standard suite)")
    assert success["difference"] == pytest.approx(0.3)
    assert success["low"] <= 0.3 <= success["high"] and success["low"] > 0.1
    assert success["p"] < 0.001 and success["n"] == 10
    same = between_studies(read_runs_csv(base), read_runs_csv(base), "none")
    assert all(r["difference"] == 0 for r in same)
    assert all(r["low"] <= 0 <= r["high"] for r in same if not math.isnan(r["low"]))


def test_within_run_factors_are_paired_per_run(tmp_path: Path) -> None:
    base = _write(tmp_path / "base", [0.2, 0.4, 0.6], shift=0.1)
    records = {r["factor"]: r for r in within_runs(read_runs_csv(base))}
    suite = records["suite: standard -> paper's"]
    assert suite["difference"] == pytest.approx(0.1) and suite["base"] == pytest.approx(0.4)
    recognition = records["input recognition: pooled -> paper's"]
    assert recognition["difference"] == pytest.approx(-0.1)


def test_the_command_writes_the_table_and_refuses_bad_files(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    base = _write(tmp_path / "base", [0.2, 0.3, 0.4])
    variant = _write(tmp_path / "variant", [0.5, 0.6, 0.7])
    out = tmp_path / "ablation.md"
    assert main(["ablation", str(base), str(variant), "--out", str(out)]) == 0
    table = out.read_text()
    assert table == capsys.readouterr().out
    assert "| variant | t/ppo/p | success (standard suite) | 3 | 0.3 | 0.6 |" in table
    other = _write(tmp_path / "other", [0.5], treatment="u/a2c/p")
    assert main(["ablation", str(base), str(other)]) == 2
    assert "shares no treatment" in capsys.readouterr().err
    assert main(["ablation", str(base), str(tmp_path / "nowhere")]) == 2
    assert "cannot read" in capsys.readouterr().err
    broken = tmp_path / "broken"
    broken.mkdir()
    (broken / "runs.csv").write_text("treatment,seed\nt,0\n")
    with pytest.raises(AblationError, match="has no column success_rate, normalized_reward, "):
        ablation_report(base, [broken])
    text = (base / "runs.csv").read_text().replace("0.2,", "zero,", 1)
    (broken / "runs.csv").write_text(text)
    with pytest.raises(AblationError, match="is not a number"):
        read_runs_csv(broken)


def test_a_study_reported_before_the_papers_suite_is_compared_on_the_standard_suite(
    tmp_path: Path,
) -> None:
    base = _write(tmp_path / "base", [0.2, 0.25, 0.3])
    old = tmp_path / "old"
    old.mkdir()
    text = (base / "runs.csv").read_text().splitlines()
    keep = [i for i, c in enumerate(text[0].split(",")) if not c.startswith("paper_")]
    (old / "runs.csv").write_text(
        "\n".join(",".join(line.split(",")[i] for i in keep) for line in text) + "\n"
    )
    records = between_studies(read_runs_csv(old), read_runs_csv(base), "new")
    assert [r["metric"] for r in records] == ["success (standard suite)"]
    assert within_runs(read_runs_csv(old)) == []
