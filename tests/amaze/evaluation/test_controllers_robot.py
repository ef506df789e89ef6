"""make_controller and robots: the agent file's robot by default, the user's spelling in errors."""

from __future__ import annotations

from pathlib import Path

import pytest

from amaze.errors import AmazeError
from amaze.evaluation.controllers import (
    OracleController,
    RandomController,
    TabularController,
    make_controller,
)


def test_without_a_robot_builtin_controllers_drive_dd():
    assert make_controller("random").robot.to_string() == "DD"
    assert isinstance(make_controller("oracle"), OracleController)
    random = make_controller("random", "H7", seed=2)
    assert isinstance(random, RandomController) and random.robot.to_string() == "CD7"


def test_without_a_robot_a_saved_agent_is_loaded_for_its_own(tmp_path: Path):
    path = TabularController(seed=3).save(tmp_path / "tabular.json")
    loaded = make_controller(str(path))
    assert isinstance(loaded, TabularController) and loaded.seed == 3


def test_a_robot_error_names_the_robot_as_the_user_spelled_it(tmp_path: Path):
    path = TabularController().save(tmp_path / "tabular.json")
    with pytest.raises(AmazeError, match=r"DD robots only, not H15 \(CD15\)$"):
        make_controller(str(path), "H15")
    with pytest.raises(AmazeError, match=r"DD robots only, not CD15$"):
        make_controller(str(path), "CD15")


def test_a_bad_robot_is_refused_before_the_file_is_read(tmp_path: Path):
    with pytest.raises(AmazeError, match="robot string 'DD15'"):
        make_controller(str(tmp_path / "missing.json"), "DD15")
