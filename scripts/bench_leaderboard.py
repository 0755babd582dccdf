"""The leaderboard's evaluation speed: the full `default` suite (all scenarios x its episodes x all built-in
controllers and the reference rows Ideal and Oracle; no learned models) with 1 worker and with N workers,
and with --ray on a local Ray with 1 and N workers, measured side by side in one run.

    python scripts/bench_leaderboard.py [--workers 2] [--ray]

Prints the wall time of each, the speed-ups, the Ray backend's overhead against the local pool (targets:
<= 180 s with 2 workers, pool speed-up >= 1.7, Ray at most 15 % slower than the pool) and whether every
episodes.csv is byte-identical.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

from frictiongym.agents import engine, registry
from frictiongym.envs.suites import load_suite


def timed(workers: int, out: Path, ray: engine.Ray | None = None) -> tuple[float, int]:
    """Wall time of the default suite into out (for Ray: including the start of its local instance)."""
    episodes = load_suite("default")
    t0 = time.perf_counter()
    names = [*registry.BUILTIN, *registry.LIMITS]
    rows, _ = engine.evaluate_to(out, names, episodes, {"bench": 1}, workers, False, (), ray)
    return time.perf_counter() - t0, len(rows)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 2)
    ap.add_argument("--ray", action="store_true", help="also the Ray backend (pip install -e .[distributed])")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        times = {"serial": timed(1, Path(d) / "serial")}
        times["pool"] = timed(args.workers, Path(d) / "pool")
        if args.ray:
            import ray

            for name, n in (("ray1", 1), ("ray", args.workers)):
                times[name] = timed(n, Path(d) / name, engine.Ray())
                ray.shutdown()
        files = {k: (Path(d) / k / "episodes.csv").read_bytes() for k in times}
    n = times["serial"][1]
    print(f"default suite: {n} episodes (built-in controllers and the reference rows)")
    print(f"local, 1 worker:  {times['serial'][0]:6.1f} s")
    speedup = times["serial"][0] / times["pool"][0]
    print(f"local, {args.workers} workers: {times['pool'][0]:6.1f} s   speed-up {speedup:.2f}x")
    if args.ray:
        r1, r = times["ray1"][0], times["ray"][0]
        print(f"ray,   1 worker:  {r1:6.1f} s")
        print(f"ray,   {args.workers} workers: {r:6.1f} s   speed-up {r1 / r:.2f}x")
        print(f"Ray overhead vs the local pool ({args.workers} workers): {r / times['pool'][0] - 1:+.1%}")
    print(f"episodes.csv identical: {len(set(files.values())) == 1} ({', '.join(files)})")


if __name__ == "__main__":
    main()
