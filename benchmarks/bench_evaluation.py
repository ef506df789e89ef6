"""Wall-clock time of the full evaluation protocol for one small MLP policy.

The policy is a numpy multilayer perceptron (8 -> 32 -> 32 -> 4, tanh, argmax)
with seeded random weights; it acts on a DD robot's observations. One
evaluation plays the standard suite (18 mazes x 4 rotations = 72 episodes,
stepped together on the batch engine until every episode has ended) and runs
the input-recognition test (140 inputs). The suite is prepared once (maze
generation and compilation), as every training run does; the time of that
preparation is printed separately. Goal: under 0.1 s per evaluation.

Usage: ``python benchmarks/bench_evaluation.py [--repeats 21] [--robot DD]``
"""

from __future__ import annotations

import argparse
import itertools
import statistics
import time

import numpy as np

from amaze.evaluation.protocol import Evaluator


class MLPPolicy:
    """A small tanh MLP, argmax over the 4 actions."""

    def __init__(self, n_inputs: int, hidden: int = 32, seed: int = 0) -> None:
        rng = np.random.default_rng(seed)
        sizes = [n_inputs, hidden, hidden, 4]
        self.layers = [
            (rng.normal(0, 1 / np.sqrt(a), (a, b)).astype(np.float32), np.zeros(b, np.float32))
            for a, b in itertools.pairwise(sizes)
        ]

    def __call__(self, observations: np.ndarray) -> np.ndarray:
        x = observations.reshape(len(observations), -1).astype(np.float32)
        for k, (weights, bias) in enumerate(self.layers):
            x = x @ weights + bias
            if k < len(self.layers) - 1:
                x = np.tanh(x)
        return x.argmax(axis=1)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=21)
    parser.add_argument("--robot", default="DD", help="DD or a hybrid robot such as H15")
    args = parser.parse_args(argv)

    started = time.perf_counter()
    evaluator = Evaluator(args.robot)
    print(f"suite prepared in {time.perf_counter() - started:.2f} s (once per run)")
    n_inputs = int(np.prod(evaluator.engine.observation_shape))
    policy = MLPPolicy(n_inputs)
    report = evaluator.evaluate(policy)  # compile / warm up
    times = []
    for _ in range(args.repeats):
        started = time.perf_counter()
        report = evaluator.evaluate(policy)
        times.append(time.perf_counter() - started)
    steps = max(e.steps for e in report.episodes)
    print(
        f"{args.robot}: {len(report.episodes)} episodes (longest {steps} steps) +"
        f" input recognition: median {statistics.median(times) * 1e3:.1f} ms"
        f" (min {min(times) * 1e3:.1f}, max {max(times) * 1e3:.1f}; {args.repeats} repeats)"
    )
    print(f"  success {report.success_rate:.3f}, mean R̄ {report.normalized_reward:+.3f}")


if __name__ == "__main__":
    main()
