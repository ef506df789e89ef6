"""Hostile inputs, each through the real command: exit status, error line, seconds, memory.

    python benchmarks/bench_hostile_inputs.py [--repeats 3] [--cases sb3-env,yaml-bomb]

Builds, in a temporary folder, each hostile input an attacker could hand the
commands (an SB3 agent zip whose ``data`` names a module, or sets a method; an
``.npz`` agent whose array header declares a terabyte; a small ``.npz`` whose
entry inflates to 2 GiB; a JAX run folder with a truncated trainer state, a
network of a million units, NaN parameters, a chunk of 2**62 steps; a YAML
config of nested aliases), then runs the command as a user would (a fresh
process, ``amaze``, ``amaze-train``, ``amaze-evolve``) and prints, per case,
the exit status, the first line of standard error, whether a marker file
appeared (code from the file ran), the median wall seconds (a small launcher's
start included) and the largest peak resident memory of the command over
``--repeats`` runs. The command's own start-up
(Python, numpy, the package) is part of both figures: ``baseline`` rows run
the same commands on sound files. The curate server's case (a request with a
lone surrogate) is in ``tests/experiments/test_curate_hostile.py``.
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))
import hostile_files

BIN = Path(sys.executable).parent
MAZE = "M0_5x5_C1"


@dataclass
class Case:
    """One command line on one hostile (or sound) input, run in ``cwd``."""

    name: str
    argv: list[str]
    cwd: Path
    marker: Path | None = None


#: Runs the command and prints its peak RSS (kB). A process keeps the peak of the
#: one it was forked from (Linux carries it across exec), so the command is
#: started by this small launcher, not by the benchmark, which holds torch and JAX.
_LAUNCHER = (
    "import os, subprocess, sys\n"
    "process = subprocess.Popen(sys.argv[1:], stdout=subprocess.DEVNULL)\n"
    "_, status, usage = os.wait4(process.pid, 0)\n"
    "print(os.waitstatus_to_exitcode(status), usage.ru_maxrss)\n"
)


def _measured(argv: list[str], cwd: Path) -> tuple[int, str, float, float]:
    """Exit status, first stderr line, wall seconds and peak RSS (MB) of one run."""
    start = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-c", _LAUNCHER, *argv], cwd=cwd, capture_output=True, text=True
    )
    seconds = time.perf_counter() - start
    code, peak = (int(word) for word in done.stdout.split())
    lines = done.stderr.splitlines()
    return code, (lines[0] if lines else ""), seconds, peak / 1024


def _sb3_agent(folder: Path) -> Path:
    from rl_baselines.agent import SB3Agent, algorithm_class
    from rl_baselines.vec_env import SB3VecEnv

    env = SB3VecEnv(["M1_5x5_U"], "DD", 2)
    model = algorithm_class("ppo")("MlpPolicy", env, device="cpu", n_steps=8, batch_size=8)
    return SB3Agent(model, "DD", "ppo").save(folder / "agent")


def _sb3_edited(source: Path, target: Path, **changes: object) -> Path:
    shutil.copy(source, target)
    shutil.copy(source.with_suffix(".json"), target.with_suffix(".json"))
    hostile_files.edit_sb3_data(target, **changes)
    return target


def _npz_agent(folder: Path) -> Path:
    import numpy as np

    from evolution.agent_file import save_network_agent
    from evolution.networks import NetworkSpec

    spec = NetworkSpec("DD", (4,))
    return save_network_agent(folder / "agent", spec, np.zeros(spec.n_params))


def _jax_run(folder: Path) -> Path:
    from rl_baselines.train import train

    out = folder / "jax-run"
    train(hostile_files.TINY_JAX_RUN, out)
    (out / "summary.json").unlink()
    return out


def _jax_copy(run: Path, folder: Path, name: str, edit: Callable[[Path], None]) -> Path:
    out = folder / name
    shutil.copytree(run, out)
    edit(out / "checkpoints/latest/trainer")
    return out


def _edit_settings(**changes: object) -> Callable[[Path], None]:
    def edit(trainer: Path) -> None:
        settings = json.loads((trainer / "trainer.json").read_text())
        for key, value in changes.items():
            if key == "net_arch":
                settings["hyperparameters"]["policy_kwargs"]["net_arch"] = value
            else:
                settings[key] = value
        (trainer / "trainer.json").write_text(json.dumps(settings))

    return edit


def _nan_params(trainer: Path) -> None:
    import numpy as np

    with np.load(trainer / "state.npz") as stored:
        arrays = {name: stored[name] for name in stored.files}
    for name, array in arrays.items():
        if name.startswith("params/"):
            arrays[name] = np.full_like(array, np.nan)
    np.savez(trainer / "state.npz", **arrays)


def _truncate(trainer: Path) -> None:
    state = trainer / "state.npz"
    state.write_bytes(state.read_bytes()[: state.stat().st_size // 2])


def cases(folder: Path) -> list[Case]:
    """Every case, its files built under ``folder``."""
    amaze, train, evolve = str(BIN / "amaze"), str(BIN / "amaze-train"), str(BIN / "amaze-evolve")
    python = sys.executable
    sb3 = _sb3_agent(folder)
    npz = _npz_agent(folder)
    marker = folder / "code-ran"
    (folder / "somemodule.py").write_text(f"open({str(marker)!r}, 'w').close()\n")
    env = _sb3_edited(sb3, folder / "env.zip", env="somemodule:AMaze-v0")
    zen = _sb3_edited(sb3, folder / "zen.zip", env="this:NoSuchEnv-v0")
    predict = _sb3_edited(sb3, folder / "predict.zip", predict=5)
    header = hostile_files.npy_header((2**40,))
    huge = hostile_files.with_entry(npz, folder / "huge.npz", "params.npy", header)
    bomb = hostile_files.bomb_npz(npz, folder / "bomb.npz", 2 << 30)
    run = _jax_run(folder)
    yaml = hostile_files.yaml_bomb(folder / "bomb.yml")
    resume = [train, "--resume"]
    return [
        Case("baseline: amaze evaluate agent.zip", [amaze, "evaluate", str(sb3), MAZE], folder),
        Case("baseline: amaze evaluate agent.npz", [amaze, "evaluate", str(npz), MAZE], folder),
        Case(
            "1 sb3 env module (python -m amaze)",
            [python, "-m", "amaze", "evaluate", str(env), MAZE],
            folder,
            marker,
        ),
        Case("1 sb3 env 'this' (amaze)", [amaze, "evaluate", str(zen), MAZE], folder),
        Case(
            "1 sb3 env module (run --controller)",
            [amaze, "run", MAZE, "--controller", str(env)],
            folder,
            marker,
        ),
        Case("2 sb3 data predict 5", [amaze, "evaluate", str(predict), MAZE], folder),
        Case("3 npz shape 2**40 (evaluate)", [amaze, "evaluate", str(huge), MAZE], folder),
        Case("3 npz shape 2**40 (run)", [amaze, "run", MAZE, "--controller", str(huge)], folder),
        Case(
            f"4 npz bomb {bomb.stat().st_size // 1024} kB -> 2 GiB",
            [amaze, "evaluate", str(bomb), MAZE],
            folder,
        ),
        Case(
            "5 jax state.npz truncated (--resume)",
            [*resume, str(_jax_copy(run, folder, "truncated", _truncate)), "--no-progress"],
            folder,
        ),
        Case(
            "6 jax net_arch [1e6, 1e6] (--resume)",
            [
                *resume,
                str(_jax_copy(run, folder, "net", _edit_settings(net_arch=[10**6, 10**6]))),
                "--no-progress",
            ],
            folder,
        ),
        Case(
            "6 jax params NaN (--resume)",
            [*resume, str(_jax_copy(run, folder, "nan", _nan_params)), "--no-progress"],
            folder,
        ),
        Case(
            "6 jax chunk_steps 2**62 (--resume)",
            [
                *resume,
                str(_jax_copy(run, folder, "chunk", _edit_settings(chunk_steps=2**62))),
                "--no-progress",
            ],
            folder,
        ),
        Case(
            "7 yaml aliases x10^9 (amaze-train)",
            [
                train,
                "--config",
                str(yaml),
                "--out",
                str(folder / "y1"),
            ],
            folder,
        ),
        Case(
            "7 yaml aliases x10^9 (amaze-evolve)",
            [evolve, "--config", str(yaml), "--out", str(folder / "y2")],
            folder,
        ),
    ]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--cases", default="", help="comma-separated substrings of case names")
    args = parser.parse_args()
    wanted = [word for word in args.cases.split(",") if word]
    print(f"{'case':44s} {'exit':>4s} {'s (median)':>10s} {'MB (max)':>9s}  code ran  stderr")
    with tempfile.TemporaryDirectory() as scratch:
        for case in cases(Path(scratch)):
            if wanted and not any(word in case.name for word in wanted):
                continue
            runs = [_measured(case.argv, case.cwd) for _ in range(args.repeats)]
            code, line = runs[0][0], runs[0][1]
            seconds = statistics.median(r[2] for r in runs)
            memory = max(r[3] for r in runs)
            ran = "yes" if case.marker is not None and case.marker.exists() else "no"
            print(
                f"{case.name:44s} {code:4d} {seconds:10.2f} {memory:9.0f}  {ran:8s}  {line[:150]}"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
