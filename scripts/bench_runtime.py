"""The cost of one control step of an exported controller (agents/deploy/runtime.py) against its plant's
control period: per committed model (numpy and onnxruntime networks) and per classical family, the runtime's
time per step (median, 99th percentile and maximum over --steps steps, one thread, this process on one
core), the step's readings a sine through the plant's range.

    frictiongym bench-runtime [--steps 100000] [--out out/bench_runtime.csv]

Prints one row per (controller, backend) with the times in µs and the share of the control period the
99th percentile takes; writes the rows as CSV.
"""

from __future__ import annotations

import math
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from frictiongym.envs.records import atomic_text, csv_text, missing_extra
from frictiongym.scripts.options import parser

CLASSICAL = {  # a classical family on a scenario of each plant it runs on
    "PID": "kang_ramp",
    "PID+FF": "m220_reversal_tracking",
    "LuGreObserver": "m220_random",
    "Southward": "kang_regulation",
    "RDFC": "kang_regulation",
    "SF+relay": "flexible_zero_speed",
    "LabPD": "emps_tracking",
    "SpeedScheduled": "m220_random",
    "PD": "kang_ramp",
    "CoulombViscousFF": "m220_reversal_tracking",
    "SF": "flexible_zero_speed",
    "SF+highgain": "flexible_zero_speed",
    "TaskScheduled": "kang_ramp",
    "SF+relay/residual-base": "flexible_speed_step",
}


def time_steps(runtime, steps: int) -> np.ndarray:
    """Seconds per step over `steps` steps of a sine reference, readings following it."""
    sc = runtime.scenario
    h, s, n = sc.control_period, sc.output_scale, len(sc.spec.sensors)
    out = np.empty(steps)
    runtime.reset()
    clock = time.perf_counter
    for k in range(steps):
        r = 0.5 * s * math.sin(2 * math.pi * 0.2 * k * h)
        preview = [
            0.5 * s * math.sin(2 * math.pi * 0.2 * (k + j) * h) for j in range(1, sc.preview_steps + 1)
        ]
        readings = [0.98 * r] * n
        t0 = clock()
        runtime.step(readings, r, preview)
        out[k] = clock() - t0
    return out


def main(argv: list[str] | None = None) -> int:
    ap = parser(__doc__)
    ap.add_argument("--steps", type=int, default=100_000, help="steps timed per controller and backend")
    ap.add_argument("--out", type=Path, default=Path("out/bench_runtime.csv"), help="the table (CSV)")
    args = ap.parse_args(argv)
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    try:
        from frictiongym.agents import registry  # the controllers
        from frictiongym.agents.deploy.runtime import Runtime, export  # onnx, onnxruntime: the deploy extra
    except ModuleNotFoundError as e:
        print(missing_extra(e, "deploy", "frictiongym bench-runtime"), file=sys.stderr)
        return 2
    jobs = [(name, scenario, "numpy") for name, scenario in CLASSICAL.items()]
    models = registry.committed_models(*registry.LEADERBOARD_GROUPS, "sim2real")
    jobs += [(str(m), None, backend) for m in models for backend in ("numpy", "onnxruntime")]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for source, scenario, backend in tqdm(jobs, desc="controllers", unit="controller"):
            art = export(source, Path(tmp) / f"{len(rows)}", scenario)
            rt = Runtime.load(art, backend=backend)
            t = time_steps(rt, args.steps) * 1e6
            period_us = rt.scenario.control_period * 1e6
            rows.append(
                {
                    "controller": Path(source).name if Path(source).is_dir() else source,
                    "backend": backend,
                    "scenario": rt.scenario.name,
                    "period_us": period_us,
                    "median_us": float(np.median(t)),
                    "p99_us": float(np.percentile(t, 99)),
                    "max_us": float(t.max()),
                    "p99_share_of_period": float(np.percentile(t, 99) / period_us),
                }
            )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    atomic_text(args.out, csv_text(rows))
    w = max(len(r["controller"]) for r in rows)
    print(f"{'controller':<{w}}  backend      period µs  median µs  p99 µs   max µs  p99/period")
    for r in rows:
        print(
            f"{r['controller']:<{w}}  {r['backend']:<11}  {r['period_us']:9.0f}  {r['median_us']:9.1f}  "
            f"{r['p99_us']:7.1f}  {r['max_us']:7.0f}  {r['p99_share_of_period']:10.4f}"
        )
    print(f"wrote {args.out} ({args.steps} steps each)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
