"""Run every applicable controller on the identical episodes of a suite and rank them.

    python scripts/leaderboard.py [--suite default] [--controllers PD PID RDFC] [--out out/leaderboard]

Prints one table per scenario (mean and 95 % bootstrap interval of the main metrics, sorted by IAE) and
writes leaderboard.md, leaderboard.csv and PNG plots to --out.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from frictiongym.agents import leaderboard
from frictiongym.envs.suites import suite_names


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--suite", default="default", choices=suite_names())
    ap.add_argument("--controllers", nargs="*", choices=list(leaderboard.CONTROLLERS), help="default: all")
    ap.add_argument("--out", type=Path, default=Path("out/leaderboard"))
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    _, table = leaderboard.run(args.suite, args.controllers, args.out)
    print(leaderboard.markdown(table, args.suite))
    print(
        f"wrote {args.out / 'leaderboard.md'}, leaderboard.csv and plots in {time.perf_counter() - t0:.0f} s"
    )


if __name__ == "__main__":
    main()
