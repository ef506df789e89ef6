"""Damage one file of a run folder at random, then ``--resume`` it; count how each try ends.

    python tools/fuzz_resume.py evolve 300
    python tools/fuzz_resume.py train 150
    python tools/fuzz_resume.py evolve-edhucat 200
    python tools/fuzz_resume.py train-edhucat 100
    python tools/fuzz_resume.py evolve-coevolution 200
    python tools/fuzz_resume.py train-coevolution 100

A small run of the trainer is made once, in a temporary folder. Each try copies
it (a curriculum run without its last branch's result, as if killed while
training it), damages one of its files (random byte flips, a truncation, inserted bytes
or a zeroed span, from a seeded generator) and resumes it in-process. A try
ends as ``resumed`` (the damage was harmless), ``refused`` (exit 2 with exactly
one ``error:`` line: the contract) or as a failure: a ``traceback`` or any
other exit. Failures are printed; the script exits 1 if there was any.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import random
import shutil
import sys
import tempfile
from pathlib import Path

RUNS = {
    "evolve": (
        {
            "algo": "cmaes",
            "mazes": ["M0_5x5_U"],
            "budget_steps": None,
            "max_generations": 3,
            "checkpoint_seconds": 0,
            "algorithm": {"population_size": 6},
        },
        ["config.json", "progress.csv", "checkpoints/state.pkl", "champion.npz"],
    ),
    "train": (
        {"algo": "a2c", "budget_steps": 40, "eval_every": 20, "tensorboard": False},
        [
            "config.json",
            "progress.csv",
            "checkpoints/state.json",
            "checkpoints/model.zip",
            "champion.zip",
            "champion.json",
        ],
    ),
}
#: Curriculum runs: 2 stages x 2 branches with the random curator.
CURRICULUM = {
    "regime": "edhucat",
    "curator": "random",
    "stages": 2,
    "branches": 2,
    "target": "M0_6x6_C1",
}
CURRICULUM_FILES = [
    "config.json",
    "progress.csv",
    "decisions.jsonl",
    "stages/stage-0/branch-0/result.json",
    "stages/stage-1/branch-0/result.json",
]
RUNS["evolve-edhucat"] = (
    {
        **CURRICULUM,
        "algo": "cmaes",
        "budget_steps": 20000,
        "checkpoint_seconds": 0,
        "algorithm": {"population_size": 6},
    },
    [
        *CURRICULUM_FILES,
        "stages/stage-0/branch-0/agent/learner.pkl",
        "stages/stage-0/branch-0/agent/champion.npz",
        "stages/stage-1/branch-0/agent/learner.pkl",
    ],
)
RUNS["evolve-coevolution"] = (
    {
        "regime": "coevolution",
        "target": "M0_6x6_C1",
        "algo": "cmaes",
        "budget_steps": None,
        "max_generations": 4,
        "checkpoint_seconds": 0,
        "algorithm": {"population_size": 6},
        "coevolution": {"capacity": 4, "batch": 2, "validation": 2, "validation_every": 1},
    },
    ["config.json", "progress.csv", "checkpoints/state.pkl", "champion.npz", "mazes.csv"],
)
RUNS["train-coevolution"] = (
    {
        "regime": "coevolution",
        "target": "M0_6x6_C1",
        "algo": "a2c",
        "budget_steps": 40,
        "eval_every": 20,
        "tensorboard": False,
        "coevolution": {"validation": 2, "validation_every": 1},
    },
    ["config.json", "progress.csv", "checkpoints/state.pkl", "checkpoints/model-2.zip"],
)
RUNS["train-edhucat"] = (
    {**CURRICULUM, "algo": "a2c", "budget_steps": 400, "eval_every": 20, "tensorboard": False},
    [
        *CURRICULUM_FILES,
        "stages/stage-0/branch-0/agent/model.zip",
        "stages/stage-0/branch-0/agent/learner.json",
        "stages/stage-1/branch-0/agent/learner.json",
    ],
)


def damage(data: bytearray, rng: random.Random) -> tuple[str, bytearray]:
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
    return kind, data


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("trainer", choices=sorted(RUNS))
    parser.add_argument("tries", type=int)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    if args.trainer.startswith("evolve"):
        from evolution.cli import main as command
        from evolution.run import evolve as make
    else:
        from rl_baselines.cli import main as command
        from rl_baselines.train import train as make
    config, files = RUNS[args.trainer]
    rng = random.Random(args.seed)
    counts = {"resumed": 0, "refused": 0, "failed": 0}
    with tempfile.TemporaryDirectory() as scratch:
        base = Path(scratch) / "run"
        make(config, base)
        (base / "summary.json").unlink()  # as if killed after its last checkpoint
        last = base / "stages/stage-1/branch-1/result.json"
        if last.exists():  # a curriculum run: killed while training its last branch
            last.unlink()
        for index in range(args.tries):
            out = Path(scratch) / f"try-{index}"
            shutil.copytree(base, out)
            name = rng.choice(files)
            kind, data = damage(bytearray((out / name).read_bytes()), rng)
            (out / name).write_bytes(bytes(data))
            err = io.StringIO()
            try:
                with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
                    code = command(["--resume", str(out), "--no-progress"])
            except BaseException as problem:  # the failure this script looks for
                code, err = -1, io.StringIO(f"{type(problem).__name__}: {problem}")
            lines = err.getvalue().splitlines()
            if code == 0:
                counts["resumed"] += 1
            elif code == 2 and len(lines) == 1 and lines[0].startswith("error: "):
                counts["refused"] += 1
            else:
                counts["failed"] += 1
                print(f"try {index}: {name} ({kind}) ended with {code}: {lines[:3]}")
            shutil.rmtree(out)
    print(f"{args.trainer}: {args.tries} tries: {counts}")
    return 1 if counts["failed"] else 0


if __name__ == "__main__":
    sys.exit(main())
