"""Training regimes side by side at an equal wall-clock budget, several seeds each.

    python benchmarks/bench_regimes.py --out results/regimes --seconds 300 --seeds 7 0 1 2 3
    python benchmarks/bench_regimes.py --out results/neat --algo neat --steps 100000000 \
        --regimes direct interpolation careful edens coevolution --seeds 0 1 2 --jobs 2

runs (or, for run folders already finished, only reads) one ``amaze-evolve``
process per regime and seed, each on its own with the same algorithm
(CMA-ES with one 16-unit hidden layer of four outputs and 16 IPOP restarts,
:data:`ALGORITHM`, or ``--algo neat`` with its defaults; ``--algorithm`` with
``"symmetry": "rotations"`` in its network gives the coevolution regime's
own default, the network shared by the four directions). NEAT's defaults
differ by regime: the coevolution regimes share its genomes across the
directions, the others do not; ``--algorithm '{"symmetry": "none"}'`` (or
``"rotations"``) makes them the same everywhere:

* ``dr``: domain randomisation, the direct regime on 8 fixed mazes of the
  target's family (``M31_8x8 ... M38_20x20``, ``C1_l.25_L.25_t.5_T.5``);
* ``direct``: the direct regime on the paper's training maze;
* ``interpolation``, ``careful`` (edhucat with the careful curator),
  ``edens``: the curriculum loop with their curators;
* ``coevolution``: the co-evolved maze population;
* ``edens-populations``: EDEnS over co-evolved maze populations (``--selector``
  gives its selector's options as JSON).

It prints, per regime, every seed's standard-suite success, R̄ and input
recognition, and its champion's success and R̄ on 32 family mazes no regime
trained or selected on (``amaze.curriculum.validation.unseen_mazes``), then the
medians, and for each regime against ``dr`` a one-sided Mann-Whitney U test
with its effect size (Cliff's delta, from -1 to 1). With a seconds budget
runs are sequential (each has the whole machine); with ``--steps`` they
may run ``--jobs`` at a time (the same steps give the same result).
``--regimes`` picks some (default ``dr edens coevolution``); ``--algorithm``
gives other options (JSON); ``--slip P`` makes the robots of the coevolution
regimes slip (:mod:`evolution.slip`).
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
from pathlib import Path

from scipy.stats import mannwhitneyu

from amaze.curriculum.regimes import COEVOLUTION_REGIMES
from amaze.curriculum.validation import unseen_mazes
from amaze.evaluation.suite import PAPER_TRAINING_MAZE
from evolution.agent_file import load_agent
from evolution.population import PopulationEvaluator
from experiments.trainers import DOMAIN_RANDOMISATION_MAZES

ALGORITHM = {"network": {"hidden": [16]}, "restarts": 16}
REGIMES = {
    "dr": {"regime": "direct", "mazes": DOMAIN_RANDOMISATION_MAZES},
    "direct": {"regime": "direct"},
    "interpolation": {"regime": "interpolation"},
    "careful": {"regime": "edhucat", "curator": "careful"},
    "edens": {"regime": "edens"},
    "coevolution": {"regime": "coevolution"},
    "edens-populations": {"regime": "edens-populations"},
}


def command(folder: Path, regime: str, seed: int, args: argparse.Namespace) -> list[str] | None:
    """The ``amaze-evolve`` command of one run; None if ``folder`` holds a finished run."""
    if (folder / "summary.json").exists():
        return None
    if (folder / "config.json").exists():
        return [sys.executable, "-m", "evolution.cli", "--resume", str(folder), "--no-progress"]
    folder.parent.mkdir(parents=True, exist_ok=True)
    config = {**REGIMES[regime], "seed": seed, "algo": args.algo, "algorithm": args.algorithm}
    config["robot"] = args.robot
    if regime == "edens-populations" and args.selector is not None:
        config["selector"] = args.selector
    if args.slip:
        config["slip"] = args.slip
    config.update(budget_seconds=args.seconds, budget_steps=args.steps)
    config_file = folder.parent / f"{folder.name}.json"
    config_file.write_text(json.dumps(config))
    return [
        sys.executable, "-m", "evolution.cli", "--config", str(config_file),
        "--out", str(folder), "--no-progress",
    ]  # fmt: skip


def run_all(commands: list[list[str]], jobs: int) -> None:
    """Run ``commands``, ``jobs`` at a time (1 for seconds budgets: each needs the machine)."""
    running: list[subprocess.Popen] = []
    for line in commands:
        while len(running) >= jobs:
            running.pop(0).wait()
        running.append(subprocess.Popen(line))
    for process in running:
        process.wait()


def champion_file(folder: Path) -> Path:
    """The agent of a run folder, as its ``summary.json`` names it (the suite's figures are its)."""
    summary = json.loads((folder / "summary.json").read_text())
    return folder / summary.get("agent", "agent.npz")


def figures(folder: Path, seed: int) -> dict[str, float]:
    """The suite's figures and the champion's on the unseen family mazes."""
    summary = json.loads((folder / "summary.json").read_text())
    unseen = PopulationEvaluator(
        unseen_mazes(PAPER_TRAINING_MAZE, seed), summary["robot"], rotations=True
    ).evaluate(load_agent(champion_file(folder)))
    return {
        "success": summary["success_rate"],
        "reward": summary["normalized_reward"],
        "recognition": summary["input_recognition"],
        "unseen_success_rate": float(unseen.success_rate[0]),
        "unseen_normalized_reward": float(unseen.normalized_reward[0]),
        "env_steps": summary["env_steps"],
    }


def cliffs_delta(a: list[float], b: list[float]) -> float:
    """P(a > b) - P(a < b) over all pairs."""
    pairs = [(x > y) - (x < y) for x in a for y in b]
    return sum(pairs) / len(pairs)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=Path("results/regimes"))
    parser.add_argument("--seconds", type=float, default=None, help="budget (default 300)")
    parser.add_argument("--steps", type=int, default=None, help="env steps budget instead")
    parser.add_argument("--seeds", type=int, nargs="+", default=[7, 0, 1, 2, 3])
    parser.add_argument(
        "--regimes", nargs="+", default=["dr", "edens", "coevolution"], choices=list(REGIMES)
    )
    parser.add_argument("--algo", default="cmaes", choices=("cmaes", "neat"))
    parser.add_argument("--robot", default="DD", help="DD, or a hybrid robot such as H15")
    parser.add_argument("--algorithm", type=json.loads, default=None, help="(default: ALGORITHM)")
    parser.add_argument("--jobs", type=int, default=1, help="runs at once (steps budgets only)")
    parser.add_argument(
        "--selector", type=json.loads, default=None,
        help="edens-populations' selector options (JSON; default: the regime's)",
    )  # fmt: skip
    parser.add_argument(
        "--slip", type=float, default=0.0,
        help="the coevolution regimes' slip probability (evolution.slip; default 0)",
    )  # fmt: skip
    args = parser.parse_args()
    unslipped = [r for r in args.regimes if REGIMES[r]["regime"] not in COEVOLUTION_REGIMES]
    if args.slip and unslipped:
        parser.error(f"--slip acts in coevolution and edens-populations only, not {unslipped}")
    if args.seconds is None and args.steps is None:
        args.seconds = 300.0
    if args.algorithm is None:
        args.algorithm = ALGORITHM if args.algo == "cmaes" else {}
    if args.seconds is not None and args.jobs != 1:
        parser.error("a seconds budget needs the whole machine per run: --jobs 1")
    runs = [(r, s, args.out / r / f"seed-{s}") for r in args.regimes for s in args.seeds]
    run_all([c for r, s, f in runs if (c := command(f, r, s, args))], args.jobs)
    table: dict[str, list[dict[str, float]]] = {}
    for regime, seed, folder in runs:
        table.setdefault(regime, []).append(figures(folder, seed))
    keys = ("success", "reward", "recognition", "unseen_success_rate", "unseen_normalized_reward")
    print(f"{'regime':12} {'seed':>4} " + " ".join(f"{k:>14}" for k in keys) + "   env steps")
    for regime, rows in table.items():
        for seed, row in zip(args.seeds, rows, strict=True):
            values = " ".join(f"{row[k]:14.3f}" for k in keys)
            print(f"{regime:12} {seed:4d} {values}   {row['env_steps']:,}")
        medians = " ".join(f"{statistics.median(r[k] for r in rows):14.3f}" for k in keys)
        print(f"{regime:12} {'med':>4} {medians}")
    if "dr" in table:
        print("\nagainst dr (one-sided Mann-Whitney U, Cliff's delta):")
        for regime, rows in table.items():
            if regime == "dr":
                continue
            for key in ("success", "reward", "unseen_success_rate", "unseen_normalized_reward"):
                ours, theirs = [r[key] for r in rows], [r[key] for r in table["dr"]]
                test = mannwhitneyu(ours, theirs, alternative="greater")
                print(
                    f"  {regime:12} {key:15} U={test.statistic:5.1f} p={test.pvalue:.4f}"
                    f" delta={cliffs_delta(ours, theirs):+.2f}"
                )


if __name__ == "__main__":
    main()
