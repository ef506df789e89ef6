"""Damage one file of a run folder, then resume, replay or play it; count how each try ends.

    python tools/fuzz_resume.py evolve 300
    python tools/fuzz_resume.py train 150
    python tools/fuzz_resume.py evolve-edhucat 200 --mode replay
    python tools/fuzz_resume.py train-edhucat 100
    python tools/fuzz_resume.py evolve-coevolution 200 --hostile
    python tools/fuzz_resume.py train-coevolution 100 --mode controller

A small run of the trainer is made once, in a temporary folder. Each try copies
it (a curriculum run without its last branch's result, as if killed while
training it), replaces one of its files, any file of the folder, with damaged
or hostile content from a seeded generator, and runs one command on it
in-process:

* ``resume`` (default): ``--resume`` the copy;
* ``replay``: ``--replay`` the copy into a new folder (curriculum runs);
* ``controller``: ``amaze run MAZE --controller FILE``, the damaged file as an agent.

Damage is byte-level (flips, a truncation, inserted bytes, a zeroed span) or,
with ``--hostile`` (half of the tries otherwise), content written to attack
the reader: pickles whose loading would create a marker file (the payload that
once ran through a restricted unpickler, a ``__reduce__`` calling
``os.system``), a ``.npz`` whose array is such a pickle, JSON nested 100,000
deep, JSON with NaN, infinities and a 5,000-digit number, an SB3 zip whose
``data`` names a module that creates the marker on import, an ``.npz`` whose
array declares a terabyte, a zip whose entry declares 4 GiB. A try ends as
``ok`` (exit 0: the damage was harmless), ``refused`` (exit 2 with exactly one
``error:`` line: the contract) or as a failure: a traceback, any other exit,
or a marker file created (code ran). Failures are printed; the script exits
1 if there was any. The test suite runs :func:`fuzz` at a small size.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import pickle
import random
import shutil
import struct
import sys
import tempfile
import time
import zipfile
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))  # tools/ is not a package
from hostile_files import npy_header

#: Curriculum runs: 2 stages x 2 branches with the random curator.
CURRICULUM = {
    "regime": "edhucat",
    "curator": "random",
    "stages": 2,
    "branches": 2,
    "target": "M0_6x6_C1",
}
RUNS: dict[str, dict] = {
    "evolve": {
        "algo": "cmaes",
        "mazes": ["M0_5x5_U"],
        "budget_steps": None,
        "max_generations": 3,
        "checkpoint_seconds": 0,
        "algorithm": {"population_size": 6},
    },
    "train": {"algo": "a2c", "budget_steps": 40, "eval_every": 20, "tensorboard": False},
    "evolve-edhucat": {
        **CURRICULUM,
        "algo": "cmaes",
        "budget_steps": 20000,
        "checkpoint_seconds": 0,
        "algorithm": {"population_size": 6},
    },
    "evolve-coevolution": {
        "regime": "coevolution",
        "target": "M0_6x6_C1",
        "algo": "cmaes",
        "budget_steps": None,
        "max_generations": 4,
        "checkpoint_seconds": 0,
        "algorithm": {"population_size": 6},
        "coevolution": {"capacity": 4, "batch": 2, "validation": 2, "validation_every": 1},
    },
    "train-coevolution": {
        "regime": "coevolution",
        "target": "M0_6x6_C1",
        "algo": "a2c",
        "budget_steps": 40,
        "eval_every": 20,
        "tensorboard": False,
        "coevolution": {"validation": 2, "validation_every": 1},
    },
    "train-edhucat": {
        **CURRICULUM,
        "algo": "a2c",
        "budget_steps": 400,
        "eval_every": 100,
        "tensorboard": False,
    },
}
MODES = ("resume", "replay", "controller")
#: The maze ``amaze run`` plays in the controller mode.
MAZE = "M0_5x5_U"


# -- content ------------------------------------------------------------------------


def damage(data: bytearray, rng: random.Random) -> tuple[str, bytes]:
    """Byte-level damage of ``data``: what a disk, a copy or a kill does to a file."""
    kind = rng.choice(["flip", "truncate", "insert", "zero"])
    if kind == "flip" and data:
        for _ in range(rng.randint(1, 8)):
            data[rng.randrange(len(data))] = rng.randrange(256)
    elif kind == "truncate":
        data = data[: rng.randrange(len(data) + 1)]
    elif kind == "insert":
        at = rng.randrange(len(data) + 1)
        data[at:at] = bytes(rng.randrange(256) for _ in range(rng.randint(1, 16)))
    else:
        at = rng.randrange(len(data) + 1)
        data[at : at + rng.randint(1, 64)] = bytes(64)
    return kind, bytes(data)


class _Reduce:
    """An object whose unpickling calls ``os.system(command)``."""

    def __init__(self, command: str) -> None:
        self.command = command

    def __reduce__(self) -> tuple:
        import os

        return os.system, (self.command,)


def generator_ctor_payload(marker: Path) -> bytes:
    """The pickle that ran ``touch MARKER`` through the restricted unpickler of version 1.

    ``numpy.random._pickle.__generator_ctor`` calls its second argument with
    its first; ``amaze.runs.launchers`` + ``subprocess.Popen`` passed a dotted
    look-up of allowed module names.
    """

    def glob(module: bytes, name: bytes) -> bytes:
        return b"c" + module + b"\n" + name + b"\n"

    def text(value: bytes) -> bytes:
        return b"X" + len(value).to_bytes(4, "little") + value

    return (
        b"\x80\x02"
        + glob(b"numpy.random._pickle", b"__generator_ctor")
        + b"(]("
        + text(b"touch")
        + text(str(marker).encode())
        + b"e"
        + glob(b"amaze.runs.launchers", b"subprocess.Popen")
        + b"tR."
    )


def _object_npz(marker: Path) -> bytes:
    buffer = io.BytesIO()
    np.savez(
        buffer,
        state=np.frombuffer(b"{}", dtype=np.uint8),
        a0=np.array([_Reduce(f"touch {marker}")]),
    )
    return buffer.getvalue()


def _zip_entries(original: bytes) -> dict[str, bytes] | None:
    """The entries of ``original`` if it is a readable zip archive."""
    try:
        with zipfile.ZipFile(io.BytesIO(original)) as archive:
            return {name: archive.read(name) for name in archive.namelist()}
    except (zipfile.BadZipFile, OSError, ValueError, EOFError):
        return None


def _zipped(entries: dict[str, bytes]) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        for name, content in entries.items():
            archive.writestr(name, content)
    return buffer.getvalue()


def _sb3_env_module(marker: Path, original: bytes) -> bytes:
    """An SB3 zip whose ``data`` names a module (``env``) that creates the marker on import.

    SB3's own ``load`` hands a stored ``env`` string to ``gym.make``, which
    imports the module before the colon. Other files are left as they are.
    """
    entries = _zip_entries(original)
    if entries is None or "data" not in entries:
        return original
    module = f"amaze_fuzz_{marker.name.replace('-', '_')}"
    (marker.parent / f"{module}.py").write_text(f"open({str(marker)!r}, 'w').close()\n")
    data = json.loads(entries["data"])
    data["env"] = f"{module}:AMaze-v0"
    entries["data"] = json.dumps(data).encode()
    return _zipped(entries)


def _npz_huge_array(marker: Path, original: bytes) -> bytes:
    """An archive whose first ``.npy`` entry declares a terabyte of floats (no data)."""
    entries = _zip_entries(original)
    arrays = [name for name in entries or {} if name.endswith(".npy")]
    if not arrays:
        return original
    entries[arrays[0]] = npy_header((137438953472,))
    return _zipped(entries)


def _zip_declared_gigabytes(marker: Path, original: bytes) -> bytes:
    """A zip whose first entry declares 4 GiB - 1 once inflated (its data unchanged)."""
    if _zip_entries(original) is None or b"PK\x01\x02" not in original:
        return original
    content = bytearray(original)
    at = content.index(b"PK\x01\x02")
    content[at + 24 : at + 28] = struct.pack("<I", 0xFFFFFFFE)
    return bytes(content)


#: Hostile contents ``make(marker, original)``, each made for a marker file that
#: exists only if code ran; the last three edit the file they replace (an SB3
#: zip, an ``.npz``, any zip) and leave other files as they are.
HOSTILE: dict[str, Callable[[Path, bytes], bytes]] = {
    "pickle-generator-ctor": lambda marker, original: generator_ctor_payload(marker),
    "pickle-reduce": lambda marker, original: pickle.dumps(_Reduce(f"touch {marker}")),
    "npz-object-array": lambda marker, original: _object_npz(marker),
    "json-nested": lambda marker, original: b"[" * 100_000,
    "json-non-finite": lambda marker, original: json.dumps(
        {"env_steps": float("nan"), "seconds": float("inf"), "stage": -float("inf")}
    ).encode(),
    "json-huge-number": lambda marker, original: b'{"env_steps": ' + b"9" * 5000 + b"}",
    "sb3-env-module": _sb3_env_module,
    "npz-huge-array": _npz_huge_array,
    "zip-declared-gigabytes": _zip_declared_gigabytes,
}


# -- the fuzzer -----------------------------------------------------------------------


@dataclass
class Report:
    """How the tries of one trainer and mode ended."""

    trainer: str
    mode: str
    counts: Counter = field(default_factory=Counter)
    failures: list[str] = field(default_factory=list)

    def line(self) -> str:
        return f"{self.trainer} {self.mode}: {sum(self.counts.values())} tries: {dict(self.counts)}"


def _commands(trainer: str) -> tuple[Callable, Callable[[list[str]], int]]:
    """The trainer's ``make(config, out)`` and its command's ``main(argv)``."""
    if trainer.startswith("evolve"):
        from evolution.cli import main
        from evolution.run import evolve

        return evolve, main
    from rl_baselines.cli import main
    from rl_baselines.train import train

    return train, main


def made_run(trainer: str, scratch: Path) -> Path:
    """A small run of ``trainer``, as if killed after its last checkpoint (see the docstring)."""
    make, _ = _commands(trainer)
    base = scratch / "run"
    make(RUNS[trainer], base)
    (base / "summary.json").unlink()
    last = base / "stages/stage-1/branch-1/result.json"
    if last.exists():
        last.unlink()
    return base


def _argv(mode: str, out: Path, target: Path, name: str) -> list[str]:
    if mode == "resume":
        return ["--resume", str(out), "--no-progress"]
    if mode == "replay":
        return ["--replay", str(out), "--out", str(target), "--no-progress"]
    return ["run", MAZE, "--controller", str(out / name)]


def fuzz(
    trainer: str,
    tries: int | None,
    *,
    mode: str = "resume",
    seed: int = 0,
    hostile: bool = False,
    kind: str | None = None,
    scratch: Path | None = None,
) -> Report:
    """Damaged copies of a small run of ``trainer``, each given to the ``mode`` command.

    ``tries`` copies, each with a file drawn at random; ``None``: one copy per
    file of the folder, in order (a sweep). ``hostile`` makes every try's
    content hostile; ``kind`` (a key of :data:`HOSTILE`) makes it that one.
    """
    from amaze.cli.main import main as amaze_main

    _, command = _commands(trainer)
    if mode == "controller":
        command = amaze_main
    report = Report(trainer, mode)
    rng = random.Random(seed)
    with contextlib.ExitStack() as stack:
        if scratch is None:
            scratch = Path(stack.enter_context(tempfile.TemporaryDirectory()))
        base = made_run(trainer, scratch)
        names = sorted(str(p.relative_to(base)) for p in base.rglob("*") if p.is_file())
        for index in range(len(names) if tries is None else tries):
            out = scratch / f"try-{index}"
            shutil.copytree(base, out)
            name = names[index] if tries is None else rng.choice(names)
            marker = scratch / f"marker-{index}"
            if kind is not None or hostile or rng.random() < 0.5:
                used = kind or rng.choice(sorted(HOSTILE))
                content = HOSTILE[used](marker, (out / name).read_bytes())
            else:
                used, content = damage(bytearray((out / name).read_bytes()), rng)
            (out / name).write_bytes(content)
            sys.path.insert(0, str(scratch))  # where the module of "sb3-env-module" lies
            try:
                code, lines = _run(command, _argv(mode, out, scratch / f"replayed-{index}", name))
            finally:
                sys.path.remove(str(scratch))
            time.sleep(0.05)  # a payload that started a process: let it touch its marker
            outcome = _outcome(code, lines, marker)
            report.counts[outcome] += 1
            if outcome not in ("ok", "refused"):
                report.failures.append(f"try {index}: {name} ({used}) {outcome}: {lines[:3]}")
            shutil.rmtree(out)
            shutil.rmtree(scratch / f"replayed-{index}", ignore_errors=True)
    return report


def _run(command: Callable[[list[str]], int], argv: list[str]) -> tuple[int, list[str]]:
    """The command's exit status and standard error lines (a traceback counts as -1)."""
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            code = command(argv)
    except BaseException as problem:  # the failure this script looks for
        return -1, [f"{type(problem).__name__}: {problem}"]
    return code, [line for line in err.getvalue().splitlines() if not line.startswith("warning:")]


def _outcome(code: int, lines: list[str], marker: Path) -> str:
    if marker.exists():
        return "ran code"
    if code == 0:
        return "ok"
    if code == 2 and len(lines) == 1 and lines[0].startswith("error: "):
        return "refused"
    return f"exit {code}"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("trainer", choices=sorted(RUNS))
    parser.add_argument("tries", type=int)
    parser.add_argument("--mode", choices=MODES, default="resume")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--hostile", action="store_true", help="hostile content in every try")
    args = parser.parse_args()
    if args.mode == "replay" and "edhucat" not in args.trainer:
        parser.error("--mode replay needs a curriculum run (evolve-edhucat, train-edhucat)")
    report = fuzz(args.trainer, args.tries, mode=args.mode, seed=args.seed, hostile=args.hostile)
    for failure in report.failures:
        print(failure)
    print(report.line())
    return 1 if report.failures else 0


if __name__ == "__main__":
    sys.exit(main())
