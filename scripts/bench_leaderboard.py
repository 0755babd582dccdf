"""The leaderboard's evaluation speed: the full `default` suite (all scenarios x its episodes x all
controllers) with 1 worker and with N workers, measured side by side in one run.

    python scripts/bench_leaderboard.py [--workers 2]

Prints the wall time of each and the pool's speed-up (targets: <= 120 s with 2 workers, speed-up >= 1.7).
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

from frictiongym.agents import engine, registry
from frictiongym.envs.suites import load_suite


def timed(workers: int, out: Path) -> tuple[float, int]:
    episodes = load_suite("default")
    t0 = time.perf_counter()
    rows, _ = engine.evaluate_to(out, list(registry.available()), episodes, {"bench": 1}, workers, False)
    return time.perf_counter() - t0, len(rows)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 2)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        serial, n = timed(1, Path(d) / "serial")
        pool, _ = timed(args.workers, Path(d) / "pool")
        same = (Path(d) / "serial/episodes.csv").read_bytes() == (Path(d) / "pool/episodes.csv").read_bytes()
    print(f"default suite: {n} episodes (all controllers)")
    print(f"1 worker:  {serial:6.1f} s")
    print(f"{args.workers} workers: {pool:6.1f} s   speed-up {serial / pool:.2f}x")
    print(f"episodes.csv identical: {same}")


if __name__ == "__main__":
    main()
