"""Evolution in the coevolution regime: run folder, mazes.csv, resume after a kill, refusals."""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from amaze.curriculum.maze_population import MAZES_CSV_FIELDS
from amaze.curriculum.validation import reserved_seeds
from amaze.maze.arrow_styles import draw_arrow, training_styles
from amaze.maze.signs import clear_custom_signs, custom_sign_path
from amaze.maze.spec import MazeSpec
from amaze.runs.checkpoint import read_checkpoint, write_checkpoint
from evolution import EvolutionConfigError
from evolution.agent_file import load_agent, read_agent
from evolution.checkpoint import evolution_codec
from evolution.cli import main
from evolution.cmaes import CMAESConfig
from evolution.coevolution import EvolutionCoevolutionRun
from evolution.neat import NeatConfig
from evolution.run import EvolutionRun, EvolveConfig
from tests.processes import kill_after_rows
from tests.run_folders import timeless_progress, write_config

ROOT = Path(__file__).resolve().parents[2]
#: A tiny coevolution run: small populations of agents and mazes, a checkpoint every generation.
CONFIG = {
    "regime": "coevolution",
    "max_generations": 40,
    "budget_steps": None,
    "checkpoint_seconds": 0,
    "algorithm": {"population_size": 8},
    "coevolution": {"capacity": 6, "batch": 3, "validation": 4, "validation_every": 2},
}


def _write_config(folder: Path, **changes: object) -> Path:
    return write_config(folder, CONFIG, **changes)


def _mazes_csv(out: Path) -> list[dict[str, str]]:
    with open(out / "mazes.csv", newline="") as handle:
        return list(csv.DictReader(handle))


@pytest.fixture(scope="module")
def finished(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("coevolution")
    out = folder / "run"
    config = _write_config(folder)
    assert main(["--config", str(config), "--out", str(out), "--no-progress"]) == 0
    return out


def test_a_coevolution_run_writes_its_folder(finished: Path) -> None:
    for name in ("config.json", "progress.csv", "mazes.csv", "population.png", "coevolution.png"):
        assert (finished / name).stat().st_size > 0, name
    assert len(list((finished / "trajectories").glob("target-rotation-*.png"))) == 4
    summary = json.loads((finished / "summary.json").read_text())
    assert summary["regime"] == "coevolution" and summary["generations"] == 40
    for key in (
        "success_rate",
        "unseen_success_rate",
        "unseen_normalized_reward",
        "champion_fitness",
        "time",
    ):
        assert key in summary, key
    assert set(summary["time"]) == {
        "evaluation", "validation", "breeding", "mazes", "logging_and_checkpoints",
    }  # fmt: skip
    assert sum(summary["time"].values()) == pytest.approx(summary["seconds"], rel=0.05, abs=0.05)
    assert 0 < summary["validation_steps"] < summary["env_steps"]
    metadata = read_agent(finished / "agent.npz")[1]
    assert metadata["generation"] == summary["champion_generation"]
    assert len(metadata["validation_mazes"]) == 4
    load_agent(finished / "agent.npz")  # an agent file amaze run can play


def test_mazes_csv_holds_every_member_ever(finished: Path) -> None:
    rows = _mazes_csv(finished)
    assert rows and list(rows[0]) == MAZES_CSV_FIELDS
    members = [r for r in rows if r["retired"] == ""]
    summary = json.loads((finished / "summary.json").read_text())
    assert len(members) == summary["members"] <= 6
    assert [int(r["id"]) for r in rows] == list(range(len(rows)))
    validation = set(read_agent(finished / "agent.npz")[1]["validation_mazes"])
    for row in rows:
        assert row["origin"] in ("family", "mutant")
        assert row["maze"] not in validation
        assert MazeSpec.from_string(row["maze"]).seed not in reserved_seeds()
        # scored when admitted (the minimal criterion is tested on MazePopulation), and
        # at every replay since: the last play's success may be anything, even 0
        assert int(row["plays"]) >= 1 and int(row["last_played"]) >= int(row["birth"])
        assert 0 <= float(row["success_rate"]) <= 1
        if row["origin"] == "mutant":
            assert 0 <= int(row["parent"]) < int(row["id"])
        if row["retired"]:
            assert int(row["birth"]) <= int(row["retired"]) <= 40
    progress = timeless_progress(finished)
    assert [int(r["generation"]) for r in progress] == list(range(1, 41))
    assert sum(int(r["admitted"]) for r in progress) == len(rows)


@pytest.mark.slow
def test_resume_after_a_kill_is_bit_identical(finished: Path, tmp_path: Path) -> None:
    out = tmp_path / "killed"
    config = _write_config(tmp_path)
    argv = [sys.executable, "-m", "evolution.cli", "--config", str(config), "--out", str(out),
            "--no-progress"]  # fmt: skip
    kill_after_rows(argv, out / "progress.csv", 15, ROOT)
    assert not (out / "summary.json").exists()
    assert main(["--resume", str(out), "--no-progress"]) == 0
    ours, theirs = read_agent(out / "agent.npz"), read_agent(finished / "agent.npz")
    assert ours[0].keys() == theirs[0].keys()
    assert all(np.array_equal(ours[0][k], theirs[0][k]) for k in ours[0])
    assert _mazes_csv(out) == _mazes_csv(finished)
    assert timeless_progress(out) == timeless_progress(finished)
    a, b = (json.loads((o / "summary.json").read_text()) for o in (out, finished))
    for key in ("env_steps", "success_rate", "unseen_success_rate", "champion_generation"):
        assert a[key] == b[key], key


def test_the_regime_chooses_the_run_class() -> None:
    config = EvolveConfig.from_dict({"regime": "coevolution"})
    assert EvolutionRun.run_class_for(config) is EvolutionCoevolutionRun


@pytest.mark.parametrize(
    ("changes", "bad"),
    [
        ({"coevolution": {"score": "fun"}}, "score 'fun'"),
        ({"coevolution": {"capacity": 2, "batch": 4}}, "capacity 2"),
        ({"coevolution": [1]}, "is not a JSON object"),
        ({"mazes": ["M4_10x10_C1"]}, r"mazes .* \['M4_10x10_C1'\] has no effect"),
        ({"regime": "direct"}, "has no effect in the direct regime"),
        ({"target": "M4_1x10"}, "target"),
    ],
)
def test_coevolution_config_refusals(changes: dict, bad: str) -> None:
    with pytest.raises(EvolutionConfigError, match=bad):
        EvolveConfig.from_dict({**CONFIG, **changes})


def test_bad_options_are_one_error_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    config = _write_config(tmp_path, coevolution={"batchsize": 3})
    assert main(["--config", str(config), "--out", str(tmp_path / "o"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "batchsize" in err[0]
    assert not (tmp_path / "o").exists()


def test_neat_in_the_coevolution_regime(tmp_path: Path) -> None:
    config = _write_config(tmp_path, algo="neat", max_generations=3, algorithm={})
    out = tmp_path / "neat"
    assert main(["--config", str(config), "--out", str(out), "--no-progress"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["algo"] == "neat" and summary["generations"] == 3
    assert read_agent(out / "agent.npz")[1]["architecture"]["type"] != "mlp"


def test_neat_with_one_genome_for_the_four_directions(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    options = {"population_size": 12, "symmetry": "rotations"}
    config = _write_config(tmp_path, algo="neat", max_generations=3, algorithm=options)
    out = tmp_path / "neat"
    assert main(["--config", str(config), "--out", str(out), "--no-progress"]) == 0
    architecture = read_agent(out / "agent.npz")[1]["architecture"]
    assert architecture["symmetry"] == "rotations" and architecture["n_outputs"] == 1
    load_agent(out / "agent.npz")  # amaze run and evaluate can play it
    # a continuous robot: one genome scores the directions, the accelerations turn with them
    continuous = _write_config(tmp_path, algo="neat", robot="CC5", algorithm=options)
    assert main(["--config", str(continuous), "--out", str(tmp_path / "cc"), "--no-progress"]) == 0
    architecture = read_agent(tmp_path / "cc" / "agent.npz")[1]["architecture"]
    assert architecture["symmetry"] == "rotations" and architecture["n_outputs"] == 1
    images = np.zeros((3, 1, 5, 5), np.uint8)
    assert load_agent(tmp_path / "cc" / "agent.npz")(images).shape == (3, 2)


def test_coevolution_fills_the_cmaes_options_it_is_not_given() -> None:
    config = EvolveConfig.from_dict({"regime": "coevolution"})
    assert config.algorithm["network"]["hidden"] == [16] and config.algorithm["restarts"] == 16
    mine = EvolveConfig.from_dict({"regime": "coevolution", "algorithm": {"restarts": 2}})
    assert mine.algorithm["network"]["hidden"] == [16] and mine.algorithm["restarts"] == 2
    neat = EvolveConfig.from_dict({"regime": "coevolution", "algo": "neat"}).algorithm
    # NEAT's own defaults, recorded, with genomes shared by the directions
    assert neat == {**NeatConfig().to_dict(), "symmetry": "rotations"}
    older = {k: v for k, v in NeatConfig().to_dict().items() if k != "symmetry"}
    kept = EvolveConfig.from_dict({"regime": "coevolution", "algo": "neat", "algorithm": older})
    assert kept.algorithm["symmetry"] == "none"  # a config.json from before the option
    direct = EvolveConfig.from_dict({}).algorithm  # the direct regime keeps CMA-ES's defaults
    assert direct == CMAESConfig().to_dict() and direct["network"]["hidden"] == []
    assert direct["network"]["symmetry"] == "none"


@pytest.mark.parametrize(
    ("robot", "symmetry"), [("DD", "rotations"), ("H15", "rotations"), ("CC15", "none")]
)
def test_coevolution_shares_the_network_across_directions_for_discrete_actions(
    robot: str, symmetry: str
) -> None:
    config = EvolveConfig.from_dict({"regime": "coevolution", "robot": robot})
    assert config.algorithm["network"]["symmetry"] == symmetry
    neat = EvolveConfig.from_dict({"regime": "coevolution", "robot": robot, "algo": "neat"})
    assert neat.algorithm["symmetry"] == symmetry
    # a network given whole (as an older config.json gives it) is taken as it is
    given = {"hidden": [16], "activation": "tanh", "pool": None}
    older = EvolveConfig.from_dict(
        {"regime": "coevolution", "robot": robot, "algorithm": {"network": given}}
    )
    assert older.algorithm["network"]["symmetry"] == "none"


def test_a_checkpoint_of_the_older_layout_resumes_bit_identically(tmp_path: Path) -> None:
    """A version 1 state (``generation``, ``champion_generation``) is read and goes on."""
    whole, part = tmp_path / "whole", tmp_path / "part"
    config = _write_config(tmp_path, max_generations=6)
    assert main(["--config", str(config), "--out", str(whole), "--no-progress"]) == 0
    config = _write_config(tmp_path, max_generations=3)
    assert main(["--config", str(config), "--out", str(part), "--no-progress"]) == 0
    path, state_class = part / "checkpoints" / "state.npz", EvolutionCoevolutionRun.state_class
    codec = evolution_codec(state_class)
    state = read_checkpoint(path, codec, EvolutionConfigError, state_class)
    attributes = state.__dict__  # as version 1 named them
    attributes["generation"] = attributes.pop("round")
    attributes["champion_generation"] = attributes.pop("champion_round")
    attributes["version"] = 1
    del attributes["champion_steps"]
    write_checkpoint(path, state, codec)
    (part / "summary.json").unlink()
    stored = json.loads((part / "config.json").read_text())
    (part / "config.json").write_text(json.dumps({**stored, "max_generations": 6}))
    assert main(["--resume", str(part), "--no-progress"]) == 0
    ours, theirs = read_agent(part / "agent.npz"), read_agent(whole / "agent.npz")
    assert all(np.array_equal(ours[0][k], theirs[0][k]) for k in theirs[0])
    assert timeless_progress(part) == timeless_progress(whole)
    assert _mazes_csv(part) == _mazes_csv(whole)
    a, b = (json.loads((o / "summary.json").read_text()) for o in (part, whole))
    for key in ("generations", "champion_generation", "agent_generation", "agent_steps"):
        assert a[key] == b[key], key


def test_validation_mazes_take_the_shapes_in_turn(tmp_path: Path) -> None:
    shapes = ["arrow", "point", "star"]
    config = EvolveConfig.from_dict(
        {**CONFIG, "robot": "H15", "coevolution": {**CONFIG["coevolution"], "shapes": shapes}}
    )
    run = EvolutionCoevolutionRun(tmp_path / "run", config)
    plain = EvolutionCoevolutionRun(tmp_path / "plain", EvolveConfig.from_dict(CONFIG))
    assert len(run.validation_mazes) == 4
    for i, (maze, original) in enumerate(
        zip(run.validation_mazes, plain.validation_mazes, strict=True)
    ):
        spec = MazeSpec.from_string(maze)
        assert {s.shape for s in (*spec.clue, *spec.lure, *spec.trap)} == {shapes[i % 3]}
        assert spec.in_shape("arrow").to_string() == original  # the same mazes, redrawn
    with pytest.raises(EvolutionConfigError, match=r"shapes .* no effect for robot DD"):
        EvolveConfig.from_dict({**CONFIG, "coevolution": {"shapes": shapes}})


def test_the_champion_is_the_latest_best_on_validation(tmp_path: Path) -> None:
    # an easy target: validation saturates at R̄ 1.0 within a few generations
    config = _write_config(tmp_path, target="M3_5x5_U", max_generations=12)
    out = tmp_path / "easy"
    assert main(["--config", str(config), "--out", str(out), "--no-progress"]) == 0
    rows = [r for r in timeless_progress(out) if r["validation"] != "nan"]
    best = max(float(r["validation"]) for r in rows)
    tied = [int(r["generation"]) for r in rows if float(r["validation"]) == best]
    assert best == 1.0 and len(tied) >= 2
    summary = json.loads((out / "summary.json").read_text())
    assert summary["champion_generation"] == tied[-1]
    assert read_agent(out / "agent.npz")[1]["generation"] == tied[-1]


def test_sign_styles_are_drawn_into_the_run_and_read_like_the_shapes(tmp_path: Path) -> None:
    # the run draws and registers its arrow styles itself: its config says what it trained on
    options = {
        **CONFIG["coevolution"],
        "shapes": ["point"],
        "sign_styles": 2,
        "sign_styles_seed": 5,
        "sign_styles_heads": ["hollow"],
        "sign_styles_shaft_width": [0.2, 0.3],
    }
    config = {**CONFIG, "robot": "H15", "max_generations": 4, "coevolution": options}
    path = write_config(tmp_path, config)
    out = tmp_path / "styled"
    clear_custom_signs()
    try:
        assert main(["--config", str(path), "--out", str(out), "--no-progress"]) == 0
        drawn = sorted(p.name for p in (out / "signs" / "training").iterdir())
        assert drawn == ["arrowv0.png", "arrowv1.png"]
        style = training_styles(2, 5, ("hollow",), (0.2, 0.3))[1]
        assert style.head == "hollow" and style.shaft_width >= 0.2
        with Image.open(out / "signs" / "training" / "arrowv1.png") as image:
            assert np.array_equal(np.asarray(image), np.asarray(draw_arrow(style)))
        assert custom_sign_path("arrowv1") == (out / "signs" / "training" / "arrowv1.png").resolve()
        run = EvolutionCoevolutionRun(out, EvolveConfig.from_dict(config))
        shapes = [
            {s.shape for s in (*spec.clue, *spec.lure, *spec.trap)}
            for spec in map(MazeSpec.from_string, run.validation_mazes)
        ]
        assert shapes == [{"point"}, {"arrowv0"}, {"arrowv1"}, {"point"}]
        summary = json.loads((out / "summary.json").read_text())
        assert summary["coevolution"]["sign_styles"] == 2
        assert summary["coevolution"]["sign_styles_heads"] == ["hollow"]
        assert summary["coevolution"]["sign_styles_shaft_width"] == [0.2, 0.3]
    finally:
        clear_custom_signs()
    with pytest.raises(EvolutionConfigError, match=r"sign_styles 2 have no effect for robot DD"):
        EvolveConfig.from_dict({**CONFIG, "coevolution": {"sign_styles": 2}})
