"""Saved agents on disk: one ``.npz`` file of arrays plus JSON metadata, never pickled.

The ``amaze-evo-agent`` format, shared by every trainer that saves a network
as plain arrays (:mod:`evolution.agent_file` today, ``rl_baselines``'
fixed-topology networks next). It lives here, below both trainers, because
they may not import each other; what the arrays mean (a network's
parameters, a NEAT-like genome) is each trainer's business.

An agent file ``<name>.npz`` is a plain numpy archive, readable with
``np.load(path, allow_pickle=False)``:

* the agent's arrays, numbers or booleans only (``params`` for a fixed
  network...);
* ``metadata``: a 0-d unicode array holding one JSON object with ``format``
  (:data:`FORMAT`), ``version`` (:data:`FORMAT_VERSION`), ``architecture`` (a
  mapping with a ``type``: ``{"type": "mlp", ...}``, ``{"type": "neat", ...}``),
  ``robot`` (canonical string) and whatever the caller adds: the training
  mazes (``mazes``), ``fitness``, the algorithm and its settings...

:func:`save_agent` writes atomically (a temporary file, then a rename), so
that a killed run never leaves half an agent. :func:`read_agent` reads with
:func:`amaze.archives.open_npz`: the metadata first (at most
:data:`MAX_METADATA_BYTES`), then each array's header is checked (numbers
only, and the caller's ``expect``) before the array is inflated; every array
is at most :data:`MAX_ARRAY_BYTES` and the file :data:`MAX_AGENT_BYTES` once
inflated. Every failure raises :class:`AgentFileError` (or the caller's
subclass of it) naming the file.
"""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from amaze.agents.robot import RobotStringError, as_robot
from amaze.archives import open_npz
from amaze.errors import AmazeError
from amaze.signals import signals_deferred

__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "MAX_AGENT_BYTES",
    "MAX_ARRAY_BYTES",
    "MAX_METADATA_BYTES",
    "METADATA_KEY",
    "SUFFIX",
    "AgentFileError",
    "ArrayCheck",
    "ExpectArrays",
    "read_agent",
    "save_agent",
]

#: Identifies our agent files, and the version of their layout.
FORMAT = "amaze-evo-agent"
FORMAT_VERSION = 1
#: Name of the metadata entry in the archive (no array may use it).
METADATA_KEY = "metadata"
SUFFIX = ".npz"
#: The first bytes of a zip archive (an .npz; the second, of an empty one), as numpy
#: tells them, and of a single .npy array.
_ZIP_MAGIC = (b"PK\x03\x04", b"PK\x05\x06")
_NPY_MAGIC = b"\x93NUMPY"
#: Bounds checked before an agent file's arrays are inflated: one array, the
#: metadata string, and the whole file once inflated (agents are kilobytes).
MAX_ARRAY_BYTES = 64 << 20
MAX_METADATA_BYTES = 16 << 20
MAX_AGENT_BYTES = 256 << 20

#: ``check(name, shape, dtype)``: raises if an array's header is not what the agent needs.
ArrayCheck = Callable[[str, tuple[int, ...], np.dtype], None]
#: ``expect(metadata, where)``: the :data:`ArrayCheck` of an agent, from its checked metadata.
ExpectArrays = Callable[[Mapping[str, Any], str], ArrayCheck]


class AgentFileError(AmazeError):
    """An agent file is missing, unreadable, of another format or inconsistent, or cannot be saved.

    An :class:`~amaze.errors.AmazeError`, so that the ``amaze`` command reports
    it as a one-line error. Trainers pass their own subclass as ``error`` to
    :func:`save_agent` and :func:`read_agent` so that their callers see the
    trainer's error class.
    """


def _agent_path(path: str | os.PathLike) -> Path:
    path = Path(path)
    return path if path.suffix == SUFFIX else path.with_name(path.name + SUFFIX)


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic | np.ndarray):
        return value.tolist()
    if isinstance(value, tuple | set | frozenset):
        return list(value)
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    raise TypeError(f"{value!r} of type {type(value).__name__} is not JSON-serialisable")


def save_agent(
    path: str | os.PathLike,
    arrays: Mapping[str, np.ndarray],
    metadata: Mapping[str, Any],
    *,
    error: type[AgentFileError] = AgentFileError,
) -> Path:
    """Write an agent file atomically and return its path (``.npz`` is appended if missing).

    Args:
        path: where to write; an existing file is replaced whole.
        arrays: the agent's arrays by name, numbers or booleans only (the file
            is read without pickle); no name may be ``metadata``, empty or hold ``/``.
        metadata: must hold ``architecture`` (a mapping with a string ``type``)
            and ``robot`` (a robot string, stored canonical); ``format`` and
            ``version`` are set here. Numpy values, tuples, sets and paths are
            stored as JSON; NaN and infinities are refused.
        error: the class raised on bad input (the caller's subclass).

    Raises:
        AgentFileError: (or ``error``) metadata or arrays that cannot be saved;
            nothing is written then.
    """
    path = _agent_path(path)
    meta = dict(metadata)
    architecture = meta.get("architecture")
    if not isinstance(architecture, Mapping) or not isinstance(architecture.get("type"), str):
        raise error("agent metadata needs an 'architecture' with a 'type'")
    try:
        meta["robot"] = as_robot(meta.get("robot", "")).to_string()
    except (RobotStringError, TypeError, AttributeError):
        raise error(f"agent metadata: robot {meta.get('robot')!r} is not a robot string") from None
    meta["format"] = FORMAT
    meta["version"] = FORMAT_VERSION
    try:
        text = json.dumps(meta, default=_json_default, allow_nan=False, sort_keys=True)
    except (TypeError, ValueError) as problem:
        raise error(f"agent metadata is not JSON-serialisable: {problem}") from None
    contents: dict[str, np.ndarray] = {}
    for name, array in arrays.items():
        if not isinstance(name, str) or not name or name == METADATA_KEY or "/" in name:
            raise error(f"array name {name!r} is not allowed in an agent file")
        array = np.asarray(array)
        if array.dtype.kind not in "biuf":
            raise error(
                f"array {name!r} has dtype {array.dtype}: only numbers and booleans are saved"
            )
        contents[name] = array
    contents[METADATA_KEY] = np.array(text)
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=".tmp", dir=path.parent)
    try:
        # a stop waits for the whole file: numpy's zip writer is never left half closed
        with signals_deferred():
            with os.fdopen(handle, "wb") as stream:
                np.savez(stream, **contents)
            os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    return path


def read_agent(
    path: str | os.PathLike,
    expect: ExpectArrays | None = None,
    *,
    error: type[AgentFileError] = AgentFileError,
) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """The arrays and the metadata of an agent file, checked before anything is inflated.

    Args:
        path: the agent file (nothing is appended to it).
        expect: ``expect(metadata, where)`` gives the check of each array's
            header (``check(name, shape, dtype)``, raising ``error`` with
            ``where`` in its message) from the metadata, once that is read and
            checked: what the architecture calls for (a network's parameter
            count...). Whatever it is, every array must hold numbers or booleans.
        error: the class raised (the caller's subclass).

    Returns:
        ``(arrays, metadata)``: the arrays by name (without ``metadata``) and
        the metadata, whose ``format``, ``version`` and ``architecture`` (a
        mapping with a string ``type``) are checked; the robot is not.

    Raises:
        AgentFileError: (or ``error``) the file is missing, not an ``.npz``, of
            another format or version, too large, or an array is not what is
            expected; the message names the file.
    """
    path = Path(path)
    if not path.is_file():
        what = "is not a file" if path.exists() else "does not exist"
        raise error(f"agent file '{path}' {what}")
    where = f"agent file '{path}'"
    try:
        with path.open("rb") as stream:
            head = stream.read(len(_NPY_MAGIC))
    except OSError as problem:
        raise error(f"{where} cannot be read: {problem.strerror or problem}") from None
    if head == _NPY_MAGIC:
        raise error(f"{where} holds a single array, not an .npz archive")
    if not head.startswith(_ZIP_MAGIC):  # numpy would try it as a pickle, and refuse it
        raise error(f"{where} is not a readable .npz archive: not a zip")
    with open_npz(
        path, where, error, max_entry_bytes=MAX_ARRAY_BYTES, max_total_bytes=MAX_AGENT_BYTES
    ) as archive:
        if METADATA_KEY not in archive.names:
            raise error(f"{where} has no '{METADATA_KEY}' entry")
        raw = archive.read(METADATA_KEY, _metadata_header(where, error))
        metadata = _checked_metadata(raw, where, error)
        extra = None if expect is None else expect(metadata, where)

        def check(name: str, shape: tuple[int, ...], dtype: np.dtype) -> None:
            if dtype.kind not in "biuf":
                raise error(f"{where}: array {name!r} has dtype {dtype}, not numbers")
            if extra is not None:
                extra(name, shape, dtype)

        contents = {
            name: archive.read(name, check) for name in archive.names if name != METADATA_KEY
        }
    return contents, metadata


def _metadata_header(where: str, error: type[AgentFileError]) -> ArrayCheck:
    """The metadata entry's header must be one string of at most :data:`MAX_METADATA_BYTES`."""

    def expect(name: str, shape: tuple[int, ...], dtype: np.dtype) -> None:
        if shape != () or dtype.kind != "U":
            raise error(f"{where}: '{METADATA_KEY}' is not a JSON string")
        if dtype.itemsize > MAX_METADATA_BYTES:
            raise error(
                f"{where}: '{METADATA_KEY}' declares {dtype.itemsize:,} bytes, more than"
                f" {MAX_METADATA_BYTES:,}"
            )

    return expect


def _checked_metadata(raw: np.ndarray, where: str, error: type[AgentFileError]) -> dict[str, Any]:
    """The agent's metadata JSON, checked (format, version, architecture)."""
    try:
        metadata = json.loads(str(raw[()]))
    except (ValueError, RecursionError) as problem:  # bad JSON, too deep, too many digits
        raise error(f"{where}: metadata is not valid JSON ({problem})") from None
    if not isinstance(metadata, dict) or metadata.get("format") != FORMAT:
        raise error(f"{where} is not an {FORMAT} file")
    version = metadata.get("version")
    if type(version) is not int or version != FORMAT_VERSION:
        raise error(
            f"{where} has format version {version!r}; this code reads version {FORMAT_VERSION}"
        )
    architecture = metadata.get("architecture")
    if not isinstance(architecture, dict) or not isinstance(architecture.get("type"), str):
        raise error(f"{where}: metadata has no valid 'architecture'")
    return metadata
