"""Every command answers ``--version`` with its name and the package's version, and exits 0."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import pytest

import amaze
from amaze.cli.main import main as amaze_main
from evolution.cli import main as evolve_main
from experiments.cli import main as experiment_main
from experiments.curate.cli import main as curate_main
from rl_baselines.cli import main as train_main

COMMANDS: dict[str, Callable[[Sequence[str]], int]] = {
    "amaze": amaze_main,
    "amaze-evolve": evolve_main,
    "amaze-train": train_main,
    "amaze-experiment": experiment_main,
    "amaze-curate": curate_main,
}


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_version(name: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as stop:
        COMMANDS[name](["--version"])
    assert stop.value.code == 0
    line = capsys.readouterr().out.strip()
    assert line.startswith(f"{name} {amaze.__version__} ")
    assert "Python 3." in line and "numpy " in line
