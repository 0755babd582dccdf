"""Training speed, measured side by side: the setups of configs/bench/training.yaml (or --setups FILE)
trained on one scenario of a training config from the same seeds, each run for the same training time
(--budget-s; validation excluded), on a pool of --workers processes (one run per core, one torch thread).

    frictiongym bench-training residual_sac --scenario m220_reversal_tracking [--seeds 0]
                                     [--budget-s 240] [--workers 2] [--only SETUP ...] [--out DIR]

Prints per setup and seed: env steps/s and gradient steps/s (over the training time), time-to-beat (the
training time until a validation evaluation first beat the best classical baseline's main metric on the
same validation episodes with admissible effort; '-' if it never did, '<=' if the first evaluation
already did: then it is an upper bound, set by the setup's validation interval), the best admissible
validation value at the budget, and the ratios of the medians over seeds against the first setup
(today's). Writes DIR/bench_training.csv as runs finish (atomically: an interrupted bench keeps the runs
it finished) and each run's model folder under DIR/<setup>/seed<N>/. Validation runs in turn here (its
time is not training time); a plain training run validates beside the training (docs/training.md).
"""

from __future__ import annotations

import math
import multiprocessing as mp
import os
import statistics
import sys
from pathlib import Path
from typing import Any

from tqdm import tqdm

from frictiongym.envs.config import ConfigError, Node, configs_dir, load_yaml
from frictiongym.envs.records import atomic_text, command_line, csv_text, missing_extra
from frictiongym.scripts.options import parser


def load_setups(path: Path) -> tuple[float, dict[str, tuple[str | None, dict[str, Any]]]]:
    """The file's training budget (s) and its setups: name -> (algorithm or None, settings overrides)."""
    top = Node(load_yaml(path), str(path))
    budget = top.positive("budget_train_s")
    sec = top.section("setups")
    setups = {}
    for name in list(sec.keys()):
        entry = dict(sec[name] or {})
        setups[name] = (entry.pop("algorithm", None), entry)
    if not setups:
        raise top.error("setups", "expected at least one setup")
    top.done()
    return budget, setups


def run_one(job: tuple[str, str, str, str | None, dict, int, float, str, str]) -> dict[str, Any]:
    """One (setup, seed) run; its figures (picklable for the pool)."""
    config, scenario, setup, algorithm, overrides, seed, budget, out, command = job
    overrides = {"total_timesteps": 10**8, **overrides}  # the budget ends the run
    from frictiongym.agents.training import NothingSelected, TrainingRun, run_config_with  # rl: main checked

    cfg = run_config_with(config, scenario, overrides, algorithm)
    run = TrainingRun(cfg, seed, Path(out), command, progress=False)  # validation in turn
    run.stop_after_train_s = budget
    row: dict[str, Any] = {"setup": setup, "seed": seed, "algorithm": cfg.algorithm, "n_envs": cfg.n_envs}
    try:
        run.train()
        error = ""
    except NothingSelected as e:  # no admissible evaluation: still a measurement of speed
        error = str(e)
    h = run.history
    train_s = h[-1]["train_s"] if h else math.nan
    beat = next(
        (r for r in h if r["admissible"] and r["main"] < run.baseline.main),
        None,
    )
    admissible = [r["main"] for r in h if r["admissible"]]
    row.update(
        {
            "steps": h[-1]["step"] if h else 0,
            "train_s": train_s,
            "eval_s": round(run.eval_s, 1),
            "env_steps_per_s": h[-1]["step"] / train_s if h else math.nan,
            "gradient_steps_per_s": h[-1]["gradient_steps"] / train_s if h else math.nan,
            "baseline": run.baseline.name,
            "baseline_main": run.baseline.main,
            "time_to_beat_s": beat["train_s"] if beat else math.nan,
            "steps_to_beat": beat["step"] if beat else math.nan,
            "beat_at_first_evaluation": bool(beat) and beat is h[0],  # then an upper bound
            "best_main": min(admissible) if admissible else math.nan,
            "error": error,
        }
    )
    return row


def median(rows: list[dict[str, Any]], key: str) -> float:
    """Median over seeds; a run that never beat the baseline counts as +inf in time-to-beat."""
    values = [math.inf if key == "time_to_beat_s" and math.isnan(r[key]) else r[key] for r in rows]
    return statistics.median(values)


def report(rows: list[dict[str, Any]], order: list[str], budget: float) -> None:
    print(
        f"\n{'setup':24s} {'seed':>4s} {'env st/s':>9s} {'grad st/s':>9s} {'beat at s':>9s} "
        f"{'best main':>10s}  baseline"
    )
    for r in sorted(rows, key=lambda r: (order.index(r["setup"]), r["seed"])):
        beat = "-" if math.isnan(r["time_to_beat_s"]) else f"{r['time_to_beat_s']:.0f}"
        if r["beat_at_first_evaluation"]:
            beat = "<=" + beat  # beaten at the first evaluation: the time is an upper bound
        print(
            f"{r['setup']:24s} {r['seed']:4d} {r['env_steps_per_s']:9.0f} {r['gradient_steps_per_s']:9.1f} "
            f"{beat:>9s} {r['best_main']:10.4g}  {r['baseline']} {r['baseline_main']:.4g}"
            + (f"  ({r['error'][:60]})" if r["error"] else "")
        )
    by = {s: [r for r in rows if r["setup"] == s] for s in order if any(r["setup"] == s for r in rows)}
    ref = by.get(order[0])
    if not ref:
        return
    print(f"\nratios of the medians over seeds against {order[0]} (budget {budget:.0f} s of training):")
    for s, rs in by.items():
        speed = median(rs, "env_steps_per_s") / median(ref, "env_steps_per_s")
        grad = median(rs, "gradient_steps_per_s") / median(ref, "gradient_steps_per_s")
        t, t0 = median(rs, "time_to_beat_s"), median(ref, "time_to_beat_s")
        beat = "n/a" if math.isinf(t0) or math.isinf(t) else f"{t / t0:.2f}"
        print(f"  {s:24s} env steps/s {speed:6.2f}x  gradient steps/s {grad:5.2f}x  time-to-beat {beat}")


def main(argv: list[str] | None = None) -> int:
    ap = parser(__doc__)
    ap.add_argument("config", help="a training config (name of configs/agents/ or a path)")
    ap.add_argument("--scenario", required=True, help="the scenario trained on")
    ap.add_argument(
        "--setups",
        type=Path,
        default=configs_dir() / "bench" / "training.yaml",
        help="the learners and settings compared (default: configs/bench/training.yaml)",
    )
    ap.add_argument("--only", nargs="+", help="these setups of the file (the first is the ratios' reference)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0], help="training seeds")
    ap.add_argument("--budget-s", type=float, help="training time per run, s (default: the file's)")
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 2, help="runs at a time (processes)")
    ap.add_argument("--out", type=Path, default=Path("out/bench_training"), help="the runs' folder")
    args = ap.parse_args(argv)
    try:
        from frictiongym.agents.training import run_config_with  # the rl extra: named if missing

    except ModuleNotFoundError as e:
        print(missing_extra(e, "rl", "frictiongym bench-training"), file=sys.stderr)
        return 2
    try:
        budget, setups = load_setups(args.setups)
        if args.only:
            unknown = [s for s in args.only if s not in setups]
            if unknown:
                msg = f"unknown setups {unknown}; the file has {list(setups)}"
                raise ConfigError("setups", msg, str(args.setups))
            setups = {s: setups[s] for s in args.only}
        budget = args.budget_s or budget
        for algorithm, overrides in setups.values():  # every setup is a valid config before any run
            run_config_with(args.config, args.scenario, overrides, algorithm)
    except ConfigError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    out = args.out / Path(args.config).stem / args.scenario
    command = command_line()
    jobs = [
        (args.config, args.scenario, name, alg, ov, seed, budget, str(out / name / f"seed{seed}"), command)
        for seed in args.seeds
        for name, (alg, ov) in setups.items()
    ]
    for j in jobs:
        if Path(j[7]).exists():
            print(f"error: {j[7]} exists: use another --out", file=sys.stderr)
            return 2
    rows: list[dict[str, Any]] = []
    order = list(setups)
    from frictiongym.agents.evaluation.engine import (  # start-up cost: after --help
        init_worker,
        run_interruptibly,
    )

    def run() -> int:

        with mp.get_context("spawn").Pool(
            args.workers, initializer=init_worker, initargs=(os.getpid(),), maxtasksperchild=1
        ) as pool:
            for row in tqdm(pool.imap_unordered(run_one, jobs), total=len(jobs), desc="runs"):
                rows.append(row)
                out.mkdir(parents=True, exist_ok=True)
                atomic_text(out / "bench_training.csv", csv_text(rows))
        report(rows, order, budget)
        print(f"\n{out / 'bench_training.csv'}")
        return 0

    return run_interruptibly(run, f"the finished runs are in {out / 'bench_training.csv'}")


if __name__ == "__main__":
    sys.exit(main())
