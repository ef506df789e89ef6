"""Builders of hostile files: what an attacker hands the commands, for the tests and benchmarks.

``tests/test_adversarial_files.py`` (through ``tests.run_folders.load_tool``)
and ``benchmarks/bench_hostile_inputs.py`` build their cases with these: an
SB3 zip whose ``data`` is edited, an ``.npy`` header declaring any shape, an
``.npz`` whose entry inflates to gigabytes, a YAML file of nested aliases,
and the config of the smallest JAX run whose folder they damage.
"""

from __future__ import annotations

import json
import struct
import zipfile
from pathlib import Path

#: The smallest direct JAX run (2 rollouts of 4 x 8 steps), for damaging its folder.
TINY_JAX_RUN = {
    "framework": "jax",
    "algo": "ppo",
    "mazes": ["M1_5x5_U"],
    "eval_mazes": ["M1_5x5_U"],
    "budget_steps": 64,
    "eval_every": 32,
    "evaluation_points": 0,
    "tensorboard": False,
    "hyperparameters": {"n_steps": 8, "batch_size": 16, "n_epochs": 1},
}


def with_entry(source: Path, target: Path, name: str, content: bytes) -> Path:
    """A copy of the zip ``source`` (``target`` may be it) whose entry ``name`` is ``content``."""
    with zipfile.ZipFile(source) as archive:
        entries = {entry: archive.read(entry) for entry in archive.namelist()}
    entries[name] = content
    with zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as archive:
        for entry, data in entries.items():
            archive.writestr(entry, data)
    return target


def edit_sb3_data(path: Path, **changes: object) -> None:
    """Set ``changes`` in the ``data`` entry of the SB3 zip ``path`` (other entries kept)."""
    with zipfile.ZipFile(path) as archive:
        data = json.loads(archive.read("data"))
    data.update(changes)
    with_entry(path, path, "data", json.dumps(data).encode())


def npy_header(shape: tuple[int, ...], dtype: str = "<f8") -> bytes:
    """A version-1 ``.npy`` header declaring an array of ``shape`` (no data follows)."""
    text = f"{{'descr': '{dtype}', 'fortran_order': False, 'shape': {shape}, }}"
    text += " " * (63 - (10 + len(text)) % 64) + "\n"
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(text)) + text.encode("latin1")


def bomb_npz(source: Path, target: Path, inflated: int, declared: int | None = None) -> Path:
    """A copy of the agent ``source`` whose ``params.npy`` inflates to ``inflated`` bytes (a
    header declaring that many floats, then zeros: about a thousandth on disk); its zip
    entry declares ``declared`` bytes (the true size when ``None``)."""
    with zipfile.ZipFile(source) as archive:
        metadata = archive.read("metadata.npy")
    header = npy_header(((inflated - 128) // 8,))
    with zipfile.ZipFile(target, "w") as archive:
        archive.writestr("metadata.npy", metadata)
        info = zipfile.ZipInfo("params.npy")
        info.compress_type = zipfile.ZIP_DEFLATED
        info.file_size = inflated
        with archive.open(info, "w") as stream:  # zip64 when the size needs it
            stream.write(header)
            left, chunk = inflated - len(header), bytes(1 << 24)
            while left:
                stream.write(chunk[: min(left, len(chunk))])
                left -= min(left, len(chunk))
    if declared is not None:
        content = bytearray(target.read_bytes())
        at = content.rindex(b"PK\x01\x02")  # the central record of params.npy, the last one
        content[at + 24 : at + 28] = struct.pack("<I", declared)
        target.write_bytes(bytes(content))
    return target


def yaml_bomb(path: Path, levels: int = 8) -> Path:
    """A YAML file of ``levels`` lists of ten aliases of the list before: 10**(levels+1) nodes."""
    lines = ["a0: &a0 [x, x, x, x, x, x, x, x, x, x]"]
    for level in range(1, levels + 1):
        lines.append(f"a{level}: &a{level} [{', '.join([f'*a{level - 1}'] * 10)}]")
    path.write_text("\n".join(lines) + "\n")
    return path
