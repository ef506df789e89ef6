"""Build the paper's evaluation suite and write ``amaze/data/paper_suite.json``.

The construction lives in :mod:`amaze.evaluation.paper_suite` (the paper's evaluation
script, ``eval.py``'s ``_generate_mazes``); this script runs it on the full sample
(10000 mazes per family) on all cores and stores the result, so that users and tests
load it instantly.

Usage: ``python tools/make_paper_suite.py [--sample-size 10000] [--workers N] [--output PATH]``
"""

from __future__ import annotations

import argparse
import json
import os
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from amaze.evaluation.paper_suite import PAPER_SAMPLE_SIZE, build_paper_suite

DEFAULT_OUTPUT = Path(__file__).resolve().parent.parent / "amaze" / "data" / "paper_suite.json"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sample-size", type=int, default=PAPER_SAMPLE_SIZE)
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT)
    args = parser.parse_args(argv)
    start = time.perf_counter()
    if args.workers > 1:
        with ProcessPoolExecutor(max_workers=args.workers) as pool:
            suite = build_paper_suite(args.sample_size, map_fn=pool.map)
    else:
        suite = build_paper_suite(args.sample_size)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    tmp = args.output.with_suffix(".tmp")
    tmp.write_text(json.dumps(suite.to_dict(), indent=1) + "\n", encoding="utf-8")
    tmp.replace(args.output)
    for maze in suite.mazes:
        print(
            f"{maze.column:>9} {maze.row:>6}  entropy={maze.script_entropy:.4f} nats"
            f"  S={maze.surprisingness:.4f}  {maze.string}"
        )
    print(f"wrote {args.output} in {time.perf_counter() - start:.1f} s")


if __name__ == "__main__":
    main()
