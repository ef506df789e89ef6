"""Bad agent files through the ``amaze`` command: exit status 2 and one line naming the file.

A corruption matrix over the three kinds of saved agents that ``--controller``
and ``--evaluate`` take: SB3 (``.zip`` + ``.json`` metadata, from
``rl_baselines``), evolved (``.npz``, from ``evolution``) and tabular
(``.json``, from ``amaze``).
"""

from __future__ import annotations

import base64
import json
import pickle
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from amaze.cli.main import main
from amaze.evaluation.controllers import TabularController

#: The commands that load an agent, with the agent's path last.
COMMANDS = (
    ["run", "M1_5x5_U", "--controller"],
    ["suite", "--evaluate"],
    ["inputs", "--controller"],
)


class _CreatesFile:
    """Unpickling this creates ``path``."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def __reduce__(self) -> tuple:
        return (open, (str(self.path), "w"))


@pytest.fixture(scope="module")
def good(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """One good agent file of each kind (the NEAT one grown, with hidden nodes)."""
    from evolution.agent_file import save_agent, save_network_agent
    from evolution.neat import genome_to_arrays
    from evolution.networks import NetworkSpec
    from rl_baselines.agent import SB3Agent, algorithm_class
    from rl_baselines.vec_env import SB3VecEnv
    from tests.evolution.neat.conftest import grown_genomes

    folder = tmp_path_factory.mktemp("good")
    model = algorithm_class("a2c")("MlpPolicy", SB3VecEnv(["M1_5x5_U"], "DD", 4), device="cpu")
    spec = NetworkSpec("DD", (4,))
    arrays, architecture = genome_to_arrays(grown_genomes("DD", count=1, steps=10, seed=3)[0])
    return {
        "zip": SB3Agent(model, "DD", "a2c").save(folder / "sb3"),
        "mlp": save_network_agent(folder / "mlp", spec, np.zeros(spec.n_params)),
        "neat": save_agent(folder / "neat", arrays, {"architecture": architecture, "robot": "DD"}),
        "json": TabularController().save(folder / "tabular.json"),
    }


def _suffix(kind: str) -> str:
    return ".npz" if kind in ("mlp", "neat") else f".{kind}"


def _copy_sidecar(source: Path, target: Path) -> None:
    if source.suffix == ".zip":
        target.with_suffix(".json").write_text(source.with_suffix(".json").read_text())


def _missing(source: Path, target: Path) -> None:
    _copy_sidecar(source, target)


def _empty(source: Path, target: Path) -> None:
    target.write_bytes(b"")
    _copy_sidecar(source, target)


def _truncated(source: Path, target: Path) -> None:
    content = source.read_bytes()
    target.write_bytes(content[: len(content) // 2])
    _copy_sidecar(source, target)


def _random_bytes(source: Path, target: Path) -> None:
    target.write_bytes(np.random.default_rng(0).bytes(2000))
    _copy_sidecar(source, target)


def _directory(source: Path, target: Path) -> None:
    target.mkdir()
    _copy_sidecar(source, target)


def _sidecar(meta: object) -> Callable[[Path, Path], None]:
    """An SB3 agent whose metadata file holds ``meta`` (a string is written as it is)."""

    def make(source: Path, target: Path) -> None:
        target.write_bytes(source.read_bytes())
        text = meta if isinstance(meta, str) else json.dumps(meta)
        target.with_suffix(".json").write_text(text)

    return make


def _no_sidecar_no_robot(source: Path, target: Path) -> None:
    """A zip without metadata whose stored spaces are no robot's (so nothing says the robot)."""
    with zipfile.ZipFile(source) as archive:
        entries = {name: archive.read(name) for name in archive.namelist()}
    data = json.loads(entries["data"])
    data["observation_space"]["_shape"] = [3]
    entries["data"] = json.dumps(data).encode()
    with zipfile.ZipFile(target, "w") as archive:
        for name, content in entries.items():
            archive.writestr(name, content)


def _zip_data(change: Callable[[Path, dict[str, bytes]], None]) -> Callable[[Path, Path], None]:
    """An SB3 agent whose zip entries ``change`` edited (given the target's folder)."""

    def make(source: Path, target: Path) -> None:
        with zipfile.ZipFile(source) as archive:
            entries = {name: archive.read(name) for name in archive.namelist()}
        change(target.parent, entries)
        with zipfile.ZipFile(target, "w") as archive:
            for name, content in entries.items():
                archive.writestr(name, content)
        _copy_sidecar(source, target)

    return make


def _pickled_data_entry(folder: Path, entries: dict[str, bytes]) -> None:
    data = json.loads(entries["data"])
    payload = base64.b64encode(pickle.dumps(_CreatesFile(folder / "code-ran"))).decode()
    data["surprise"] = {":type:": "<class 'object'>", ":serialized:": payload}
    entries["data"] = json.dumps(data).encode()


def _metadata(change: Callable[[dict], None]) -> Callable[[Path, Path], None]:
    """An evolved agent whose JSON metadata ``change`` edited."""

    def make(source: Path, target: Path) -> None:
        with np.load(source, allow_pickle=False) as archive:
            contents = {name: archive[name] for name in archive.files}
        meta = json.loads(str(contents.pop("metadata")))
        change(meta)
        np.savez(target, **contents, metadata=np.array(json.dumps(meta)))

    return make


def _raw_metadata(text: str) -> Callable[[Path, Path], None]:
    """An evolved agent whose metadata entry is ``text``."""

    def make(source: Path, target: Path) -> None:
        with np.load(source, allow_pickle=False) as archive:
            contents = {name: archive[name] for name in archive.files if name != "metadata"}
        np.savez(target, **contents, metadata=np.array(text))

    return make


def _architecture(**changes: object) -> Callable[[Path, Path], None]:
    return _metadata(lambda meta: meta["architecture"].update(changes))


def _document(change: Callable[[dict], None]) -> Callable[[Path, Path], None]:
    """A tabular controller whose JSON document ``change`` edited."""

    def make(source: Path, target: Path) -> None:
        document = json.loads(source.read_text())
        change(document)
        target.write_text(json.dumps(document))

    return make


COMMON = {
    "missing": _missing,
    "empty": _empty,
    "truncated": _truncated,
    "random-bytes": _random_bytes,
    "directory": _directory,
}
CASES: list[tuple[str, str, Callable[[Path, Path], None]]] = [
    (kind, name, make) for kind in ("zip", "mlp", "neat", "json") for name, make in COMMON.items()
] + [
    ("zip", "no-metadata-file-spaces-of-no-robot", _no_sidecar_no_robot),
    ("zip", "metadata-not-json", _sidecar("{not json")),
    ("zip", "metadata-a-list", _sidecar([1, 2])),
    ("zip", "unknown-algo", _sidecar({"robot": "DD", "algo": "dqn"})),
    ("zip", "algo-an-integer", _sidecar({"robot": "DD", "algo": 3})),
    ("zip", "robot-a-list", _sidecar({"robot": ["DD"], "algo": "a2c"})),
    ("zip", "format-a-number", _sidecar({"robot": "DD", "algo": "a2c", "format": 1})),
    ("zip", "no-data", _zip_data(lambda folder, entries: entries.pop("data"))),
    ("zip", "data-not-json", _zip_data(lambda folder, entries: entries.update(data=b"{"))),
    ("zip", "pickled-data-entry", _zip_data(_pickled_data_entry)),
    ("zip", "tensors-not-tensors", _zip_data(lambda f, e: e.update({"policy.pth": b"x"}))),
    ("mlp", "metadata-not-json", _raw_metadata("{not json")),
    ("mlp", "metadata-a-list", _raw_metadata("[1, 2]")),
    ("mlp", "metadata-empty", _metadata(lambda meta: meta.clear())),
    ("mlp", "version-a-string", _metadata(lambda meta: meta.update(version="1"))),
    ("mlp", "format-unknown", _metadata(lambda meta: meta.update(format="other"))),
    ("mlp", "robot-a-number", _metadata(lambda meta: meta.update(robot=5))),
    ("mlp", "hidden-a-string", _architecture(hidden="4")),
    ("mlp", "pool-a-string", _architecture(pool="5")),
    ("mlp", "architecture-a-list", _metadata(lambda meta: meta.update(architecture=[1]))),
    ("neat", "n-inputs-null", _architecture(n_inputs=None)),
    ("neat", "n-inputs-a-list", _architecture(n_inputs=[8])),
    ("neat", "n-outputs-a-string", _architecture(n_outputs="4")),
    ("neat", "activations-integers", _architecture(activations=[0, 1, 2, 3, 4, 5])),
    ("neat", "activations-a-string", _architecture(activations="tanh")),
    ("neat", "n-nodes-a-float", _architecture(n_nodes=2.5)),
    ("json", "a-list", lambda source, target: target.write_text("[1, 2]")),
    ("json", "q-a-number", _document(lambda doc: doc.update(q=1))),
    ("json", "epsilon-a-string", _document(lambda doc: doc.update(epsilon="0.1"))),
    ("json", "seed-a-float", _document(lambda doc: doc.update(seed=1.5))),
    ("json", "robot-a-list", _document(lambda doc: doc.update(robot=["DD"]))),
    ("json", "q-entry-short", _document(lambda doc: doc.update(q=[[[0] * 8, [0, 0]]]))),
]


@pytest.mark.parametrize(
    ("kind", "make"),
    [(kind, make) for kind, _, make in CASES],
    ids=[f"{k}-{n}" for k, n, _ in CASES],
)
def test_bad_agent_files_are_one_error_line_naming_the_file(
    good: dict[str, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    kind: str,
    make: Callable[[Path, Path], None],
) -> None:
    path = tmp_path / f"bad-{kind}{_suffix(kind)}"
    make(good[kind], path)
    for command in COMMANDS:
        assert main([*command, str(path)]) == 2, command
        captured = capsys.readouterr()
        lines = captured.err.splitlines()
        assert len(lines) == 1 and lines[0].startswith("error: "), (command, captured.err)
        assert path.name in lines[0], (command, lines[0])
        assert captured.out == ""
    assert not (tmp_path / "code-ran").exists()


def test_the_good_files_of_the_matrix_load(
    good: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    """The matrix breaks files that the command otherwise plays."""
    for path in good.values():
        assert main(["run", "M1_5x5_U", "--controller", str(path), "--json"]) == 0
        assert json.loads(capsys.readouterr().out)["steps"] > 0
