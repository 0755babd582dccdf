"""Draw the episode parameters of many seeds for every plant preset and every scenario and count the draws
that reset would reject (the numerics and physical checks); the ranges are checked at their corners at
load, so every count should be 0. Exits with status 1 if any draw is rejected.

    frictiongym check-draws [--seeds 100000] [--workers 2]
"""

from __future__ import annotations

import sys
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context

from tqdm import tqdm

from frictiongym.envs.config import plant_names, scenario_names
from frictiongym.scripts.options import parser

CHUNK = 5000  # seeds per job


def main() -> None:
    ap = parser(__doc__)
    ap.add_argument("--seeds", type=int, default=100_000, help="seeds 0 .. N-1 per preset and scenario")
    ap.add_argument("--workers", type=int, default=2, help="processes")
    args = ap.parse_args()
    # start-up cost: --help imports no MuJoCo
    from frictiongym.envs.plants import plant_spec
    from frictiongym.envs.plants.params import rejected_draws
    from frictiongym.envs.scenario import load_scenario

    if args.seeds < 1 or args.workers < 1:
        ap.error("--seeds and --workers must be at least 1")
    specs = {f"plant {p}": plant_spec(p) for p in plant_names()}
    specs |= {f"scenario {s}": load_scenario(s).spec for s in scenario_names()}
    starts = range(0, args.seeds, CHUNK)
    with ProcessPoolExecutor(args.workers, mp_context=get_context("spawn")) as pool:
        futures = {
            label: [pool.submit(rejected_draws, spec, range(a, min(a + CHUNK, args.seeds))) for a in starts]
            for label, spec in specs.items()
        }
        bar = tqdm(total=len(specs) * len(starts), unit="chunk", desc="drawing")
        rejected = {}
        for label, fs in futures.items():
            rejected[label] = []
            for f in fs:
                rejected[label] += f.result()
                bar.update()
        bar.close()
    print(f"{'preset or scenario':42s} {'seeds':>8s} {'rejected':>9s}  first rejected")
    for label, bad in rejected.items():
        first = f"seed {bad[0][0]}: {bad[0][1]}" if bad else ""
        print(f"{label:42s} {args.seeds:8d} {len(bad):9d}  {first}")
    sys.exit(1 if any(rejected.values()) else 0)


if __name__ == "__main__":
    main()
