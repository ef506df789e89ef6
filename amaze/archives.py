"""Zip and ``.npz`` archives from users, read with bounds checked before anything is inflated.

Agent files (``.npz``, SB3's ``.zip``) and checkpoints are zip archives that
anyone may hand the program. A zip entry declares its uncompressed size, and
an ``.npy`` entry declares its array's shape: a 2 MB file can declare 2 GiB,
and ``numpy.load`` allocates whatever a header says. Here every declared size
is checked first, against the caller's bounds, and nothing is read past it:

* :func:`zip_entries` opens an archive and checks every entry's declared
  size (each and in total) and that no name repeats, without inflating;
* :func:`read_entry` inflates one entry, at most its declared size;
* :func:`read_npz` (all arrays) and :func:`open_npz` (one by one) read an
  ``.npz`` as ``numpy.load(..., allow_pickle=False)`` would, but check each
  array's header first: no object dtype, a shape whose bytes are exactly the
  entry's declared data, and the caller's own expectation (``expect``: the
  shape the robot and network call for).

Every failure raises the caller's error class naming the file (``where``).
"""

from __future__ import annotations

import io
import math
import zipfile
import zlib
from collections.abc import Callable
from pathlib import Path
from typing import IO

import numpy as np

__all__ = [
    "MAX_ARCHIVE_BYTES",
    "MAX_ENTRY_BYTES",
    "NpzArchive",
    "open_npz",
    "read_entry",
    "read_npz",
    "zip_entries",
]

#: Absolute bounds on what one archive may declare: one entry, and all of them.
#: Far above the project's own files (an agent is kilobytes, a checkpoint
#: megabytes); the callers pass tighter bounds where they know more.
MAX_ENTRY_BYTES = 1 << 30
MAX_ARCHIVE_BYTES = 2 << 30
#: Longest ``.npy`` header read (numpy's own default limit).
_MAX_NPY_HEADER = 10_000

#: What a damaged archive raises from zipfile, zlib and numpy's header parser.
_DAMAGE = (
    zipfile.BadZipFile,
    zlib.error,
    EOFError,
    OSError,
    ValueError,
    KeyError,
    NotImplementedError,  # an unsupported compression method
    RuntimeError,  # an encrypted entry
    SyntaxError,  # a header that is not a Python literal
)

#: ``expect(name, shape, dtype)``: raises the caller's error if the array does not fit.
Expectation = Callable[[str, tuple[int, ...], np.dtype], None]


def _size(count: int) -> str:
    return f"{count:,} bytes"


def zip_entries(
    source: str | Path | bytes,
    where: str,
    error: type[ValueError],
    *,
    max_entry_bytes: int = MAX_ENTRY_BYTES,
    max_total_bytes: int = MAX_ARCHIVE_BYTES,
    kind: str = "zip",
) -> zipfile.ZipFile:
    """The open archive ``source`` (a path or the file's bytes), its entries' sizes checked.

    Raises ``error`` naming ``where`` if it is not a zip archive, if an entry
    name repeats, or if an entry declares more than ``max_entry_bytes`` (or
    all of them more than ``max_total_bytes``) once inflated (``kind`` names
    the format in the message). Nothing is inflated here. The caller closes the archive.
    """
    try:
        archive = zipfile.ZipFile(io.BytesIO(source) if isinstance(source, bytes) else source)
    except IsADirectoryError:
        raise error(f"{where} is a directory") from None
    except FileNotFoundError:
        raise error(f"{where} does not exist") from None
    except _DAMAGE as problem:
        raise error(
            f"{where} is damaged: not a readable {kind} archive ({_reason(problem)})"
        ) from None
    try:
        total = 0
        seen: set[str] = set()
        for info in archive.infolist():
            if info.filename in seen:
                raise error(f"{where} holds the entry {info.filename!r} twice")
            seen.add(info.filename)
            if info.file_size > max_entry_bytes:
                raise error(
                    f"{where}: entry {info.filename!r} declares {_size(info.file_size)} once"
                    f" inflated, more than the {_size(max_entry_bytes)} allowed"
                )
            total += info.file_size
        if total > max_total_bytes:
            raise error(
                f"{where} declares {_size(total)} once inflated, more than the"
                f" {_size(max_total_bytes)} allowed"
            )
    except BaseException:
        archive.close()
        raise
    return archive


def _reason(problem: BaseException) -> str:
    text = str(problem).splitlines()[0] if str(problem) else ""
    return f"{type(problem).__name__}: {text}" if text else type(problem).__name__


def read_entry(archive: zipfile.ZipFile, name: str, where: str, error: type[ValueError]) -> bytes:
    """The inflated bytes of entry ``name`` (at most its declared size, checked by its CRC)."""
    try:
        return archive.read(name)
    except _DAMAGE as problem:
        raise error(f"{where}: entry {name!r} is damaged ({_reason(problem)})") from None


def _npy_header(stream: IO[bytes]) -> tuple[tuple[int, ...], bool, np.dtype]:
    """``(shape, fortran_order, dtype)`` of the ``.npy`` stream, read without its data."""
    major, _ = np.lib.format.read_magic(stream)
    if major == 1:
        return np.lib.format.read_array_header_1_0(stream, max_header_size=_MAX_NPY_HEADER)
    if major == 2:
        return np.lib.format.read_array_header_2_0(stream, max_header_size=_MAX_NPY_HEADER)
    raise ValueError(f".npy format version {major} is not read")


def _read_array(
    archive: zipfile.ZipFile,
    info: zipfile.ZipInfo,
    where: str,
    error: type[ValueError],
    expect: Expectation | None,
) -> np.ndarray:
    """One ``.npy`` entry as an array, its header checked before its data is inflated."""
    name = info.filename.removesuffix(".npy")
    try:
        with archive.open(info) as stream:
            shape, fortran, dtype = _npy_header(stream)
            header_bytes = stream.tell()
            if dtype.hasobject:
                raise error(
                    f"{where}: array {name!r} holds Python objects ({dtype}), read only by"
                    " unpickling: refused (a pickle can run code)"
                )
            data_bytes = math.prod(shape) * dtype.itemsize
            if data_bytes != info.file_size - header_bytes:
                raise error(
                    f"{where}: array {name!r} declares shape {shape} of {dtype}"
                    f" ({_size(data_bytes)}), but its entry holds"
                    f" {_size(info.file_size - header_bytes)} of data"
                )
            if expect is not None:
                expect(name, tuple(shape), dtype)
            data = stream.read(data_bytes)
            if len(data) != data_bytes:
                raise EOFError("the entry ends early")
    except error:
        raise
    except _DAMAGE as problem:
        raise error(f"{where}: array {name!r} is damaged ({_reason(problem)})") from None
    array = np.frombuffer(bytearray(data), dtype=dtype)
    return array.reshape(shape, order="F" if fortran else "C")


class NpzArchive:
    """An open ``.npz`` archive whose arrays are read one by one, each header checked first.

    Opened by :func:`open_npz`; every entry is an ``.npy`` array (checked on
    opening). :meth:`read` checks a header against ``expect`` before the data
    is inflated, so a caller can read a small metadata array first and then
    say what shape the others must have.
    """

    def __init__(self, archive: zipfile.ZipFile, where: str, error: type[ValueError]) -> None:
        self.archive = archive
        self.where = where
        self.error = error
        self.infos = {info.filename.removesuffix(".npy"): info for info in archive.infolist()}
        for info in self.infos.values():
            if not info.filename.endswith(".npy"):
                archive.close()
                raise error(f"{where}: entry {info.filename!r} is not a .npy array")

    @property
    def names(self) -> list[str]:
        """The arrays' names (``.npy`` dropped), in the archive's order."""
        return list(self.infos)

    def read(self, name: str, expect: Expectation | None = None) -> np.ndarray:
        """The array ``name``; ``expect(name, shape, dtype)`` vets its header first."""
        if name not in self.infos:
            raise self.error(f"{self.where} has no array {name!r}")
        return _read_array(self.archive, self.infos[name], self.where, self.error, expect)

    def close(self) -> None:
        self.archive.close()

    def __enter__(self) -> NpzArchive:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def open_npz(
    path: str | Path,
    where: str,
    error: type[ValueError],
    *,
    max_entry_bytes: int = MAX_ENTRY_BYTES,
    max_total_bytes: int = MAX_ARCHIVE_BYTES,
) -> NpzArchive:
    """The ``.npz`` archive ``path`` opened, bounds as :func:`zip_entries` (nothing inflated)."""
    archive = zip_entries(
        Path(path),
        where,
        error,
        max_entry_bytes=max_entry_bytes,
        max_total_bytes=max_total_bytes,
        kind=".npz",
    )
    return NpzArchive(archive, where, error)


def read_npz(
    path: str | Path,
    where: str,
    error: type[ValueError],
    *,
    max_entry_bytes: int = MAX_ENTRY_BYTES,
    max_total_bytes: int = MAX_ARCHIVE_BYTES,
    expect: Expectation | None = None,
) -> dict[str, np.ndarray]:
    """Every array of the ``.npz`` archive ``path`` by name, as ``numpy.load`` names them.

    Each entry must be an ``.npy`` array without Python objects whose declared
    shape fills exactly its declared size; ``expect(name, shape, dtype)`` vets
    each header before its data is inflated. Raises ``error`` naming ``where``.
    """
    with open_npz(
        path, where, error, max_entry_bytes=max_entry_bytes, max_total_bytes=max_total_bytes
    ) as npz:
        return {name: npz.read(name, expect) for name in npz.names}
