"""Train learned friction compensators (stable-baselines3 / sb3-contrib) from a training config.

    frictiongym train --config configs/agents/residual_sac.yaml [--scenario S] [--seed N ...]
                      [--steps N] [--workers W] [--out DIR] [--resume]
    frictiongym train --sweep configs/sweeps/residual_sac_alpha.yaml [--address ADDR] [--workers W]
    frictiongym train --export RUN_DIR ... --out agents/models/specialist

Each (scenario, seed) run writes DIR/<name>/<scenario>/seed<N>/: the model selected on the validation
suite with its frozen normalisation statistics, manifest.yaml (algorithm, scenario, base controller, α,
hyper-parameters, seed, steps, wall time, this command, package version, validation score),
validation.csv, training_curve.png, TensorBoard logs (tb/) and a checkpoint for --resume. The folder
is a leaderboard entry: frictiongym leaderboard --models DIR/<name>/<scenario>/seed<N>

A sweep (seeds x a grid, or an Optuna search, over config values; configs/sweeps/) runs its trials on
Ray Tune: a local Ray on --workers CPUs, or the cluster at --address. Every trial writes a model folder
DIR/<sweep>/<scenario>/seed<N>-<trial>/ and reports its validation score to Tune; DIR/<sweep>.csv lists
the trials. Needs pip install -e .[distributed].
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

from frictiongym.envs.config import ConfigError, preset_names
from frictiongym.envs.records import atomic_text, csv_text, missing_extra
from frictiongym.scripts.options import parser


def main(argv: list[str] | None = None) -> int:
    ap = parser(__doc__)
    what = ap.add_mutually_exclusive_group(required=True)
    what.add_argument("--config", help=f"a YAML path or a name of configs/agents/ {preset_names('agents')}")
    what.add_argument("--sweep", help="a YAML path or a name of configs/sweeps/ (runs on Ray Tune)")
    what.add_argument("--export", nargs="+", type=Path, help="copy finished run folders to --out (to commit)")
    ap.add_argument("--address", help="with --sweep: the Ray cluster to run on (default: a local Ray)")
    ap.add_argument("--scenario", help="train only this scenario of the config")
    ap.add_argument("--seed", type=int, nargs="+", default=[0], help="training seeds (default: 0)")
    ap.add_argument(
        "--steps", type=int, help="environment steps per run, replacing the config's total_timesteps (a try)"
    )
    ap.add_argument("--workers", type=int, default=1, help="parallel runs or trials, one process each")
    ap.add_argument("--out", type=Path, default=Path("out/models"), help="the runs' folder")
    ap.add_argument("--resume", action="store_true", help="continue the runs' checkpoints")
    args = ap.parse_args(argv)
    if args.workers < 1 or any(s < 0 for s in args.seed) or (args.steps is not None and args.steps < 1):
        ap.error("--workers and --steps must be >= 1 and seeds >= 0")
    from frictiongym.agents.evaluation.engine import (  # start-up cost: after --help
        disk_error,
        run_interruptibly,
    )

    try:
        from frictiongym.agents.training import (  # the rl extra: a missing one is named, after --help
            NothingSelected,
            export_model,
            load_config,
            train_many,
        )
    except ModuleNotFoundError as e:
        print(missing_extra(e, "rl", "frictiongym train"), file=sys.stderr)
        return 2
    if args.sweep:
        return run_interruptibly(
            lambda: sweep(args),
            f"the trials' model folders so far are in {args.out}; rerunning starts the sweep anew",
        )
    if args.export:
        for run in args.export:
            print(export_model(run, args.out))
        return 0
    manifests: list = []

    def train() -> int:
        manifests.extend(
            train_many(
                [
                    c if args.steps is None else dataclasses.replace(c, total_timesteps=args.steps)
                    for c in load_config(args.config, args.scenario)
                ],
                args.seed,
                args.out,
                args.resume,
                args.workers,
            )
        )
        return 0

    try:
        code = run_interruptibly(
            train, f"the runs' checkpoints are in {args.out}; add --resume to the same command to continue"
        )
    except (ConfigError, FileExistsError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except OSError as e:
        print(disk_error(e, args.out), file=sys.stderr)
        return 1
    if code:
        return code
    for m in manifests:
        if isinstance(m, NothingSelected):
            print(f"no model: {m}")
            continue
        v = m["validation"]
        b = v["best_classical"]
        print(
            f"{m['name']:<24} {m['scenario']:<24} steps {m['steps']:>7} wall {m['wall_time_s']:>6.0f} s  "
            f"validation {v['main_metric']} {v['value']:.4g} (best classical {b['name']} {b['main']:.4g}), "
            f"effort_rms {v['effort_rms']:.4g} ({b['effort_rms']:.4g})"
        )
    return 0


def sweep(args: argparse.Namespace) -> int:
    """Run a sweep on Ray Tune and write DIR/<sweep>.csv (one row per trial)."""
    try:
        from frictiongym.agents.training.sweeps import METRIC, load_sweep, run_sweep  # the distributed extra
    except ModuleNotFoundError as e:
        print(missing_extra(e, "distributed", "frictiongym train --sweep"), file=sys.stderr)
        return 2

    try:
        s = load_sweep(args.sweep)
    except ConfigError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    rows = run_sweep(s, args.out, args.address, args.workers)
    args.out.mkdir(parents=True, exist_ok=True)
    fields = sorted({k for r in rows for k in r})
    rows = sorted(rows, key=lambda r: r[METRIC])
    atomic_text(args.out / f"{s.name}.csv", csv_text(rows, fields))
    for r in rows:
        print(", ".join(f"{k}={r[k]}" for k in fields if k != "folder"), r["folder"])
    return 0 if not any(r["error"] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
