"""Where along an episode a controller breaks: the command's rms and the mean absolute tracking error per
time window, averaged over a scenario's episodes (on a chirp, a window is a frequency band).

    frictiongym windows --scenario flexible_chirp --seeds 800000-800004 [--window-s 2.5]
                        [--controllers PID LuGreObserver ...] [--models DIR ...] [--no-randomize]
                        [--out out/windows]

Writes OUT/windows.csv (one row per controller and window; rewritten atomically after each controller, so
an interrupted run keeps the controllers it finished) and OUT/windows.png, and prints the table.
Default controllers: every one the leaderboard would run on the scenario (built-in, the physical-limit
references, plug-ins and the --models folders'); a residual base that is no baseline runs when named.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import TYPE_CHECKING

from frictiongym.scripts.options import parser, scenario_name, seed_range

if TYPE_CHECKING:
    from frictiongym.envs.scenario import Scenario


def main(argv: list[str] | None = None) -> int:
    ap = parser(__doc__)
    ap.add_argument("--scenario", required=True, type=scenario_name, metavar="SCENARIO", help="the scenario")
    ap.add_argument("--seeds", type=seed_range, required=True, help="episode seeds, e.g. 800000-800004")
    ap.add_argument("--window-s", type=float, default=2.5, help="window length (s; default 2.5)")
    ap.add_argument("--controllers", nargs="+", help="default: every built-in controller defined here")
    ap.add_argument("--models", nargs="*", type=Path, default=[], help="saved-model folders")
    ap.add_argument("--no-randomize", action="store_true", help="the nominal plant in every episode")
    ap.add_argument("--out", type=Path, default=Path("out/windows"), help="the run's folder")
    args = ap.parse_args(argv)
    from frictiongym.agents.evaluation.engine import one_line_errors  # --help imports no engine
    from frictiongym.envs.scenario import load_scenario

    scenario = load_scenario(args.scenario)
    if not args.window_s >= scenario.control_period:  # a window could hold no sample
        period = scenario.control_period
        ap.error(f"--window-s must be at least the control period, {period:g} s; got {args.window_s}")
    return one_line_errors(lambda: run(args, scenario), args.out)  # a bad controller, model or disk


def run(args: argparse.Namespace, scenario: Scenario) -> int:
    """The windows of every controller asked for (main's checked options)."""
    from tqdm import tqdm

    from frictiongym.agents import registry
    from frictiongym.agents.evaluation.evaluate import EnvCache
    from frictiongym.agents.evaluation.windows import FIELDS, controller_windows, plot_windows
    from frictiongym.envs.records import atomic_text, csv_text
    from frictiongym.envs.suites import Episode

    controllers, models = registry.entries(args.controllers, args.models)
    if controllers:
        for name in controllers:
            reason = registry.why_not(name, models)(scenario)
            if reason is not None:
                raise ValueError(f"--controllers: {name} does not apply to {args.scenario}: {reason}")
        names = controllers
    else:
        names = [n for n in registry.default_entries(models) if registry.why_not(n, models)(scenario) is None]
    controllers = [registry.make(n, models) for n in names]
    episodes = [Episode(args.scenario, s, not args.no_randomize) for s in args.seeds]
    args.out.mkdir(parents=True, exist_ok=True)
    rows: list[dict] = []
    envs = EnvCache()
    for c in tqdm(controllers, desc="controllers", unit="controller"):
        rows += controller_windows(c, episodes, args.window_s, envs)
        atomic_text(args.out / "windows.csv", csv_text(rows, FIELDS))
    plot_windows(rows, args.out)
    width = max(len("window start (s)"), *(len(c.name) for c in controllers))
    first = [r for r in rows if r["controller"] == controllers[0].name]  # every controller has these windows
    print(f"{'window start (s)':<{width}}  " + " ".join(f"{r['window_start_s']:6.2f}" for r in first))
    if all(math.isfinite(r["frequency_hz_start"]) for r in first):  # a chirp: each window is a band
        print(f"{'frequency (Hz)':<{width}}  " + " ".join(f"{r['frequency_hz_start']:6.3f}" for r in first))
    for key, label in (("mean_abs_error", "mean |error|"), ("effort_rms", "command rms")):
        print(f"\n{label}")
        for c in controllers:
            print(
                f"{c.name:<{width}}  " + " ".join(f"{r[key]:6.3f}" for r in rows if r["controller"] == c.name)
            )
    print(f"\nwrote {args.out / 'windows.csv'} and {args.out / 'windows.png'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
