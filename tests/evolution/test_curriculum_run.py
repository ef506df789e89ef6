"""Evolution in the curriculum regimes: run folder, replay, resume after a kill, refusals."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from evolution import EvolutionConfigError
from evolution.agent_file import load_agent, read_agent
from evolution.cli import main
from evolution.curriculum import EvolutionCurriculumRun
from evolution.run import EvolutionRun, EvolveConfig
from tests.run_folders import refused_resume, snapshot

ROOT = Path(__file__).resolve().parents[2]
#: A tiny edhucat run: 2 stages x 2 branches, a small CMA-ES population.
ARGS = [
    "--regime", "edhucat", "--curator", "random", "--stages", "2", "--branches", "2",
    "--budget-steps", "60000", "--population-size", "8", "--checkpoint-seconds", "0",
]  # fmt: skip


def _decisions(out: Path) -> list[tuple]:
    lines = (out / "decisions.jsonl").read_text().splitlines()
    return [
        (d["stage"], d["kind"], d.get("choice"), tuple(d.get("mazes", ())))
        for d in map(json.loads, lines)
    ]


def _final_champion(out: Path) -> dict[str, np.ndarray]:
    summary = json.loads((out / "summary.json").read_text())
    stage, branch = len(summary["final_lineage"]) - 1, summary["final_lineage"][-1]
    arrays, _ = read_agent(out / f"stages/stage-{stage}/branch-{branch}/agent/champion.npz")
    return arrays


def _same(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> bool:
    return a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)


@pytest.fixture(scope="module")
def finished(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("edhucat") / "run"
    assert main([*ARGS, "--out", str(out), "--no-progress"]) == 0
    return out


def test_an_edhucat_run_writes_its_folder(
    finished: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    for name in ("config.json", "decisions.jsonl", "progress.csv", "curriculum.png"):
        assert (finished / name).stat().st_size > 0, name
    assert [(s, k) for s, k, _, _ in _decisions(finished)] == [
        (0, "generate"), (1, "select"), (1, "generate"), (2, "select"),
    ]  # fmt: skip
    for stage, branches in ((0, 1), (1, 2)):
        for branch in range(branches):
            folder = finished / f"stages/stage-{stage}/branch-{branch}"
            for name in ("result.json", "trajectory.png", "agent/learner.npz"):
                assert (folder / name).exists(), folder / name
            assert not (folder / "checkpoint").exists()
            load_agent(folder / "agent" / "champion.npz")  # an agent file amaze run can play
    summary = json.loads((finished / "summary.json").read_text())
    assert summary["regime"] == "edhucat" and summary["curator"] == "random"
    assert summary["algo"] == "cmaes" and summary["fitness_measure"] == "normalized_reward"
    assert summary["generations"] >= 3 and summary["lineage_generations"] >= 2
    assert summary["policy_steps_per_second"] > 0
    assert summary["env_steps"] >= 60000 * 0.9 and len(summary["curriculum"]) == 2
    for key in ("success_rate", "normalized_reward", "champion_fitness", "final_lineage"):
        assert key in summary
    config = EvolveConfig.from_dict(json.loads((finished / "config.json").read_text()))
    assert (config.regime, config.stages, config.branches) == ("edhucat", 2, 2)


def test_replay_reaches_the_same_champion(finished: Path, tmp_path: Path) -> None:
    out = tmp_path / "replay"
    assert main(["--replay", str(finished), "--out", str(out), "--no-progress"]) == 0
    assert _same(_final_champion(out), _final_champion(finished))
    assert _decisions(out) == _decisions(finished)
    assert json.loads((out / "config.json").read_text())["replay"] == str(finished)
    assert (out / "replay.jsonl").exists()


def test_resume_after_a_kill_mid_stage(finished: Path, tmp_path: Path) -> None:
    out = tmp_path / "killed"
    process = subprocess.Popen(
        [sys.executable, "-m", "evolution.cli", *ARGS, "--out", str(out), "--no-progress"],
        cwd=ROOT,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    deadline = time.monotonic() + 120
    while not any(out.glob("stages/stage-1/branch-*/checkpoint/learner.npz")):
        if process.poll() is not None or time.monotonic() > deadline:
            process.kill()
            pytest.fail("the run ended before it could be killed mid-stage")
        time.sleep(0.002)
    os.kill(process.pid, signal.SIGKILL)
    process.wait()
    assert not (out / "summary.json").exists()
    assert main(["--resume", str(out), "--no-progress"]) == 0
    assert _same(_final_champion(out), _final_champion(finished))
    assert _decisions(out) == _decisions(finished)
    ours, theirs = (json.loads((o / "summary.json").read_text()) for o in (out, finished))
    for key in ("env_steps", "generations", "success_rate", "normalized_reward", "curriculum"):
        assert ours[key] == theirs[key], key


def test_a_corrupt_decisions_file_is_refused_on_resume(
    finished: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    def damage(path: Path) -> None:
        lines = path.read_text().splitlines()
        path.write_text("\n".join([lines[0], "{not json", *lines[2:]]) + "\n")

    line = refused_resume(main, finished, tmp_path / "copy", "decisions.jsonl", damage, capsys)
    assert "decisions.jsonl" in line and "line 2" in line


def test_a_bad_curator_is_one_error_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = [*ARGS, "--curator", "nobody", "--out", str(tmp_path / "r")]
    assert main(argv) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and "nobody" in err[0]
    assert not (tmp_path / "r").exists()


def test_bad_algorithm_options_fail_before_anything_is_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "algo.json").write_text(json.dumps({"sigma0": -1}))
    argv = [*ARGS, "--config", str(tmp_path / "algo.json"), "--out", str(tmp_path / "r")]
    assert main(argv) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "sigma0" in err[0]
    assert not (tmp_path / "r").exists()


@pytest.mark.parametrize(
    ("overrides", "bad"),
    [
        ({"max_generations": 5}, "max_generations .* 5 has no effect in the edhucat regime"),
        ({"budget_steps": None}, "needs budget_steps"),
        ({"mazes": ["M1_5x5_C1"]}, r"mazes .* \['M1_5x5_C1'\] has no effect"),
    ],
)
def test_curriculum_config_refusals(overrides: dict, bad: str) -> None:
    with pytest.raises(EvolutionConfigError, match=bad):
        EvolveConfig.from_dict({"regime": "edhucat", "curator": "random", **overrides})


def test_the_regime_chooses_the_run_class() -> None:
    direct = EvolveConfig.from_dict({})
    curriculum = EvolveConfig.from_dict({"regime": "interpolation"})
    assert EvolutionRun.run_class_for(direct) is EvolutionRun
    assert EvolutionRun.run_class_for(curriculum) is EvolutionCurriculumRun
    assert (curriculum.curator, curriculum.branches) == ("interpolation", 1)
    assert direct.to_dict()["regime"] == "direct" and direct.curator is None


def test_neat_in_the_interpolation_regime(tmp_path: Path) -> None:
    out = tmp_path / "neat"
    argv = [
        "--algo", "neat", "--regime", "interpolation", "--stages", "2",
        "--budget-steps", "20000", "--population-size", "10", "--out", str(out), "--no-progress",
    ]  # fmt: skip
    assert main(argv) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["algo"] == "neat" and summary["final_lineage"] == [0, 0]
    _, metadata = read_agent(out / "stages/stage-1/branch-0/agent/champion.npz")
    assert metadata["architecture"]["type"] == "neat"
    before = snapshot(out)
    assert main(["--replay", str(out), "--out", str(tmp_path / "again"), "--no-progress"]) == 0
    assert snapshot(out) == before
    assert _same(_final_champion(tmp_path / "again"), _final_champion(out))


@pytest.mark.slow
def test_a_person_at_the_terminal_curates_typing_mistakes_and_all(tmp_path: Path) -> None:
    """The human curator through amaze-evolve: bad typing is asked again, EOF stops cleanly."""
    out = tmp_path / "run"
    cli = [sys.executable, "-m", "evolution.cli"]

    def play(args: list[str], typed: str) -> subprocess.CompletedProcess:
        return subprocess.run([*cli, *args], input=typed, capture_output=True, text=True, cwd=ROOT)

    human = [*ARGS[:3], "human", *ARGS[4:]]
    # Stage 1's two mazes: a bad string, then one typed, then the suggestion; then the
    # input ends before the final choice.
    first = play([*human, "--out", str(out), "--no-progress"], "M1_5x5_Q\nM3_6x6_C1\n\n")
    assert first.returncode == 2
    assert "bad maze 'M1_5x5_Q'" in first.stdout
    assert first.stderr.strip().splitlines() == [
        "error: the human curator's input ended (end of file) before the decision was made;"
        " the decisions made so far are recorded: resume the run to go on"
    ]
    made = _decisions(out)
    assert made[-1][:2] == (1, "generate") and made[-1][3][0] == "M3_6x6_C1"
    # Resumed, it asks only the final choice: a wrong branch number first.
    second = play(["--resume", str(out), "--no-progress"], "7\nzero\n1\n")
    assert second.returncode == 0, second.stderr
    assert _decisions(out)[: len(made)] == made
    assert _decisions(out)[-1][:3] == (2, "select", 1)
    assert json.loads((out / "summary.json").read_text())["final_lineage"] == [0, 1]


def test_a_curriculum_on_a_seconds_budget(tmp_path: Path) -> None:
    out = tmp_path / "run"
    args = [a for a in ARGS]
    at = args.index("--budget-steps")
    args[at : at + 2] = ["--budget-seconds", "2"]
    assert main([*args, "--out", str(out), "--no-progress"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["budget_seconds"] == 2.0 and summary["budget_steps"] is None
    assert json.loads((out / "config.json").read_text())["budget_steps"] is None
    for result in out.glob("stages/stage-*/branch-*/result.json"):
        assert json.loads(result.read_text())["env_steps"] > 0  # at least one generation


@pytest.mark.slow
def test_the_edens_regime_plays_open_ended_stages_until_its_budget_is_spent(
    tmp_path: Path,
) -> None:
    out = tmp_path / "edens"
    args = ["--regime", "edens", "--budget-steps", "120000", "--population-size", "8"]
    assert main([*args, "--out", str(out), "--no-progress"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["stages"] == 0 and summary["rehearsal"] == 7
    assert summary["stages_played"] >= 10  # an epoch is 120000 / (3 * 20) steps a branch
    assert summary["env_steps"] >= 120000 * 0.99
    decisions = _decisions(out)
    assert decisions[-1][:2] == (summary["stages_played"], "select")
    last = summary["stages_played"] - 1
    result = json.loads((out / f"stages/stage-{last}/branch-0/result.json").read_text())
    assert len(result["training_mazes"]) > 1  # its own maze and the lineage's
    replay = tmp_path / "replay"
    assert main(["--replay", str(out), "--out", str(replay), "--no-progress"]) == 0
    assert _decisions(replay) == decisions
    assert _same(_final_champion(replay), _final_champion(out))


def test_a_damaged_finished_learner_is_refused_before_training_goes_on(
    finished: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    def damage(path: Path) -> None:
        # as if killed in the last branch, whose training the resume would do first
        (path.parents[3] / "stage-1/branch-1/result.json").unlink()
        path.write_bytes(path.read_bytes()[:100])

    line = refused_resume(
        main,
        finished,
        tmp_path / "run",
        "stages/stage-0/branch-0/agent/learner.npz",
        damage,
        capsys,
    )
    assert "stage-0/branch-0/agent/learner.npz" in line and "damaged" in line


def test_the_run_agent_is_at_the_top_and_amaze_evaluate_scores_it(
    finished: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from amaze.cli.main import main as amaze_main
    from amaze.evaluation.protocol import evaluate

    summary = json.loads((finished / "summary.json").read_text())
    assert summary["agent"] == "agent.npz" and summary["agent_rule"].startswith("the curator's")
    mazes = ["M1_6x6_C1", "M2_6x6_C1", "M3_6x6_U"]
    assert amaze_main(["evaluate", str(finished / "agent.npz"), *mazes, "--json"]) == 0
    scored = json.loads(capsys.readouterr().out)
    python = evaluate(load_agent(finished / "agent.npz"), "DD", mazes, rotations=4)
    assert scored["episodes"] == 12 == len(python.episodes)
    assert scored["success_rate"] == python.summary()["success_rate"]
    assert scored["normalized_reward"] == python.summary()["normalized_reward"]
    # another file of the run folder, given as an agent, names the run's agent
    learner = finished / "stages/stage-0/branch-0/agent/learner.npz"
    for path in (learner, finished / "progress.csv", finished / "config.json"):
        assert amaze_main(["run", "M1_6x6_C1", "--controller", str(path)]) == 2
        err = capsys.readouterr().err
        assert f"the agent of the run '{finished}' is '{finished / 'agent.npz'}'" in err, err
