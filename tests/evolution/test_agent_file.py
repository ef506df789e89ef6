"""Agent files: .npz arrays + JSON metadata, no pickle; loading through the amaze command."""

from __future__ import annotations

import json
import sys
import types
import zipfile
from pathlib import Path

import numpy as np
import pytest

from amaze.agents.robot import as_robot
from amaze.cli.main import main
from amaze.evaluation.controllers import make_controller
from amaze.evaluation.protocol import Evaluator
from amaze.maze import rotations
from evolution import EvolutionConfigError
from evolution.agent_file import (
    FORMAT,
    FORMAT_VERSION,
    AgentFileError,
    load_agent,
    read_agent,
    save_agent,
    save_network_agent,
)
from evolution.networks import NetworkSpec


def clue_follower(spec: NetworkSpec) -> np.ndarray:
    """A linear DD network that follows clues (logit = 2 x sign - wall slot)."""
    weights = np.zeros((8, 4))
    weights[:4, :4] = -np.eye(4)
    weights[4:, :4] = 2 * np.eye(4)
    return np.concatenate([weights.ravel(), np.zeros(4)])


def random_observations(robot: str, n: int, rng: np.random.Generator) -> np.ndarray:
    if robot == "DD":
        return rng.choice([0.0, 0.5, 1.0], size=(n, 8)).astype(np.float32)
    v = as_robot(robot).vision
    return rng.integers(0, 256, size=(n, 1, v, v)).astype(np.uint8)


@pytest.mark.parametrize(
    ("robot", "hidden"), [("DD", (16,)), ("DD", ()), ("CD11", (6,)), ("CC15", (4, 3))]
)
def test_save_load_gives_identical_actions(tmp_path, robot, hidden):
    rng = np.random.default_rng(9)
    spec = NetworkSpec(robot, hidden)
    population = spec.population(spec.initial_params(rng, 3) * 2)
    params = np.asarray(population.params[1], dtype=np.float64) + 1e-9  # float64 is kept
    observations = random_observations(spec.robot, 50, rng)
    path = save_network_agent(
        tmp_path / "champion",
        spec,
        params,
        mazes=["M4_6x6_C1"],
        fitness=np.float32(0.25),
        generation=np.int64(12),
        extra={"seed": 3},
    )
    assert path == tmp_path / "champion.npz" and path.is_file()
    agent = load_agent(path)
    assert agent.robot == as_robot(robot) and agent.n_policies == 1
    expected = spec.population(params[None])(observations)
    np.testing.assert_array_equal(agent(observations), expected)
    np.testing.assert_array_equal(agent(observations[:7]), expected[:7])
    arrays, metadata = read_agent(path)
    np.testing.assert_array_equal(arrays["params"], params)
    assert arrays["params"].dtype == np.float64
    assert metadata["format"] == FORMAT and metadata["version"] == FORMAT_VERSION
    assert metadata["architecture"] == {"type": "mlp", **spec.to_dict()}
    assert metadata["robot"] == spec.robot
    assert metadata["mazes"] == ["M4_6x6_C1"] and metadata["fitness"] == 0.25
    assert metadata["generation"] == 12 and metadata["extra"] == {"seed": 3}


def test_files_are_plain_npz_without_pickle(tmp_path):
    spec = NetworkSpec("DD", (4,))
    path = save_network_agent(tmp_path / "a.npz", spec, np.zeros(spec.n_params))
    with np.load(path, allow_pickle=False) as archive:
        assert sorted(archive.files) == ["metadata", "params"]
        assert archive["metadata"].dtype.kind == "U" and archive["metadata"].shape == ()
        assert json.loads(str(archive["metadata"]))["robot"] == "DD"
    with zipfile.ZipFile(path) as archive:
        assert sorted(archive.namelist()) == ["metadata.npy", "params.npy"]
    assert [p.name for p in tmp_path.iterdir()] == ["a.npz"]  # no temporary file left


def test_saving_replaces_atomically_and_checks_inputs(tmp_path):
    spec = NetworkSpec("DD")
    path = save_network_agent(tmp_path / "x.npz", spec, np.zeros(spec.n_params), fitness=1)
    save_network_agent(path, spec, np.ones(spec.n_params), fitness=2)
    arrays, metadata = read_agent(path)
    assert metadata["fitness"] == 2 and arrays["params"].sum() == spec.n_params
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.npz"]
    with pytest.raises(EvolutionConfigError, match="JSON"):
        save_network_agent(tmp_path / "y", spec, np.zeros(spec.n_params), bad=object())
    with pytest.raises(EvolutionConfigError, match="JSON"):
        save_network_agent(tmp_path / "y", spec, np.zeros(spec.n_params), fitness=float("nan"))
    with pytest.raises(EvolutionConfigError, match="36"):
        save_network_agent(tmp_path / "y", spec, np.zeros(35))
    with pytest.raises(EvolutionConfigError, match="'metadata'"):
        save_agent(
            tmp_path / "y",
            {"metadata": np.zeros(2)},
            {"architecture": {"type": "mlp"}, "robot": "DD"},
        )
    with pytest.raises(EvolutionConfigError, match="dtype object"):
        save_agent(
            tmp_path / "y",
            {"w": np.array([{}], dtype=object)},
            {"architecture": {"type": "mlp"}, "robot": "DD"},
        )
    with pytest.raises(EvolutionConfigError, match="architecture"):
        save_agent(tmp_path / "y", {}, {"robot": "DD"})
    with pytest.raises(EvolutionConfigError, match="'ZZ'"):
        save_agent(tmp_path / "y", {}, {"architecture": {"type": "mlp"}, "robot": "ZZ"})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.npz"]


def write_npz(path: Path, metadata: object | None, **arrays: np.ndarray) -> Path:
    contents = dict(arrays)
    if metadata is not None:
        contents["metadata"] = np.array(
            metadata if isinstance(metadata, str) else json.dumps(metadata)
        )
    with open(path, "wb") as handle:
        np.savez(handle, **contents)
    return path


def write_npy(path: Path, array: np.ndarray) -> Path:
    with open(path, "wb") as handle:
        np.save(handle, array)
    return path


def good_metadata(**changes: object) -> dict:
    spec = NetworkSpec("DD")
    meta = {
        "format": FORMAT,
        "version": FORMAT_VERSION,
        "robot": "DD",
        "architecture": {"type": "mlp", **spec.to_dict()},
    }
    meta.update(changes)
    return meta


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda p: p.with_suffix(".npz"), "does not exist"),
        (lambda p: (p.write_bytes(b"not a zip at all"), p)[1], "not a readable .npz"),
        (lambda p: (p.write_bytes(b"PK\x03\x04 truncated"), p)[1], "not a readable .npz"),
        (lambda p: write_npy(p, np.zeros(3)), "single array"),
        (lambda p: write_npz(p, None, params=np.zeros(36)), "no 'metadata'"),
        (lambda p: write_npz(p, "{not json", params=np.zeros(36)), "not valid JSON"),
        (lambda p: write_npz(p, good_metadata(format="other"), params=np.zeros(36)), FORMAT),
        (lambda p: write_npz(p, good_metadata(version=99), params=np.zeros(36)), "version 99"),
        (
            lambda p: write_npz(p, good_metadata(architecture={"type": "transformer"})),
            "'transformer'",
        ),
        (lambda p: write_npz(p, good_metadata(architecture=[1])), "architecture"),
        (lambda p: write_npz(p, good_metadata(), params=np.zeros(35)), "36 floats"),
        (lambda p: write_npz(p, good_metadata()), "36 floats"),
        (lambda p: write_npz(p, good_metadata(robot="H15"), params=np.zeros(36)), "CD15"),
        (lambda p: write_npz(p, good_metadata(robot="QQ"), params=np.zeros(36)), "'QQ'"),
        (
            lambda p: write_npz(
                p, good_metadata(architecture={"type": "mlp", "robot": "DD", "hidden": [0]})
            ),
            "hidden layer 0",
        ),
        (lambda p: write_npz(p, good_metadata(), params=np.array([{}], dtype=object)), "pickle"),
    ],
)
def test_bad_files_are_one_clear_error(tmp_path, make, message):
    path = make(tmp_path / "agent.npz")
    with pytest.raises(AgentFileError, match=message) as caught:
        load_agent(path)
    assert "agent.npz" in str(caught.value)
    assert isinstance(caught.value, EvolutionConfigError)


def test_neat_agents_are_built_by_the_neat_module(tmp_path, monkeypatch):
    calls = []

    def policy_from_arrays(arrays, architecture, robot):
        calls.append((sorted(arrays), architecture, robot))
        return "a neat policy"

    module = types.ModuleType("evolution.neat")
    module.policy_from_arrays = policy_from_arrays
    monkeypatch.setitem(sys.modules, "evolution.neat", module)
    architecture = {"type": "neat", "inputs": 8, "outputs": 4}
    path = save_agent(
        tmp_path / "n",
        {"nodes": np.zeros((3, 2)), "links": np.ones((2, 3))},
        {"architecture": architecture, "robot": "DD", "fitness": 0.5},
    )
    assert load_agent(path) == "a neat policy"
    assert calls == [(["links", "nodes"], architecture, "DD")]


def test_the_amaze_command_runs_saved_agents(tmp_path, capsys):
    spec = NetworkSpec("DD")
    path = save_network_agent(tmp_path / "champion", spec, clue_follower(spec))
    assert main(["run", "M4_10x10_C1", "--controller", str(path), "--json"]) == 0
    outcome = json.loads(capsys.readouterr().out)
    assert outcome["success"] is True and outcome["normalized_reward"] == pytest.approx(1.0)
    assert main(["inputs", "--controller", str(path)]) == 0
    assert capsys.readouterr().out.startswith("140 inputs (DD, ")
    assert main(["suite", "--evaluate", str(path)]) == 0
    assert "72 episodes (DD): success" in capsys.readouterr().out
    assert main(["run", "M4_10x10_C1", "--controller", str(path), "--robot", "H15"]) == 2
    assert "drives DD robots" in capsys.readouterr().err
    broken = tmp_path / "broken.npz"
    broken.write_bytes(b"garbage")
    assert main(["run", "M4_10x10_C1", "--controller", str(broken)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "broken.npz" in err and err.count("\n") == 1


def test_loaded_agents_go_through_the_evaluation_protocol(tmp_path):
    spec = NetworkSpec("H7", (5,))
    params = spec.initial_params(np.random.default_rng(4))
    path = save_network_agent(tmp_path / "h", spec, params)
    agent = make_controller(str(path), "H7")
    assert agent.robot == as_robot("H7")
    mazes = rotations("M4_6x6_C1")
    report = Evaluator("H7", mazes).evaluate(agent)
    direct = Evaluator("H7", mazes).evaluate(spec.population(params[None]))
    assert report.normalized_reward == direct.normalized_reward
    assert report.input_recognition == direct.input_recognition is not None


def neat_arrays() -> tuple[dict[str, np.ndarray], dict]:
    """The arrays and architecture of a grown DD genome (hidden nodes, several connections)."""
    from evolution.neat import genome_to_arrays
    from tests.evolution.neat.conftest import grown_genomes

    return genome_to_arrays(grown_genomes("DD", count=1, steps=10, seed=3)[0])


def neat_agent(path: Path, architecture: dict | None = None, **arrays: np.ndarray) -> Path:
    """A NEAT agent file of :func:`neat_arrays`, its architecture or some arrays replaced."""
    good, good_architecture = neat_arrays()
    meta = {
        "format": FORMAT,
        "version": FORMAT_VERSION,
        "robot": "DD",
        "architecture": good_architecture if architecture is None else architecture,
    }
    return write_npz(path, meta, **{**good, **arrays})


def neat_architecture(**changes: object) -> dict:
    """The architecture of :func:`neat_arrays` with ``changes`` (``...`` removes a key)."""
    architecture = {**neat_arrays()[1], **changes}
    return {key: value for key, value in architecture.items() if value is not ...}


def test_a_neat_agent_file_loads(tmp_path: Path) -> None:
    """The files the checks below break are good ones to start with."""
    agent = load_agent(neat_agent(tmp_path / "agent.npz"))
    assert agent(np.zeros((3, 8), np.float32)).shape == (3,)


@pytest.mark.parametrize(
    ("architecture", "field"),
    [
        (neat_architecture(n_inputs=None), "'n_inputs' None"),
        (neat_architecture(n_inputs=[8]), r"'n_inputs' \[8\]"),
        (neat_architecture(n_inputs="8"), "'n_inputs' '8'"),
        (neat_architecture(n_inputs=8.0), "'n_inputs' 8.0"),
        (neat_architecture(n_inputs=True), "'n_inputs' True"),
        (neat_architecture(n_outputs=None), "'n_outputs' None"),
        (neat_architecture(n_outputs={"n": 4}), "'n_outputs'"),
        (neat_architecture(activations=[0, 1, 2, 3, 4, 5]), "'activations'"),
        (neat_architecture(activations="tanh"), "'activations' 'tanh'"),
        (neat_architecture(activations=None), "'activations' None"),
        (neat_architecture(activations=[]), "'activations'"),
        (neat_architecture(activations=...), "lacks 'activations'"),
        (neat_architecture(n_nodes="3"), "'n_nodes' '3'"),
        (neat_architecture(n_nodes=10_000), "'n_nodes' 10000 does not match"),
        (neat_architecture(n_connections=-1), "'n_connections' -1"),
    ],
)
def test_neat_metadata_of_the_wrong_type_is_one_clear_error(
    tmp_path: Path, architecture: dict, field: str
) -> None:
    path = neat_agent(tmp_path / "agent.npz", architecture)
    with pytest.raises(AgentFileError, match=field) as caught:
        load_agent(path)
    assert "agent.npz" in str(caught.value)


@pytest.mark.parametrize(
    ("change", "field"),
    [
        (lambda a: {"bias": np.where(a["bias"] == a["bias"][0], np.nan, 0.0)}, "'bias' holds non"),
        (lambda a: {"weights": np.full_like(a["weights"], np.inf)}, "'weights' holds non-finite"),
        (lambda a: {"bias": a["bias"][None]}, "'bias' must be a 1-d float array"),
        (lambda a: {"weights": a["weights"].astype(np.int64)}, "'weights' must be a 1-d float"),
        (lambda a: {"outputs": a["outputs"].astype(float)}, "'outputs' must be a 1-d integer"),
        (lambda a: {"activation": a["activation"] > 0}, "'activation' must be a 1-d integer"),
        (
            lambda a: {"sources": np.full(a["sources"].shape, 2**63, np.uint64)},
            "'sources' holds values out of range",
        ),
        (lambda a: {"indptr": a["indptr"][:-1]}, "inconsistent sizes"),
        (lambda a: {"outputs": a["outputs"] + len(a["bias"])}, "'outputs'"),
    ],
)
def test_neat_arrays_of_the_wrong_kind_are_one_clear_error(
    tmp_path: Path, change: object, field: str
) -> None:
    path = neat_agent(tmp_path / "agent.npz", **change(neat_arrays()[0]))
    with pytest.raises(AgentFileError, match=field) as caught:
        load_agent(path)
    assert "agent.npz" in str(caught.value)


def test_archive_entries_and_metadata_that_numpy_or_json_cannot_read_are_refused(
    tmp_path: Path,
) -> None:
    raw = tmp_path / "raw.npz"
    with zipfile.ZipFile(raw, "w") as archive:
        archive.writestr("metadata", json.dumps(good_metadata()))
        archive.writestr("params.npy", b"not an array")
    deep = write_npz(tmp_path / "deep.npz", "[" * 100_000 + "]" * 100_000, params=np.zeros(36))
    digits = write_npz(tmp_path / "digits.npz", '{"version": ' + "9" * 5000 + "}")
    version = write_npz(tmp_path / "version.npz", good_metadata(version=True), params=np.zeros(36))
    for path, message in [
        (raw, "entry 'metadata' is not a .npy array"),
        (deep, "not valid JSON"),
        (digits, "not valid JSON"),
        (version, "version True"),
    ]:
        with pytest.raises(AgentFileError, match=message) as caught:
            load_agent(path)
        assert path.name in str(caught.value)
