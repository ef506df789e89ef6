"""Evolution in the edens-populations regime: epochs, alternatives, the pick, resume, refusals."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from amaze.curriculum.population_selector import CONTROLLER_FIELDS, DEFAULT_CRITERIA
from evolution import EvolutionConfigError
from evolution.agent_file import read_agent
from evolution.cli import main
from evolution.edens_populations import EvolutionEdensPopulationsRun
from evolution.run import EvolutionRun, EvolveConfig
from rl_baselines import RLConfigError
from rl_baselines.config import TrainConfig
from tests.processes import kill_after_rows
from tests.run_folders import timeless_progress, write_config

ROOT = Path(__file__).resolve().parents[2]
#: A tiny run: 3 alternatives of 4 generations per epoch, 30 generations (2 epochs and a half).
CONFIG = {
    "regime": "edens-populations",
    "max_generations": 30,
    "budget_steps": None,
    "checkpoint_seconds": 0,
    "algorithm": {"population_size": 8},
    "coevolution": {"capacity": 6, "batch": 3, "validation": 4, "validation_every": 2},
    "selector": {"alternatives": 3, "epoch": 4},
}


def _write_config(folder: Path, **changes: object) -> Path:
    return write_config(folder, CONFIG, **changes)


def _epochs(out: Path) -> list[dict]:
    return [json.loads(line) for line in (out / "epochs.jsonl").read_text().splitlines()]


@pytest.fixture(scope="module")
def finished(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("edens-populations")
    out = folder / "run"
    assert main(["--config", str(_write_config(folder)), "--out", str(out), "--no-progress"]) == 0
    return out


def test_a_run_plays_epochs_of_alternatives(finished: Path) -> None:
    summary = json.loads((finished / "summary.json").read_text())
    assert summary["regime"] == "edens-populations" and summary["generations"] == 30
    assert summary["epochs"] == 2  # 12 generations an epoch; 6 of the third
    assert summary["epoch_under_way"] == {"alternative": 1, "generations": 2}
    assert summary["selector"]["criteria"] == list(DEFAULT_CRITERIA)
    assert sum(summary["chosen_alternatives"]) == 2
    assert set(summary["controller"]) == set(CONTROLLER_FIELDS)
    progress = timeless_progress(finished)
    assert [int(r["generation"]) for r in progress] == list(range(1, 31))
    # each alternative plays 4 generations in turn, its last one validated
    assert [int(r["alternative"]) for r in progress[:12]] == [0] * 4 + [1] * 4 + [2] * 4
    assert [int(r["epoch"]) for r in progress] == [0] * 12 + [1] * 12 + [2] * 6
    for row in progress[3:24:4]:
        assert row["validation_success_rate"] != "nan"
    metadata = read_agent(finished / "agent.npz")[1]
    assert metadata["generation"] == summary["champion_generation"]
    for name in ("epochs.jsonl", "epochs.png", "mazes.csv", "population.png", "coevolution.png"):
        assert (finished / name).stat().st_size > 0, name


def test_epochs_jsonl_records_every_alternative_and_the_pick(finished: Path) -> None:
    epochs = _epochs(finished)
    assert [e["epoch"] for e in epochs] == [0, 1]
    assert [e["generation"] for e in epochs] == [12, 24]
    progress = timeless_progress(finished)
    for epoch in epochs:
        alternatives = epoch["alternatives"]
        assert [a["index"] for a in alternatives] == [0, 1, 2]
        assert alternatives[0]["mutated"] == []  # the first keeps the parent's controller
        for a in alternatives[1:]:
            assert 1 <= len(a["mutated"]) <= 2 and set(a["mutated"]) <= set(CONTROLLER_FIELDS)
        assert epoch["chosen"] in epoch["front"]
        assert epoch["front"] == [a["index"] for a in alternatives if a["on_front"]]
        # an alternative's criteria are its last generation's validation
        for a in alternatives:
            last = progress[epoch["generation"] - 12 + 4 * a["index"] + 3]
            assert float(last["validation_success_rate"]) == pytest.approx(
                a["validation_success_rate"]
            )
            assert float(last["validation"]) == pytest.approx(a["validation_fitness"], abs=1e-6)
        # the front: no living alternative beats a member on every criterion
        alive = [a for a in alternatives if not a["extinct"]] or alternatives
        for a in alternatives:
            if not a["on_front"]:
                continue
            mine = [a[k] for k in DEFAULT_CRITERIA]
            for other in alive:
                theirs = [other[k] for k in DEFAULT_CRITERIA]
                beaten = all(t >= m for t, m in zip(theirs, mine, strict=True))
                assert not (beaten and theirs != mine)
    # the next epoch starts from the chosen alternative's controller
    chosen = epochs[0]["alternatives"][epochs[0]["chosen"]]["controller"]
    assert epochs[1]["alternatives"][0]["controller"] == chosen


@pytest.mark.slow
def test_the_same_seed_gives_the_same_choices(finished: Path, tmp_path: Path) -> None:
    out = tmp_path / "again"
    assert main(["--config", str(_write_config(tmp_path)), "--out", str(out), "--no-progress"]) == 0
    assert _epochs(out) == _epochs(finished)
    assert timeless_progress(out) == timeless_progress(finished)


@pytest.mark.slow
def test_resume_after_a_kill_in_an_epoch_is_bit_identical(finished: Path, tmp_path: Path) -> None:
    out = tmp_path / "killed"
    argv = [sys.executable, "-m", "evolution.cli", "--config", str(_write_config(tmp_path)),
            "--out", str(out), "--no-progress"]  # fmt: skip
    # killed in the second alternative of the second epoch, or later
    kill_after_rows(argv, out / "progress.csv", 18, ROOT)
    assert not (out / "summary.json").exists()
    assert main(["--resume", str(out), "--no-progress"]) == 0
    ours, theirs = read_agent(out / "agent.npz"), read_agent(finished / "agent.npz")
    assert all(np.array_equal(ours[0][k], theirs[0][k]) for k in ours[0])
    assert _epochs(out) == _epochs(finished)
    assert timeless_progress(out) == timeless_progress(finished)
    assert (out / "mazes.csv").read_text() == (finished / "mazes.csv").read_text()


def test_the_regime_chooses_the_run_class() -> None:
    config = EvolveConfig.from_dict({"regime": "edens-populations"})
    assert EvolutionRun.run_class_for(config) is EvolutionEdensPopulationsRun
    assert config.selector["alternatives"] == 3  # config.json records what ran
    assert config.algorithm["network"]["symmetry"] == "rotations"  # the coevolution defaults


@pytest.mark.parametrize(
    ("changes", "bad"),
    [
        ({"selector": {"alternatives": 0}}, "selector alternatives 0"),
        ({"selector": {"epochs": 3}}, "unknown selector option.*'epochs'"),
        ({"selector": {"criteria": ["speed"]}}, "selector criteria"),
        ({"selector": {"criteria": "diversity"}}, "non-empty list"),
        ({"selector": [1]}, "is not a JSON object"),
        ({"coevolution": {"score": "fun"}}, "score 'fun'"),
        ({"regime": "coevolution"}, "selector .* has no effect in the coevolution regime"),
    ],
)
def test_edens_populations_config_refusals(changes: dict, bad: str) -> None:
    with pytest.raises(EvolutionConfigError, match=bad):
        EvolveConfig.from_dict({**CONFIG, **changes})


def test_rl_refuses_the_regime_with_sb3() -> None:
    with pytest.raises(RLConfigError, match="edens-populations with framework sb3"):
        TrainConfig.from_dict({"regime": "edens-populations"})


def test_bad_selector_options_are_one_error_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = _write_config(tmp_path, selector={"epoch": -1})
    assert main(["--config", str(config), "--out", str(tmp_path / "o"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "selector epoch -1" in err[0]
    assert not (tmp_path / "o").exists()


def _strip_replayed(epochs: list[dict]) -> list[dict]:
    return [{k: v for k, v in e.items() if k != "replayed"} for e in epochs]


@pytest.mark.slow
def test_a_replay_follows_the_recorded_picks(finished: Path, tmp_path: Path) -> None:
    out = tmp_path / "replay"
    assert main(["--replay", str(finished), "--out", str(out), "--no-progress"]) == 0
    epochs = _epochs(out)
    assert all(e["replayed"] for e in epochs)
    assert not any(e["replayed"] for e in _epochs(finished))
    assert _strip_replayed(epochs) == _strip_replayed(_epochs(finished))
    assert (out / "replay.jsonl").read_text() == (finished / "epochs.jsonl").read_text()
    ours, theirs = read_agent(out / "agent.npz"), read_agent(finished / "agent.npz")
    assert all(np.array_equal(ours[0][k], theirs[0][k]) for k in ours[0])


@pytest.mark.slow
def test_a_replay_keeps_the_alternative_a_person_chose(finished: Path, tmp_path: Path) -> None:
    source = tmp_path / "edited"
    subprocess.run(["cp", "-r", str(finished), str(source)], check=True)
    epochs = _epochs(source)
    overruled = next(
        a["index"] for a in epochs[0]["alternatives"] if a["index"] != epochs[0]["chosen"]
    )
    epochs[0]["chosen"] = overruled
    (source / "epochs.jsonl").write_text("".join(json.dumps(e) + "\n" for e in epochs))
    out = tmp_path / "replay"
    assert main(["--replay", str(source), "--out", str(out), "--no-progress"]) == 0
    replayed = _epochs(out)
    assert replayed[0]["chosen"] == overruled
    chosen = replayed[0]["alternatives"][overruled]["controller"]
    assert replayed[1]["alternatives"][0]["controller"] == chosen  # its lineage went on


@pytest.mark.parametrize(
    ("text", "bad"),
    [
        ('{"epoch": 1, "chosen": 0}\n', "line 1: epoch 1 is not 0"),
        ('{"epoch": 0, "chosen": 3}\n', "chosen 3 is not one of the 3 alternatives"),
        ('{"epoch": 0, "chosen": "0"}\n', "chosen '0' is not a number"),
        ('{"epoch": 0, "chosen": 0}\n[1]\n', "line 2: epoch None"),
        ("{oops\n", "line 1"),
    ],
)
def test_a_bad_epochs_file_is_refused_by_name(
    finished: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str, bad: str
) -> None:
    source = tmp_path / "bad"
    subprocess.run(["cp", "-r", str(finished), str(source)], check=True)
    (source / "epochs.jsonl").write_text(text)
    out = tmp_path / "replay"
    assert main(["--replay", str(source), "--out", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "epochs.jsonl" in err[0] and bad in err[0], err
    assert not out.exists()


def test_an_unfinished_run_is_not_replayed(finished: Path, tmp_path: Path) -> None:
    source = tmp_path / "unfinished"
    subprocess.run(["cp", "-r", str(finished), str(source)], check=True)
    (source / "summary.json").unlink()
    with pytest.raises(EvolutionConfigError, match="unfinished run"):
        EvolutionRun.replay(source, tmp_path / "replay")
