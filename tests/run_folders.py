"""Helpers of the tests that damage run folders: snapshots and ways to damage a file."""

from __future__ import annotations

import csv
import importlib.util
import json
import shutil
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest


def load_tool(name: str):
    """The module of the maintenance script ``tools/<name>.py`` (``tools`` is not a package)."""
    if name not in sys.modules:
        path = Path(__file__).parents[1] / "tools" / f"{name}.py"
        spec = importlib.util.spec_from_file_location(name, path)
        module = sys.modules[name] = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    return sys.modules[name]


#: 512 random bytes (seeded): a file of garbage.
RANDOM = bytes(np.random.default_rng(0).integers(0, 256, 512, dtype=np.uint8))


def snapshot(folder: Path) -> dict[str, bytes | None]:
    """Every path under ``folder`` with its content (``None`` for folders)."""
    return {
        str(p.relative_to(folder)): (p.read_bytes() if p.is_file() else None)
        for p in sorted(folder.rglob("*"))
    }


def write(content: bytes) -> Callable[[Path], None]:
    """Damage: replace the file's content."""
    return lambda path: path.write_bytes(content)


def truncate(path: Path) -> None:
    """Damage: keep the first half of the file."""
    path.write_bytes(path.read_bytes()[: max(1, path.stat().st_size // 2)])


def directory(path: Path) -> None:
    """Damage: a folder where the file was."""
    path.unlink()
    path.mkdir()
    (path / "inside").write_text("x")


def missing(path: Path) -> None:
    """Damage: no file."""
    path.unlink()


def edit_json(**changes: object) -> Callable[[Path], None]:
    """Damage: change some keys of a JSON object."""

    def edit(path: Path) -> None:
        path.write_text(json.dumps({**json.loads(path.read_text()), **changes}))

    return edit


def edit_sb3_data(**changes: object) -> Callable[[Path], None]:
    """Damage: an SB3 zip whose ``data`` entry has ``changes`` (other entries kept)."""
    return lambda path: load_tool("hostile_files").edit_sb3_data(path, **changes)


def refused_resume(
    main: Callable[[list[str]], int],
    finished_run: Path,
    out: Path,
    name: str,
    damage: Callable[[Path], None],
    capsys: pytest.CaptureFixture[str],
) -> str:
    """Damage file ``name`` of a copy of ``finished_run`` (its summary removed), ``--resume`` it.

    Checks the command's contract for a refusal (exit 2, exactly one line
    ``error: ...`` on stderr, nothing in the folder changed) and returns that line.
    """
    shutil.copytree(finished_run, out)
    (out / "summary.json").unlink(missing_ok=True)  # a finished run is not resumed: killed before
    damage(out / name)
    before = snapshot(out)
    assert main(["--resume", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("error: "), err
    assert snapshot(out) == before
    return err[0]


def write_config(folder: Path, config: dict, **changes: object) -> Path:
    """``config`` with ``changes``, written as ``folder/config-in.json`` (for ``--config``)."""
    path = folder / "config-in.json"
    path.write_text(json.dumps({**config, **changes}))
    return path


def timeless_progress(out: Path) -> list[dict[str, str]]:
    """The rows of an evolution run's ``progress.csv`` without the columns of seconds.

    Two runs of one config and seed have equal rows; their seconds differ.
    """
    with open(out / "progress.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    for row in rows:
        del row["seconds"], row["eval_seconds"]
    return rows


class FakeClock:
    """A clock that moves by ``tick`` seconds each time it is read (and by a sleep's length).

    Patched into the modules that time a run (:meth:`install`), it makes a run on a
    seconds budget end after the same steps however fast or loaded the machine is.
    """

    def __init__(self, tick: float = 0.01) -> None:
        self.now = 1000.0
        self.tick = tick

    def _read(self) -> float:
        self.now += self.tick
        return self.now

    monotonic = perf_counter = time = _read

    def sleep(self, seconds: float) -> None:
        self.now += max(0.0, seconds)

    def install(self, monkeypatch: pytest.MonkeyPatch, *modules: object) -> FakeClock:
        """Make ``time`` in each of ``modules`` this clock."""
        for module in modules:
            monkeypatch.setattr(module, "time", self)
        return self


def retagged_checkpoint(path: Path, old: str, new: str, out: Path) -> Path:
    """A copy of checkpoint ``path`` at ``out`` whose class tags of module ``old`` name ``new``.

    What a run folder written before a module was renamed holds (``old`` the
    current module, ``new`` the former name), or a tag of a module that never was.
    """
    with np.load(path) as archive:
        entries = {name: archive[name] for name in archive.files}
    text = entries["state"].tobytes().decode("utf-8")
    assert f"{old}:" in text
    retagged = text.replace(f"{old}:", f"{new}:")
    entries["state"] = np.frombuffer(retagged.encode("utf-8"), dtype=np.uint8)
    np.savez_compressed(out, **entries)
    return out
