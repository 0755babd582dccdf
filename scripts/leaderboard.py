"""Run every applicable controller on the identical episodes of a suite and rank them.

    frictiongym leaderboard [--suite default | --scenarios A B --seeds 5000-5049 [--randomize]]
                            [--controllers PD PID ...] [--models DIR ...] [--workers N]
                            [--out out/leaderboard]
    frictiongym leaderboard --report-from DIR --out OTHER    (a finished run's report, DIR only read;
                            its models and plug-ins only those --models and --controllers name)

Episodes run as jobs on N worker processes (default: every core) and land in OUT/episodes.csv as they
finish; rerunning with the same options and --out resumes, and other options into the same --out are
refused. Every episode also runs the reference rows (Zero, Ideal: the scenario's uncompensated loop
without the nonlinear friction, TrackingLimit: the friction-free twin under the linear two-degree-of-
freedom loop, on tracking scenarios, Oracle: the loop plus the true friction torque) and the
uncompensated loop. Then writes index.html (the page to open in a browser), answer.md (the suite's
question per plant and per scenario), leaderboard.md, leaderboard.csv, aggregate.csv (the per-plant
aggregates of g over equal sets of scenarios), skipped.csv (the pairs that do not apply, with their
reasons) and PNG plots, and prints the answer per plant and where the page is.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from frictiongym.envs.suites import suite_names
from frictiongym.scripts.options import add_backend_arguments, backend_of, parser, scenario_name, seed_range


def main(argv: list[str] | None = None) -> int:
    ap = parser(__doc__)
    src = ap.add_mutually_exclusive_group()
    src.add_argument(
        "--suite", choices=suite_names(), help="a suite of configs/suites.yaml (default: default)"
    )
    src.add_argument(
        "--scenarios",
        nargs="+",
        type=scenario_name,
        metavar="SCENARIO",
        help="an inline suite (with --seeds); `frictiongym list` prints the scenarios",
    )
    ap.add_argument("--seeds", type=seed_range, help="seeds of the inline suite, e.g. 5000-5049")
    ap.add_argument("--randomize", action="store_true", help="randomise the inline suite's episodes")
    ap.add_argument(
        "--controllers",
        nargs="+",
        help="built-in names, your own as path.py:Class or module:Class (default: every built-in entry "
        "and --models; a residual base that is no baseline, e.g. SpeedScheduled, runs only when named)",
    )
    ap.add_argument(
        "--models",
        nargs="*",
        type=Path,
        help="saved-model folders (manifest.yaml); default: the committed ones "
        "(agents/models/specialist and agents/models/generalist); "
        "--models alone: none (classical and plug-in controllers only, no rl extra needed)",
    )
    src.add_argument(
        "--report-from",
        type=Path,
        metavar="DIR",
        help="write the report of the finished run in DIR to --out, reading DIR only (e.g. read-only media)",
    )
    ap.add_argument(
        "--no-judging",
        action="store_true",
        help="a quick look: skip the judging sets (the baseline is then chosen on the run's own episodes and "
        "no row runs the robustness set); the answer says it is not one to quote",
    )
    add_backend_arguments(ap)
    ap.add_argument("--out", type=Path, default=Path("out/leaderboard"), help="the run's folder")
    args = ap.parse_args(argv)
    # start-up cost: --help imports none of these (MuJoCo, the controllers, the engine)
    from frictiongym.agents.evaluation import leaderboard
    from frictiongym.agents.evaluation.engine import one_line_errors, run_interruptibly
    from frictiongym.agents.registry import LEADERBOARD_GROUPS, committed_models
    from frictiongym.envs.suites import Episode

    if args.report_from is not None:

        # what the run's folder may name: the command line's models (default: the committed ones) and
        # plug-ins (--controllers path.py:Class); run.json itself is data
        allowed = (*(args.models if args.models is not None else committed_models(*LEADERBOARD_GROUPS)),)
        allowed += tuple(c for c in args.controllers or () if ":" in c)

        def report() -> int:
            leaderboard.report_from(args.report_from, args.out, tuple(map(str, allowed)))
            print(f"wrote {args.out / 'leaderboard.md'}, leaderboard.csv and plots from {args.report_from}")
            return 0

        return one_line_errors(report, args.out)
    ray = backend_of(args, ap)
    if args.scenarios and not args.seeds:
        ap.error("--scenarios needs --seeds")
    if args.seeds and not args.scenarios:
        ap.error("--seeds goes with --scenarios (a suite has its own seeds)")
    suite = args.suite or ("inline" if args.scenarios else "default")
    episodes = (
        [Episode(sc, seed, args.randomize) for sc in args.scenarios for seed in args.seeds]
        if args.scenarios
        else None
    )
    models = args.models if args.models is not None else committed_models(*LEADERBOARD_GROUPS)
    t0 = time.perf_counter()

    def run() -> int:
        leaderboard.run(
            suite,
            args.controllers,
            args.out,
            workers=args.workers,
            episodes=episodes,
            models=models,
            ray=ray,
            judge=not args.no_judging,
        )
        return 0

    resume = f"the finished rows are in {args.out / 'episodes.csv'}; rerun the same command to resume"
    code = one_line_errors(lambda: run_interruptibly(run, resume), args.out)
    if code:
        return code
    print(f"\n{the_answer(args.out / 'answer.md')}\n")
    print(f"done in {time.perf_counter() - t0:.0f} s on {args.workers} workers")
    print(f"the page (open it in a browser): {args.out / 'index.html'}")
    print(f"the answer per scenario: {args.out / 'answer.md'}; every table: {args.out / 'leaderboard.md'}")
    return 0


def the_answer(answer_md: Path) -> str:
    """answer.md's headline (its "The answer" section: per plant, the verdict and the rows that win)."""
    text = answer_md.read_text()
    section = text.partition("## The answer\n")[2].split("\n## ")[0].strip()
    return "The answer (best learned or plug-in entry against the best classical, per plant):\n" + section


if __name__ == "__main__":
    sys.exit(main())
