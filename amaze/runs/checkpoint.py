"""Checkpoints that cannot run code when they are read.

A trainer's state (a search algorithm with its random generators, ``cma``'s
strategy object, NEAT genomes) is a graph of objects from a few libraries.
It is written with :mod:`pickle` (:func:`write_checkpoint`, atomically) and read
back by a restricted unpickler (:func:`read_checkpoint`), the approach of
``torch.load(weights_only=True)``: a plain ``pickle.loads`` would call any
function a file names (a ``__reduce__`` payload runs a shell command before a
type check could refuse the result). Here:

* a file may name only the globals of an :class:`Allowlist` (exact
  ``module:name`` pairs, or classes of allowed module prefixes);
* it may *call* (pickle's ``REDUCE``) only the few callables of
  :data:`SAFE_CALLS` (numpy's array, scalar, dtype and generator constructors,
  ``defaultdict``) and enumeration classes (a call is a look-up by value);
  classes are otherwise rebuilt with ``__new__`` and their saved attributes,
  never by calling them with arguments from the file;
* the opcodes that call a class directly (``INST``, ``OBJ``), the extension
  registry (``EXT*``) and persistent ids are refused.

The pure-Python unpickler is used because only it lets a subclass replace the
handling of single opcodes (the C unpickler only lets one restrict globals,
and calling an allowed class can be as dangerous as calling ``os.system``:
``cma`` evaluates option strings given to its constructors). Any file that
breaks a rule, and any damaged file, raises the caller's error naming the
file; nothing is executed.
"""

from __future__ import annotations

import enum
import hashlib
import io
import os
import pickle
import sys
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

from amaze.runs.folder import write_bytes

__all__ = ["COMMON_GLOBALS", "SAFE_CALLS", "Allowlist", "read_checkpoint", "write_checkpoint"]

#: The callables a checkpoint may call while it is read (besides enumerations):
#: numpy's constructors of arrays, scalars, dtypes and random generators, and
#: a few containers.
SAFE_CALLS = frozenset(
    {
        ("numpy", "dtype"),
        ("numpy._core.multiarray", "_reconstruct"),
        ("numpy._core.multiarray", "scalar"),
        ("numpy._core.numeric", "_frombuffer"),
        ("numpy.random._pickle", "__generator_ctor"),
        ("numpy.random._pickle", "__bit_generator_ctor"),
        ("numpy.random.bit_generator", "__pyx_unpickle_SeedSequence"),
        ("collections", "defaultdict"),
        ("collections", "OrderedDict"),
        ("builtins", "complex"),
    }
)

#: Globals every checkpoint may name: the callables above, the types they
#: build, and built-in types (as values: a defaultdict's factory).
COMMON_GLOBALS = SAFE_CALLS | frozenset(
    {
        ("numpy", "ndarray"),
        ("numpy.random.bit_generator", "SeedSequence"),
        ("numpy.random._pcg64", "PCG64"),
        ("numpy.random._mt19937", "MT19937"),
        *(("builtins", name) for name in "int float str bytes bool list dict set".split()),
        *(("builtins", name) for name in ("frozenset", "tuple", "bytearray")),
    }
)


@dataclass(frozen=True)
class Allowlist:
    """What a checkpoint may name.

    ``names`` are exact ``(module, name)`` pairs (functions and classes);
    ``class_prefixes`` allow every *class* of the modules starting with one
    of them (``"evolution."``), never their functions.
    """

    names: frozenset[tuple[str, str]] = field(default_factory=frozenset)
    class_prefixes: tuple[str, ...] = ()

    def allows(self, module: str, name: str, obj: Any) -> bool:
        if (module, name) in self.names or (module, name) in COMMON_GLOBALS:
            return True
        return isinstance(obj, type) and module.startswith(self.class_prefixes)

    @classmethod
    def of(cls, names: Iterable[str], class_prefixes: Iterable[str] = ()) -> Allowlist:
        """An allow-list from ``"module:name"`` strings and module prefixes."""
        pairs = frozenset(tuple(entry.split(":", 1)) for entry in names)
        return cls(pairs, tuple(class_prefixes))  # type: ignore[arg-type]


class _Refused(pickle.UnpicklingError):
    pass


class _RestrictedUnpickler(pickle._Unpickler):  # type: ignore[name-defined]
    """The pure-Python unpickler with globals, calls and class calls restricted."""

    dispatch: ClassVar[dict] = dict(pickle._Unpickler.dispatch)  # type: ignore[attr-defined]

    def __init__(self, data: bytes, allowed: Allowlist) -> None:
        super().__init__(io.BytesIO(data))
        self.allowed = allowed

    def find_class(self, module: str, name: str) -> Any:
        if module not in sys.modules:
            # Only modules the trainer has already imported: reading a file
            # never imports code that was not running.
            raise _Refused(f"names {module}.{name}, from a module that is not loaded")
        obj: Any = sys.modules[module]
        try:
            for part in name.split("."):
                obj = getattr(obj, part)
        except AttributeError:
            raise _Refused(f"names {module}.{name}, which does not exist") from None
        if not self.allowed.allows(module, name, obj):
            raise _Refused(f"names {module}.{name}, which a checkpoint may not use")
        return obj

    def persistent_load(self, pid: Any) -> Any:
        raise _Refused("uses a persistent id")

    def _load_reduce(self) -> None:
        func = self.stack[-2]
        key = (getattr(func, "__module__", None), getattr(func, "__qualname__", None))
        is_enum = isinstance(func, type) and issubclass(func, enum.Enum)
        if key not in SAFE_CALLS and not is_enum:
            raise _Refused(f"calls {key[0]}.{key[1]}, which a checkpoint may not call")
        pickle._Unpickler.load_reduce(self)  # type: ignore[attr-defined]

    def _refuse(self) -> None:
        raise _Refused("uses an opcode that calls a class or the extension registry")

    dispatch[pickle.REDUCE[0]] = _load_reduce
    for _opcode in (pickle.INST, pickle.OBJ, pickle.EXT1, pickle.EXT2, pickle.EXT4):
        dispatch[_opcode[0]] = _refuse
    del _opcode


#: The first line of a checkpoint; the second is the SHA-256 of the pickle that follows.
MAGIC = b"amaze-checkpoint 1\n"


def write_checkpoint(path: str | os.PathLike, state: Any) -> Path:
    """Write ``state`` to ``path`` atomically: a pickle behind its SHA-256 digest.

    The digest lets :func:`read_checkpoint` refuse a damaged file before it
    is unpickled: a flipped byte in an array would otherwise load as a valid
    state holding wrong numbers (a covariance matrix with a NaN) and fail
    later, far from the file, or not at all.
    """
    data = pickle.dumps(state, protocol=pickle.HIGHEST_PROTOCOL)
    digest = hashlib.sha256(data).hexdigest().encode("ascii")
    return write_bytes(path, MAGIC + digest + b"\n" + data)


def read_checkpoint(
    path: str | os.PathLike, allowed: Allowlist, error: type[ValueError], expected: type
) -> Any:
    """The state in the checkpoint ``path``, rebuilt without running code from the file.

    Raises ``error`` naming the file if it cannot be read, is damaged, breaks
    a rule of the module docstring, or does not hold an ``expected`` object.
    """
    where = repr(str(path))
    try:
        data = Path(path).read_bytes()
    except IsADirectoryError:
        raise error(f"checkpoint {where} is a directory") from None
    except OSError as problem:
        raise error(f"checkpoint {where} cannot be read: {problem.strerror or problem}") from None
    if not data:
        raise error(f"checkpoint {where} is empty")
    if data.startswith(MAGIC):
        digest, _, data = data[len(MAGIC) :].partition(b"\n")
        if hashlib.sha256(data).hexdigest().encode("ascii") != digest:
            raise error(f"checkpoint {where} is damaged (its SHA-256 digest does not match)")
    # else: a checkpoint written before the digest, a bare pickle
    try:
        state = _RestrictedUnpickler(data, allowed).load()
    except _Refused as refused:
        raise error(f"checkpoint {where} {refused}: refused") from None
    except error as refused:  # a class's own check of its restored state
        raise error(f"checkpoint {where}: {refused}") from None
    except Exception as problem:  # a damaged file can raise almost anything here
        raise error(f"checkpoint {where} is damaged ({type(problem).__name__})") from None
    if not isinstance(state, expected):
        raise error(f"checkpoint {where} does not hold a {expected.__name__}")
    return state
