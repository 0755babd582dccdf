"""Tune a classical family's settings for one plant on the validation suite, under a wall-time budget.

    frictiongym tune FAMILY --plant PLANT [--budget-min 20] [--trials 200] [--seed 0] [--episodes 10]
                     [--workers 2] [--out configs/tuned.yaml]

Searches the family's knobs (configs/controllers.yaml, its section) with Optuna's seeded TPE sampler, the
document's design as the first trial, on the first EPISODES validation episodes of each of the plant's
validation scenarios the family applies to; the objective is the rule that selects learned models
(agents/tuning/search.py). Stops at the budget or the trial cap, whichever comes first, and merges the best
values with their manifest into OUT (default: the repository's configs/tuned.yaml, which the leaderboard
reads: the family's `[tuned]` twin). `test` and `generalisation` are never used.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from frictiongym.scripts.options import parser


def main(argv: list[str] | None = None) -> int:
    ap = parser(__doc__)
    ap.add_argument("family", help="a tunable built-in family, e.g. PID+MFF, Cascade+MFF, DOB")
    ap.add_argument("--plant", required=True, help="plant preset: kang_robot, m220, emps, flexible_servo")
    ap.add_argument("--budget-min", type=float, default=20.0, help="wall-time budget (min; default 20)")
    ap.add_argument("--trials", type=int, default=200, help="trial cap, the design included (default 200)")
    ap.add_argument("--seed", type=int, default=0, help="the sampler's seed")
    ap.add_argument("--episodes", type=int, default=10, help="validation episodes per scenario (default 10)")
    ap.add_argument("--workers", type=int, default=2, help="trials evaluated at a time (processes)")
    ap.add_argument("--out", type=Path, default=None, help="tuned-settings file (default configs/tuned.yaml)")
    args = ap.parse_args(argv)
    for name in ("budget_min", "trials", "episodes", "workers"):
        if not getattr(args, name) > 0:
            ap.error(f"--{name.replace('_', '-')} must be positive, got {getattr(args, name)}")
    from frictiongym.agents.evaluation.engine import one_line_errors  # start-up cost: after --help
    from frictiongym.agents.tuning.tuned import tuned_path

    out = args.out or tuned_path()
    return one_line_errors(lambda: run(args, out), out)


def run(args: argparse.Namespace, out: Path) -> int:
    """Tune and write (main's checked options)."""
    from frictiongym.agents.tuning.search import tune, write_tuned

    entry = tune(
        args.family, args.plant, args.budget_min * 60, args.trials, args.seed, args.episodes, args.workers
    )
    write_tuned(out, args.family, args.plant, entry)
    print(f"wrote {args.family}[tuned] for {args.plant} to {out}: {entry['values']}")
    return 0
