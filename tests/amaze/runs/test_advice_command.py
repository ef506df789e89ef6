"""``--advisor``, ``--curator-option`` and ``--advisor-option`` given to amaze-evolve."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from evolution.cli import main

SMALL = ["--algo", "cmaes", "--regime", "edhucat", "--stages", "2", "--branches", "2"]


@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (["--regime", "direct", "--advisor", "edens"],
         "advisor (--advisor) 'edens' has no effect in the direct regime: it is for edhucat"),
        (["--regime", "edens", "--advisor", "edens"], "has no effect in the edens regime"),
        (["--regime", "coevolution", "--advisor", "edens"], "in the coevolution regime"),
        ([*SMALL, "--stages", "1", "--curator", "careful", "--advisor", "edens"],
         "advisor 'edens' has no effect with 1 stage"),
        ([*SMALL, "--curator", "follow"], "curator 'follow' follows an advisor's proposals"),
        ([*SMALL, "--curator", "careful", "--advisor", "human"], "advisor 'human' cannot advise"),
        ([*SMALL, "--curator", "careful", "--advisor-option", "validation=2"],
         "without an advisor (--advisor NAME)"),
        ([*SMALL, "--curator", "careful", "--curator-option", "p"],
         "--curator-option 'p' is not KEY=VALUE"),
        ([*SMALL, "--curator", "random", "--curator-option", "x=1"],
         "curator 'random': unknown option(s) x (it takes none)"),
        ([*SMALL, "--curator", "careful", "--advisor", "edens", "--advisor-option", "x=1"],
         "advisor 'edens': unknown option(s) x"),
        ([*SMALL, "--curator", "follow", "--advisor", "edens", "--curator-option", "p=2"],
         "follow p 2 is not a number in [0, 1]"),
        (["--replay", "x", "--advisor", "edens"], "--advisor, --budget-steps would be ignored"),
        (["--replay", "x", "--curator-option", "p=1"], "--curator-option would be ignored"),
    ],
)  # fmt: skip
def test_an_advisor_where_it_has_no_effect_or_a_bad_one_is_one_error_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], words: str
) -> None:
    assert main([*argv, "--budget-steps", "200000", "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and words in err[0], err
    assert not (tmp_path / "run").exists()


def test_resume_refuses_advice_options_it_would_ignore(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    for argv in (["--advisor", "edens"], ["--advisor-option", "validation=2"]):
        assert main(["--resume", str(tmp_path), *argv]) == 2
        flag = argv[0]
        assert f"{flag} would be ignored" in capsys.readouterr().err


def test_follow_with_options_from_the_command_line_records_advice(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    argv = [*SMALL, "--curator", "follow", "--advisor", "edens", "--curator-option", "p=0.5",
            "--curator-option", "base=careful", "--advisor-option", "validation=4",
            "--budget-steps", "60000", "--out", str(out)]  # fmt: skip
    assert main(argv) == 0
    config = json.loads((out / "config.json").read_text())
    assert config["curator_options"] == {"p": 0.5, "base": "careful"}
    assert config["advisor"] == "edens" and config["advisor_options"] == {"validation": 4}
    lines = [json.loads(line) for line in (out / "decisions.jsonl").read_text().splitlines()]
    assert [("proposal" in d, "accepted" in d) for d in lines] == [(False, False)] * 2 + [
        (True, True)
    ] * 2
    assert all(d["proposal"]["advisor"] == "edens" for d in lines[2:])
