"""Checkpoints: rebuilt without running code from the file, damaged files refused by name."""

from __future__ import annotations

import enum
import os
import pickle
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from amaze.errors import AmazeError
from amaze.runs.checkpoint import Allowlist, read_checkpoint, write_checkpoint

ALLOWED = Allowlist.of(names=(), class_prefixes=("tests.",))


class Colour(enum.Enum):
    RED = "red"
    BLUE = "blue"


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


def _state() -> State:
    rng = np.random.default_rng(3)
    rng.random(5)  # a generator part-way through its stream
    state = State(
        weights=np.arange(12, dtype=np.float32).reshape(3, 4),
        rng=rng,
        legacy=np.random.RandomState(1).get_state(),
    )
    state.counts["x"] += 2
    state.nested = {"self": [state.weights], (1, 2): {3}, "f": 1.5}
    return state


def test_a_state_comes_back_whole(tmp_path: Path) -> None:
    original = _state()
    path = write_checkpoint(tmp_path / "checkpoints" / "state.pkl", original)
    restored = read_checkpoint(path, ALLOWED, AmazeError, expected=State)
    assert np.array_equal(restored.weights, original.weights)
    assert restored.weights.dtype == np.float32
    assert restored.rng.random() == original.rng.random()  # the stream goes on identically
    assert restored.counts == {"x": 2} and restored.counts["new"] == 0  # still a defaultdict
    assert restored.colour is Colour.BLUE and restored.scalar == 0.5
    assert restored.nested["self"][0] is restored.weights  # shared references stay shared
    assert restored.nested[(1, 2)] == {3}


class _Payload:
    """An object whose unpickling would call ``function(*arguments)``."""

    def __init__(self, function, *arguments) -> None:
        self.function, self.arguments = function, arguments

    def __reduce__(self):
        return self.function, self.arguments


def _malicious(tmp_path: Path, payload: object) -> Path:
    path = tmp_path / "state.pkl"
    path.write_bytes(
        pickle.dumps(State(np.zeros(1), np.random.default_rng(0), (), nested={"x": payload}))
    )
    return path


@pytest.mark.parametrize(
    ("make_payload", "words"),
    [
        (lambda marker: _Payload(os.system, f"touch {marker}"), "os.system|posix.system"),
        (lambda marker: _Payload(exec, f"open({str(marker)!r}, 'w')"), "builtins.exec"),
        (lambda marker: _Payload(Path.touch, marker), "pathlib.Path.touch"),
        # an allowed class, called with arguments from the file: refused too
        (lambda marker: _Payload(_Payload, f"touch {marker}"), "may not call"),
    ],
)
def test_a_reduce_payload_runs_no_code(tmp_path: Path, make_payload, words: str) -> None:
    marker = tmp_path / "marker"
    path = _malicious(tmp_path, make_payload(marker))
    with pytest.raises(AmazeError, match="refused") as caught:
        read_checkpoint(path, ALLOWED, AmazeError, expected=State)
    assert str(path) in str(caught.value)
    assert any(word in str(caught.value) for word in words.split("|"))
    assert not marker.exists()


def test_opcodes_that_call_a_class_are_refused(tmp_path: Path) -> None:
    # INST (protocol 0): build an instance of an allowed class by calling it
    path = tmp_path / "state.pkl"
    path.write_bytes(b"(S'x'\nitests.amaze.runs.test_checkpoint\n_Payload\n.")
    with pytest.raises(AmazeError, match="calls a class"):
        read_checkpoint(path, ALLOWED, AmazeError, expected=State)


def test_a_module_that_is_not_loaded_is_never_imported(tmp_path: Path) -> None:
    path = tmp_path / "state.pkl"
    path.write_bytes(b"cantigravity\nfly\n.")  # GLOBAL antigravity.fly
    with pytest.raises(AmazeError, match="not loaded"):
        read_checkpoint(path, ALLOWED, AmazeError, expected=State)
    import sys

    assert "antigravity" not in sys.modules


@pytest.mark.parametrize(
    ("content", "words"),
    [
        (None, "cannot be read"),
        (b"", "is empty"),
        ("truncated", "is damaged"),
        (bytes(range(256)) * 4, "is damaged"),
        ("directory", "is a directory"),
        (pickle.dumps([1, 2, 3]), "does not hold a State"),
    ],
)
def test_damaged_checkpoints_are_refused_naming_the_file(
    tmp_path: Path, content: object, words: str
) -> None:
    path = tmp_path / "state.pkl"
    if content == "truncated":
        full = pickle.dumps(_state(), protocol=pickle.HIGHEST_PROTOCOL)
        path.write_bytes(full[: len(full) // 2])
    elif content == "directory":
        path.mkdir()
    elif content is not None:
        path.write_bytes(content)
    with pytest.raises(AmazeError, match=words) as caught:
        read_checkpoint(path, ALLOWED, AmazeError, expected=State)
    assert str(path) in str(caught.value)


def test_a_cma_option_string_is_refused_on_restore(tmp_path: Path) -> None:
    from evolution import EvolutionConfigError
    from evolution.cmaes import CMAESAlgorithm
    from evolution.run import CHECKPOINT_ALLOWLIST

    algorithm = CMAESAlgorithm({"population_size": 4}, "DD", 0)
    marker = tmp_path / "marker"
    algorithm.es.opts["tolfun"] = f"open({str(marker)!r}, 'w') and 1e-11"
    path = write_checkpoint(tmp_path / "state.pkl", algorithm)
    with pytest.raises(EvolutionConfigError, match="'tolfun' holds the string"):
        read_checkpoint(path, CHECKPOINT_ALLOWLIST, EvolutionConfigError, CMAESAlgorithm)
    assert not marker.exists()


def test_a_flipped_byte_in_the_numbers_is_refused_before_unpickling(tmp_path: Path) -> None:
    path = write_checkpoint(tmp_path / "state.pkl", np.arange(64, dtype=np.float64))
    data = bytearray(path.read_bytes())
    data[-20] ^= 0x40  # inside the array: the pickle alone would still load
    path.write_bytes(bytes(data))
    with pytest.raises(AmazeError, match=r"state\.pkl' is damaged \(its SHA-256 digest"):
        read_checkpoint(path, ALLOWED, AmazeError, np.ndarray)


def test_a_bare_pickle_of_an_older_version_still_reads(tmp_path: Path) -> None:
    path = tmp_path / "old.pkl"
    path.write_bytes(pickle.dumps(np.arange(3)))
    assert read_checkpoint(path, ALLOWED, AmazeError, np.ndarray).tolist() == [0, 1, 2]


def test_a_progress_log_with_a_damaged_number_is_refused(tmp_path: Path) -> None:
    from amaze.runs.folder import ProgressLog

    log = ProgressLog(tmp_path / "progress.csv", ("step", "best", "maze"), text_fields=("maze",))
    log.append({"step": 1, "best": -4.5, "maze": "M1_5x5_U"})
    assert len(log.checked_rows("step", AmazeError)) == 1
    log.path.write_text(log.path.read_text().replace("-4.5", "-4.]5"))
    with pytest.raises(AmazeError, match=r"line 2: best '-4\.\]5' is not a number"):
        log.checked_rows("step", AmazeError)
