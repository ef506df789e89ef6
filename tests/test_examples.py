"""The scripts of ``examples/`` run to the end on their tiny budgets (``--tiny``).

Each script runs as a user runs it, ``python examples/NAME.py --tiny``, in a
subprocess from the repository's root, and says what it did; the test checks
its exit status and the lines that carry its result (their numbers are not
checked: a tiny budget learns nothing).
"""

from __future__ import annotations

import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
RATE = r"success rate \d\.\d\d"

#: Each example with the lines (regular expressions) its output must hold.
EXPECTED = {
    "ppo_purejaxrl": [
        r"PPO on 8 mazes like M4_10x10_C1 x 4 rotations: 4 updates of 64x64 steps",
        r"trained 16,384 env steps in",
        rf"unseen mazes of the family \(32 x 4\): {RATE}, mean R̄ [-+]\d",
        rf"standard suite \(18 x 4\): {RATE}, .*input recognition \d\.\d\d",
    ],
    "sb3_gymnasium": [
        r"trained 512 env steps in",
        r"EvalCallback: 2 evaluations, best mean return",
        rf"final model on M4_5x5_C1, 4 rotations: {RATE}",
        rf"best model on the standard suite: {RATE}, .*input recognition",
    ],
    "custom_curator": [
        r"curators: careful, .*\bgrow\b",
        r"stage 0 trains on: M4_5x5_U",
        r"stage 1 trains on: M\d+_5x5_\w+, M\d+_5x5_\w+",
        r"stage 1: branch [01] goes on \(own maze success \d\.\d\d, validation success",
        rf"final agent, [\d,]+ env steps: standard suite {RATE}",
        rf"final agent on 32 unseen mazes like M4_10x10_C1 x 4: {RATE}",
    ],
    "evolution_ask_tell": [
        r"CMA-ES on 212 parameters, population 32",
        r"generation    3: best R̄ [-+]\d\.\d{3}, mean",
        rf"champion on unseen mazes of the family \(32 x 4\): {RATE}",
        rf"champion on the standard suite: {RATE}",
    ],
    "study_from_python": [
        r"study 'direct-vs-family': 2 runs",
        r"ran in [\d.]+ s \(exit status 0\)",
        r"all\s+2\s+0\s+0\s+0\s+0",
        r"report\.md: Budgets held equal; Final agents on the evaluation set",
        r"direct/cmaes/steps: success on the evaluation set \d\.\d\d \(median",
        r"domain-randomisation/cmaes/steps: success on the evaluation set",
    ],
}


def test_every_example_is_tested() -> None:
    assert sorted(p.stem for p in EXAMPLES.glob("*.py")) == sorted(EXPECTED)


@pytest.mark.parametrize("name", list(EXPECTED))
def test_example_runs_on_a_tiny_budget(name: str) -> None:
    if name == "ppo_purejaxrl":
        for module in ("jax", "optax"):
            if importlib.util.find_spec(module) is None:
                pytest.skip(f"{module} is not installed (the jax extra)")
    environment = {**os.environ, "PYTHONUNBUFFERED": "1", "MPLBACKEND": "Agg"}
    done = subprocess.run(
        [sys.executable, str(EXAMPLES / f"{name}.py"), "--tiny"],
        cwd=ROOT,
        env=environment,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    for expected in EXPECTED[name]:
        assert re.search(expected, done.stdout), f"no line {expected!r} in:\n{done.stdout}"
