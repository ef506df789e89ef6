"""Checkpoints that cannot name a callable: a trainer's state as JSON plus arrays.

A trainer's state (a search algorithm with its random generators, ``cma``'s
strategy object, NEAT genomes, a maze population) is a graph of objects from a
few libraries. :func:`write_checkpoint` writes it as one ``.npz`` archive
(numpy's zip of ``.npy`` arrays, written atomically): the entry ``state`` holds
a JSON document describing the graph, and every numpy array of the graph is an
entry of its own. :func:`read_checkpoint` reads it back with
:func:`amaze.archives.open_npz` (every declared size bounded before it is
inflated) and :func:`json.loads`; nothing in the
file is ever unpickled, imported or called.

The document is plain JSON (numbers, strings, lists, objects) with a few
tagged forms, each an object with one ``$`` key:

========================== ====================================================
``{"$object": T, ...}``    an instance of the class registered as ``T``
``{"$enum": T, ...}``      a member of the enumeration registered as ``T``
``{"$constant": T}``       a value registered as ``T`` (a function an object
                           keeps as a value, like ``numpy.linalg.eigh``)
``{"$array": i}``          the archive's array ``a<i>``
``{"$scalar": i}``         a numpy scalar, stored as the 0-d array ``a<i>``
``{"$generator": ...}``    a ``numpy.random.Generator``: its bit generator's
                           name and ``state`` dict
``{"$defaultdict": F, ...}`` a ``collections.defaultdict`` whose factory ``F``
                           is a registered constant
``{"$tuple": [...]}``      and ``$list``, ``$dict`` (key-value pairs), ``$set``,
                           ``$frozenset``, ``$float`` (``nan``, ``inf``,
                           ``-inf``), ``$bytes`` (base64), ``$dtype``
``{"$ref": n}``            the object marked ``"$id": n`` earlier (shared
                           objects and cycles stay shared)
========================== ====================================================

``T`` is a *tag*, ``module:qualname``, looked up in the :class:`StateCodec`
that the caller hands to both functions: the classes and values its code
registered, and nothing else. A tag outside it is refused; the reader never
imports a module or follows a dotted name. A tag of a module renamed since
(:data:`~amaze.runs.state_document.RENAMED_MODULES`) is read as the new
module's. An object is rebuilt as pickle
rebuilds it, without calling its class with anything from the file: an empty
instance (``cls.__new__(cls)``) whose saved attributes are restored (its
``__setstate__``, or its ``__dict__``), and the items of a ``dict`` or
``list`` subclass through the base type's own methods. So the worst a crafted
file can do is hold wrong numbers in the registered data types, which the
trainers check as they check any input.

Damage is found by the archive's CRC-32 checksums; a file that breaks any rule
raises the caller's error naming the file. Checkpoints of older versions (a
pickle) are refused by name, unread.
"""

from __future__ import annotations

import io
import json
import os
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from amaze.archives import open_npz
from amaze.runs.folder import write_bytes
from amaze.runs.state_document import (
    ArrayLookup,
    CheckpointError,
    Refused,
    StateCodec,
    StateReader,
    StateWriter,
    package_classes,
    simplified,
)
from amaze.signals import signals_deferred
from amaze.validation import parse_json

__all__ = [
    "FORMAT",
    "CheckpointError",
    "StateCodec",
    "curriculum_classes",
    "package_classes",
    "read_checkpoint",
    "write_checkpoint",
]

#: The ``format`` field of a checkpoint's document and its version.
FORMAT = "amaze-checkpoint"
VERSION = 2
#: How deep a checkpoint's document may nest (about three JSON levels a level of the state).
MAX_DOCUMENT_DEPTH = 200
#: The first bytes of the checkpoints of version 1 (pickles); refused unread.
_PICKLE_CHECKPOINT = b"amaze-checkpoint 1\n"


def curriculum_classes() -> list[type]:
    """The classes of the curriculum's states (a co-evolved maze population and its mazes).

    Both trainers' co-evolution checkpoints hold them.
    """
    # loaded, so that their classes are found
    import amaze.curriculum.maze_population
    import amaze.curriculum.population_selector  # noqa: F401

    return [
        *package_classes("amaze.agents.robot"),
        *package_classes("amaze.maze"),
        *package_classes("amaze.curriculum"),
    ]


def write_checkpoint(path: str | os.PathLike, state: Any, codec: StateCodec) -> Path:
    """Write ``state`` to ``path`` atomically, as the module docstring says.

    Raises :class:`CheckpointError` naming the value (its path in the state)
    if the state holds anything ``codec`` does not register.
    """
    writer = StateWriter(codec)
    document = {"format": FORMAT, "version": VERSION, "state": writer.write(state, "state")}
    text = json.dumps(simplified(document), separators=(",", ":"), allow_nan=False)
    arrays = {f"a{index}": array for index, array in enumerate(writer.arrays)}
    with signals_deferred():  # a stop inside numpy's zip writer would leave it half closed
        buffer = io.BytesIO()
        state_bytes = np.frombuffer(text.encode("utf-8"), dtype=np.uint8)
        np.savez_compressed(buffer, state=state_bytes, **arrays)
        return write_bytes(path, buffer.getvalue())


def read_checkpoint(
    path: str | os.PathLike, codec: StateCodec, error: type[ValueError], expected: type
) -> Any:
    """The state in the checkpoint ``path``, rebuilt without calling anything the file names.

    Raises ``error`` naming the file if it cannot be read, is damaged, breaks
    a rule of the module docstring, or does not hold an ``expected`` object.
    """
    where = f"checkpoint {str(path)!r}"
    try:
        with open(path, "rb") as stream:
            head = stream.read(len(_PICKLE_CHECKPOINT))
    except IsADirectoryError:
        raise error(f"{where} is a directory") from None
    except OSError as problem:
        raise error(f"{where} cannot be read: {problem.strerror or problem}") from None
    if not head:
        raise error(f"{where} is empty")
    if head == _PICKLE_CHECKPOINT or head[:1] == b"\x80":
        raise error(
            f"{where} is a pickle, written by an older version: pickles are not read,"
            " since a pickle can run code; start the run again"
        )
    if not head.startswith(b"PK\x03\x04"):
        raise error(f"{where} is not an amaze checkpoint (not a zip archive)")
    try:
        with open_npz(path, where, error) as archive:
            document = parse_json(
                archive.read("state").tobytes(), where, error=error, max_depth=MAX_DOCUMENT_DEPTH
            )
            arrays = ArrayLookup(archive, len(archive.names))
            if not (isinstance(document, dict) and document.get("format") == FORMAT):
                raise error(f"{where} is not an amaze checkpoint")
            if document.get("version") != VERSION:
                raise error(f"{where} is of version {document.get('version')!r}, not {VERSION}")
            state = StateReader(codec, arrays).read(document.get("state"))
    except error:
        raise
    except Refused as refused:
        raise error(f"{where} {refused}: refused") from None
    except RecursionError:
        raise error(f"{where} nests its state too deeply: refused") from None
    except (zipfile.BadZipFile, EOFError, KeyError, OSError, ValueError, MemoryError) as problem:
        raise error(f"{where} is damaged ({type(problem).__name__})") from None
    except Exception as problem:  # a registered class's own __setstate__ checks
        raise error(f"{where} holds a state its classes refuse ({problem})") from None
    if not isinstance(state, expected):
        raise error(f"{where} does not hold a {expected.__name__}")
    return state
