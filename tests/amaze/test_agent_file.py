"""The agent-file format of amaze.agents.agent_file, without any trainer: write, read, refuse."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from amaze.agents.agent_file import (
    FORMAT,
    FORMAT_VERSION,
    METADATA_KEY,
    AgentFileError,
    read_agent,
    save_agent,
)
from amaze.agents.robot import as_robot
from amaze.errors import AmazeError

ARCHITECTURE = {"type": "mlp", "hidden": [3]}
GOOD = {"architecture": ARCHITECTURE, "robot": "DD"}


def write_npz(path: Path, metadata: dict, **arrays: np.ndarray) -> Path:
    """An .npz written by numpy itself (object arrays pickled), bypassing :func:`save_agent`."""
    with open(path, "wb") as handle:
        np.savez(handle, metadata=np.array(json.dumps(metadata)), **arrays)
    return path


def metadata(**changes: object) -> dict:
    """Metadata as a good agent file holds it."""
    return {
        "format": FORMAT,
        "version": FORMAT_VERSION,
        "architecture": ARCHITECTURE,
        "robot": "DD",
        **changes,
    }


def test_arrays_and_metadata_come_back_as_saved(tmp_path: Path) -> None:
    arrays = {
        "params": np.linspace(-1, 1, 7) + 1e-12,
        "matrix": np.arange(6, dtype=np.float32).reshape(2, 3),
        "indices": np.array([3, 1, 2], dtype=np.int32),
        "mask": np.array([True, False]),
        "count": np.uint8(5),
    }
    path = save_agent(
        tmp_path / "agent",
        arrays,
        {
            "architecture": ARCHITECTURE,
            "robot": "H15",
            "fitness": np.float32(0.5),
            "generation": np.int64(3),
            "mazes": ("M4_6x6_C1",),
            "folder": tmp_path,
        },
    )
    assert path == tmp_path / "agent.npz"
    assert [p.name for p in tmp_path.iterdir()] == ["agent.npz"]  # no temporary file left
    read, meta = read_agent(path)
    assert sorted(read) == sorted(arrays)
    for name, array in arrays.items():
        assert read[name].dtype == np.asarray(array).dtype, name
        np.testing.assert_array_equal(read[name], array)
    assert meta == {
        "format": FORMAT,
        "version": FORMAT_VERSION,
        "architecture": ARCHITECTURE,
        "robot": as_robot("H15").to_string(),
        "fitness": 0.5,
        "generation": 3,
        "mazes": ["M4_6x6_C1"],
        "folder": str(tmp_path),
    }
    with np.load(path, allow_pickle=False) as archive:  # a plain .npz, no pickle
        assert sorted(archive.files) == sorted([*arrays, METADATA_KEY])


def test_saving_again_replaces_the_file(tmp_path: Path) -> None:
    path = save_agent(tmp_path / "a.npz", {"w": np.zeros(3)}, {**GOOD, "fitness": 1})
    save_agent(path, {"w": np.ones(2)}, {**GOOD, "fitness": 2})
    arrays, read = read_agent(path)
    np.testing.assert_array_equal(arrays["w"], np.ones(2))
    assert read["fitness"] == 2 and [p.name for p in tmp_path.iterdir()] == ["a.npz"]


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"format": "sb3-zip"}, f"is not an {FORMAT} file"),
        ({"format": None}, f"is not an {FORMAT} file"),
        ({"version": FORMAT_VERSION + 1}, f"version {FORMAT_VERSION + 1}"),
        ({"architecture": "mlp"}, "no valid 'architecture'"),
    ],
)
def test_a_file_of_another_format_is_refused_by_name(
    tmp_path: Path, changes: dict, message: str
) -> None:
    path = write_npz(tmp_path / "other.npz", metadata(**changes), params=np.zeros(3))
    with pytest.raises(AgentFileError, match=message) as caught:
        read_agent(path)
    assert "other.npz" in str(caught.value) and isinstance(caught.value, AmazeError)


def test_a_file_that_is_no_npz_is_refused_by_name(tmp_path: Path) -> None:
    single = tmp_path / "single.npz"
    with open(single, "wb") as handle:
        np.save(handle, np.zeros(3))
    (tmp_path / "text.npz").write_text("hello")
    for path, message in [
        (single, "single array"),
        (tmp_path / "text.npz", "not a zip"),
        (tmp_path / "missing.npz", "does not exist"),
    ]:
        with pytest.raises(AgentFileError, match=message) as caught:
            read_agent(path)
        assert path.name in str(caught.value)


def test_object_arrays_are_refused_on_save_and_on_read(tmp_path: Path) -> None:
    with pytest.raises(AgentFileError, match="dtype object"):
        save_agent(tmp_path / "saved", {"w": np.array([{}], dtype=object)}, GOOD)
    assert list(tmp_path.iterdir()) == []
    hostile = write_npz(tmp_path / "hostile.npz", metadata(), w=np.array([{}], dtype=object))
    with pytest.raises(AgentFileError, match="Python objects") as caught:
        read_agent(hostile)
    assert "hostile.npz" in str(caught.value)


def test_arrays_that_are_not_numbers_are_refused_on_read(tmp_path: Path) -> None:
    path = write_npz(tmp_path / "text.npz", metadata(), w=np.array(["a", "b"]))
    with pytest.raises(AgentFileError, match="'w' has dtype <U1, not numbers"):
        read_agent(path)


@pytest.mark.parametrize("robot", ["ZZ", "", 15, None])
def test_a_bad_robot_is_refused_on_save(tmp_path: Path, robot: object) -> None:
    with pytest.raises(AgentFileError, match="robot") as caught:
        save_agent(tmp_path / "agent", {}, {"architecture": ARCHITECTURE, "robot": robot})
    assert repr(robot) in str(caught.value)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("arrays", "meta", "message"),
    [
        ({}, {"robot": "DD"}, "'architecture' with a 'type'"),
        ({}, {"robot": "DD", "architecture": {"hidden": [3]}}, "'architecture' with a 'type'"),
        ({METADATA_KEY: np.zeros(2)}, GOOD, "'metadata' is not allowed"),
        ({"a/b": np.zeros(2)}, GOOD, "'a/b' is not allowed"),
        ({}, {**GOOD, "fitness": float("nan")}, "not JSON-serialisable"),
        ({}, {**GOOD, "what": object()}, "not JSON-serialisable"),
    ],
)
def test_other_bad_input_is_refused_on_save(
    tmp_path: Path, arrays: dict, meta: dict, message: str
) -> None:
    with pytest.raises(AgentFileError, match=message):
        save_agent(tmp_path / "agent", arrays, meta)
    assert list(tmp_path.iterdir()) == []


def test_the_callers_expectation_and_error_class_are_used(tmp_path: Path) -> None:
    class TrainerError(AgentFileError):
        """A trainer's own error class."""

    seen = []

    def expect(meta: dict, where: str):
        seen.append((meta["architecture"], where))

        def check(name: str, shape: tuple[int, ...], dtype: np.dtype) -> None:
            if name == "params" and shape != (4,):
                raise TrainerError(f"{where}: 'params' must be 4 numbers, got shape {shape}")

        return check

    good = save_agent(tmp_path / "good", {"params": np.zeros(4)}, GOOD)
    arrays, _ = read_agent(good, expect, error=TrainerError)
    assert arrays["params"].shape == (4,)
    assert seen == [(ARCHITECTURE, f"agent file '{good}'")]
    bad = write_npz(tmp_path / "bad.npz", metadata(), params=np.zeros(5))
    with pytest.raises(TrainerError, match=r"bad.npz.*must be 4 numbers, got shape \(5,\)"):
        read_agent(bad, expect, error=TrainerError)
    with pytest.raises(TrainerError, match="does not exist"):
        read_agent(tmp_path / "missing.npz", expect, error=TrainerError)
    with pytest.raises(TrainerError, match="robot 'ZZ'"):
        save_agent(tmp_path / "x", {}, {**GOOD, "robot": "ZZ"}, error=TrainerError)
