"""Checkpoints: JSON plus arrays, rebuilt without calling anything the file names."""

from __future__ import annotations

import enum
import io
import json
import os
import pickle
import signal
import zipfile
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from amaze.errors import AmazeError
from amaze.runs.checkpoint import CheckpointError, StateCodec, read_checkpoint, write_checkpoint
from tests.run_folders import load_tool
from tests.stops import stop_inside


class Colour(enum.Enum):
    RED = "red"
    BLUE = "blue"


@dataclass(slots=True)
class Gene:
    """A slots class, as NEAT's genes are."""

    key: int
    weight: float


@dataclass(frozen=True)
class Spec:
    """A frozen class, as network specs and robots are."""

    size: int


class Options(dict):
    """A dict subclass with attributes and an overridden ``__setitem__``, as cma's options."""

    def __setitem__(self, key: Any, value: Any) -> None:
        raise AssertionError("a checkpoint fills a dict subclass through dict's own methods")


@dataclass
class State:
    """A stand-in for a trainer's state: the kinds of objects real checkpoints hold."""

    weights: np.ndarray
    rng: np.random.Generator
    legacy: tuple
    counts: defaultdict = field(default_factory=lambda: defaultdict(int))
    colour: Colour = Colour.BLUE
    nested: dict = field(default_factory=dict)
    scalar: float = 0.5
    extra: list = field(default_factory=list)


CODEC = StateCodec([State, Colour, Gene, Spec, Options], constants=[int, np.linalg.eigh])


def _state() -> State:
    rng = np.random.default_rng(3)
    rng.random(5)  # a generator part-way through its stream
    state = State(
        weights=np.arange(12, dtype=np.float32).reshape(3, 4),
        rng=rng,
        legacy=np.random.RandomState(1).get_state(),
    )
    state.counts["x"] += 2
    options = Options()
    dict.update(options, {"eig": np.linalg.eigh, "tol": 1e-11})
    options.note = "attribute"
    state.nested = {"self": [state.weights], (1, 2): {3}, "f": 1.5, "$odd": b"\x00\xff"}
    state.extra = [
        Gene(1, -0.25),
        Spec(7),
        options,
        [float("nan"), float("inf"), -0.0],
        np.float32(2.5),
        np.int64(-3),
        frozenset({"a", "b"}),
        np.dtype("float32"),
        10**30,
        state,  # a cycle back to the state
    ]
    return state


def test_a_state_comes_back_whole(tmp_path: Path) -> None:
    original = _state()
    path = write_checkpoint(tmp_path / "checkpoints" / "state.npz", original, CODEC)
    restored = read_checkpoint(path, CODEC, AmazeError, expected=State)
    assert np.array_equal(restored.weights, original.weights)
    assert restored.weights.dtype == np.float32
    assert restored.rng.random() == original.rng.random()  # the stream goes on identically
    assert restored.legacy[0] == "MT19937" and np.array_equal(
        restored.legacy[1], original.legacy[1]
    )
    assert restored.counts == {"x": 2} and restored.counts["new"] == 0  # still a defaultdict
    assert restored.colour is Colour.BLUE and restored.scalar == 0.5
    assert restored.nested["self"][0] is restored.weights  # shared references stay shared
    assert restored.nested[(1, 2)] == {3} and restored.nested["$odd"] == b"\x00\xff"
    gene, spec, options, floats, f32, i64, names, dtype, big, cycle = restored.extra
    assert gene == Gene(1, -0.25) and spec == Spec(7)
    assert type(options) is Options and options == {"eig": np.linalg.eigh, "tol": 1e-11}
    assert options.note == "attribute"
    assert np.isnan(floats[0]) and floats[1] == np.inf and str(floats[2]) == "-0.0"
    assert type(f32) is np.float32 and f32 == 2.5 and type(i64) is np.int64 and i64 == -3
    assert names == frozenset({"a", "b"}) and dtype == np.float32 and big == 10**30
    assert cycle is restored


def test_the_file_is_json_and_arrays_with_no_pickle(tmp_path: Path) -> None:
    path = write_checkpoint(tmp_path / "state.npz", _state(), CODEC)
    with zipfile.ZipFile(path) as archive:
        assert sorted(archive.namelist())[-1] == "state.npy"
    with np.load(path, allow_pickle=False) as archive:  # numpy refuses any pickled entry
        document = json.loads(archive["state"].tobytes())
        assert all(archive[name].dtype != object for name in archive.files)
    assert document["format"] == "amaze-checkpoint" and document["version"] == 2


def test_writing_an_unregistered_value_names_it() -> None:
    state = _state()
    state.nested["hook"] = print
    with pytest.raises(CheckpointError, match=r"state\.nested\['hook'\].*builtins"):
        write_checkpoint(os.devnull, state, CODEC)


def test_a_class_that_pickles_by_a_call_cannot_be_registered() -> None:
    class Called:
        def __reduce__(self) -> tuple:
            return (print, ("x",))

    with pytest.raises(CheckpointError, match="constructor call"):
        StateCodec([Called])


# -- hostile files -------------------------------------------------------------------


def _crafted(path: Path, document: Any, **arrays: np.ndarray) -> Path:
    """A checkpoint whose document is ``document`` (as a file could be written by anyone)."""
    text = json.dumps({"format": "amaze-checkpoint", "version": 2, "state": document})
    buffer = io.BytesIO()
    np.savez(buffer, state=np.frombuffer(text.encode(), dtype=np.uint8), **arrays)
    path.write_bytes(buffer.getvalue())
    return path


class _Payload:
    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self) -> tuple:
        return os.system, (f"touch {self.marker}",)


@pytest.mark.parametrize(
    "payload",
    [
        load_tool("fuzz_resume").generator_ctor_payload,
        lambda marker: pickle.dumps(_Payload(marker)),
        lambda marker: b"amaze-checkpoint 1\n" + b"0" * 64 + b"\n" + pickle.dumps(_Payload(marker)),
    ],
    ids=["generator-ctor-popen", "reduce-os-system", "version-1-with-digest"],
)
def test_a_pickle_is_refused_unread(tmp_path: Path, payload: Any) -> None:
    marker = tmp_path / "PWNED"
    path = tmp_path / "state.npz"
    path.write_bytes(payload(marker))
    with pytest.raises(AmazeError, match="is a pickle, written by an older version") as caught:
        read_checkpoint(path, CODEC, AmazeError, expected=State)
    assert str(path) in str(caught.value)
    assert not marker.exists()


@pytest.mark.parametrize(
    ("document", "words"),
    [
        ({"$object": "subprocess:Popen", "state": {"args": ["touch", "X"]}}, "may not hold"),
        ({"$object": "amaze.runs.launchers:subprocess.Popen"}, "may not hold"),
        ({"$constant": "os:system"}, "may not hold"),
        ({"$constant": "builtins:eval"}, "may not hold"),
        ({"$enum": "tests.amaze.runs.test_checkpoint:State", "value": 1}, "enumeration"),
        ({"$object": "tests.amaze.runs.test_checkpoint:Colour"}, "class"),
        ({"$defaultdict": {"$constant": "builtins:exec"}, "items": []}, "may not hold"),
        ({"$defaultdict": {"$constant": "numpy.linalg:eigh"}, "items": []}, "factory"),
        ({"$generator": "Evil", "state": {}}, "bit generator"),
        ({"$reduce": ["os:system", "touch X"]}, "unknown form"),
        ({"$ref": 0}, "not defined before"),
        ([{"$list": [], "$id": 0}, {"$list": [], "$id": 0}], "repeated"),
        ({"$dict": [[[1], 2]]}, "unhashable"),
        ({"$array": 5}, "does not hold"),
        ({"$float": "1e999"}, "$float"),
        ({"$dtype": "O"}, "dtype"),
        ({"$object": "tests.amaze.runs.test_checkpoint:Spec", "state": ["x"]}, "attributes"),
    ],
)
def test_a_crafted_document_is_refused_and_calls_nothing(
    tmp_path: Path, document: Any, words: str
) -> None:
    path = _crafted(tmp_path / "state.npz", document, a0=np.zeros(2))
    with pytest.raises(AmazeError, match="refused") as caught:
        read_checkpoint(path, CODEC, AmazeError, expected=object)
    assert words in str(caught.value) and str(path) in str(caught.value)


def test_a_state_naming_only_registered_things_is_still_checked_by_type(tmp_path: Path) -> None:
    path = _crafted(tmp_path / "state.npz", {"$object": "tests.amaze.runs.test_checkpoint:Spec"})
    with pytest.raises(AmazeError, match="does not hold a State"):
        read_checkpoint(path, CODEC, AmazeError, expected=State)


def test_an_array_of_objects_is_refused_unpickled(tmp_path: Path) -> None:
    marker = tmp_path / "PWNED"
    path = _crafted(tmp_path / "state.npz", {"$array": 0}, a0=np.array([_Payload(marker)]))
    with pytest.raises(AmazeError, match="unpickling: refused"):
        read_checkpoint(path, CODEC, AmazeError, expected=object)
    assert not marker.exists()


def test_a_deeply_nested_document_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "state.npz"
    text = '{"format": "amaze-checkpoint", "version": 2, "state": ' + "[" * 100000
    buffer = io.BytesIO()
    np.savez(buffer, state=np.frombuffer(text.encode(), dtype=np.uint8))
    path.write_bytes(buffer.getvalue())
    with pytest.raises(AmazeError, match="deep"):
        read_checkpoint(path, CODEC, AmazeError, expected=object)


@pytest.mark.parametrize(
    ("content", "words"),
    [
        (None, "cannot be read"),
        (b"", "is empty"),
        ("truncated", "is damaged"),
        ("flipped", "is damaged"),
        (bytes(range(256)) * 4, "not an amaze checkpoint"),
        ("directory", "is a directory"),
        ("other version", "version 3"),
    ],
)
def test_damaged_checkpoints_are_refused_naming_the_file(
    tmp_path: Path, content: object, words: str
) -> None:
    path = tmp_path / "state.npz"
    if content in ("truncated", "flipped"):
        full = bytearray(write_checkpoint(path, _state(), CODEC).read_bytes())
        if content == "truncated":
            full = full[: len(full) // 2]
        else:
            full[len(full) // 3] ^= 0x40  # inside a compressed entry: its CRC no longer matches
        path.write_bytes(bytes(full))
    elif content == "directory":
        path.mkdir()
    elif content == "other version":
        text = json.dumps({"format": "amaze-checkpoint", "version": 3, "state": None})
        np.savez(path, state=np.frombuffer(text.encode(), dtype=np.uint8))
    elif content is not None:
        path.write_bytes(content)
    with pytest.raises(AmazeError, match=words) as caught:
        read_checkpoint(path, CODEC, AmazeError, expected=State)
    assert str(path) in str(caught.value)


def test_a_cma_option_string_is_refused_on_restore(tmp_path: Path) -> None:
    from evolution import EvolutionConfigError
    from evolution.checkpoint import evolution_codec
    from evolution.cmaes import CMAESAlgorithm

    algorithm = CMAESAlgorithm({"population_size": 4}, "DD", 0)
    marker = tmp_path / "marker"
    algorithm.es.opts["tolfun"] = f"open({str(marker)!r}, 'w') and 1e-11"
    path = write_checkpoint(tmp_path / "state.npz", algorithm, evolution_codec())
    with pytest.raises(EvolutionConfigError, match="'tolfun' holds the string"):
        read_checkpoint(path, evolution_codec(), EvolutionConfigError, CMAESAlgorithm)
    assert not marker.exists()


def test_a_progress_log_with_a_damaged_number_is_refused(tmp_path: Path) -> None:
    from amaze.runs.folder import ProgressLog

    log = ProgressLog(tmp_path / "progress.csv", ("step", "best", "maze"), text_fields=("maze",))
    log.append({"step": 1, "best": -4.5, "maze": "M1_5x5_U"})
    assert len(log.checked_rows("step", AmazeError)) == 1
    log.path.write_text(log.path.read_text().replace("-4.5", "-4.]5"))
    with pytest.raises(AmazeError, match=r"line 2: best '-4\.\]5' is not a number"):
        log.checked_rows("step", AmazeError)


@pytest.mark.parametrize("sent", [signal.SIGINT, signal.SIGTERM])
def test_a_stop_during_the_write_lands_after_a_whole_checkpoint(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, sent: int
) -> None:
    """Ctrl-C or SIGTERM inside numpy's zip writer waits for the write, then stops the run."""
    path = tmp_path / "state.npz"
    stop_inside(
        monkeypatch, np, "savez_compressed", sent, lambda: write_checkpoint(path, _state(), CODEC)
    )
    restored = read_checkpoint(tmp_path / "state.npz", CODEC, AmazeError, expected=State)
    assert np.array_equal(restored.weights, _state().weights)
