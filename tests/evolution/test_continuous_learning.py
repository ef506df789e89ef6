"""A continuous robot learns: a short CMA-ES run drives CC5 to the goal of a tiny maze."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from amaze.evaluation.protocol import evaluate
from evolution.agent_file import load_agent
from evolution.cli import main
from tests.run_folders import write_config

MAZE = "M1_3x3_U"
CONFIG = {
    "robot": "CC5",
    "regime": "direct",
    "algo": "cmaes",
    "mazes": [MAZE],
    "evaluation_points": 0,
    "max_generations": 60,
    # a linear network shared by the four directions: (tanh(s_E - s_W), tanh(s_N - s_S))
    "algorithm": {"network": {"hidden": [], "symmetry": "rotations"}, "restarts": 4},
}


@pytest.mark.slow
def test_a_short_run_drives_a_continuous_robot_to_the_goal(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "cc5"
    config = write_config(tmp_path, CONFIG)
    assert main(["--config", str(config), "--out", str(out), "--no-progress"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["generations"] == 60 and not summary["agent_untrained"]
    agent = load_agent(out / "agent.npz")
    # its training maze in its four rotations: every episode reaches the goal
    report = evaluate(agent, "CC5", [MAZE], rotations=4, inputs=False)
    assert report.success_rate == 1.0
    # and the agent moves with purpose: far above the motionless agent's R̄ (about -4)
    assert report.normalized_reward > 0.0
    capsys.readouterr()
