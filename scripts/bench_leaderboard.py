"""The leaderboard's evaluation speed: the full `default` suite (all scenarios x its episodes x all built-in
controllers and the reference rows Ideal and Oracle; no learned models) with 1 worker and with N workers,
with --ray on a local Ray with 1 and N workers, and with --models on N workers with the saved models of
those folders added (the default leaderboard's own run), measured side by side in one run.

    frictiongym bench-leaderboard [--workers 2] [--ray] [--no-serial]
        [--models agents/models/specialist agents/models/generalist]

Prints the physics floors first (the suite's physics steps per plant times a bare mj_step loop's time per
step: what no evaluation code can go below; without and with the models), then the wall time of each
run and its ratio to its floor (targets: the classical and reference rows at most 1.3x, the whole
default leaderboard with the models at most 1.4x), the speed-ups, the Ray backend's overhead against the
local pool (pool speed-up >= 1.7, Ray at most 15 % slower than the pool) and whether every
episodes.csv of the same controllers is byte-identical. The friction-free optimum's cache is off
(FRICTIONGYM_CACHE=off): every run solves the programs a first run solves, so no run reads another's.
"""

from __future__ import annotations

import os
import tempfile
import time
from collections import Counter
from pathlib import Path
from typing import TYPE_CHECKING

from frictiongym.scripts.options import parser

if TYPE_CHECKING:  # start-up cost: --help imports no MuJoCo or engine; the functions import what they run
    import mujoco

    from frictiongym.agents.evaluation import engine

PHYSICS_STEPS = 20000  # steps per timing of the bare mj_step loop (best of 5)


def physics_floor(workers: int, models: tuple[str, ...] = ()) -> float:
    """Print and return the default suite's bare mj_step time on `workers` cores (s), with the saved
    models of `models` among its controllers: per plant, the physics steps of every applicable
    (controller, episode) job times the best time per step of a bare mj_step loop of the plant's model."""
    import mujoco

    from frictiongym.agents import registry
    from frictiongym.agents.evaluation.evaluate import EnvCache
    from frictiongym.envs.suites import load_suite

    envs, steps, model = EnvCache(), Counter(), {}
    controllers = [registry.make(n, models) for n in registry.default_entries(models)]
    for e in load_suite("default"):
        sc = envs.scenario(e)
        jobs = sum(c.applies_to(sc) for c in controllers)
        steps[sc.spec.name] += jobs * sc.episode_steps * sc.spec.substeps
        model.setdefault(sc.spec.name, envs.env(controllers[0], e).core.model)
    total = 0.0
    what = f"with the models of {' '.join(models)}" if models else "classical and reference rows"
    for plant, n in steps.items():
        m = model[plant]
        d = mujoco.MjData(m)
        per_step = min(_timed_steps(m, d) for _ in range(5)) / PHYSICS_STEPS
        total += n * per_step
        cost = n * per_step
        print(f"physics floor {plant:15s} {n / 1e6:6.1f} M steps x {per_step * 1e6:.2f} us = {cost:6.1f} s")
    print(f"physics floor ({what}): {total:.1f} s of mj_step, {total / workers:.1f} s on {workers} cores")
    return total / workers


def _timed_steps(m: mujoco.MjModel, d: mujoco.MjData) -> float:
    import mujoco

    t0 = time.perf_counter()
    mujoco.mj_step(m, d, PHYSICS_STEPS)
    return time.perf_counter() - t0


def timed(
    workers: int, out: Path, ray: engine.Ray | None = None, models: tuple[str, ...] = ()
) -> tuple[float, int]:
    """Wall time of the default suite into out (for Ray: including the start of its local instance), with
    the saved models of `models` added to the built-in controllers."""
    from frictiongym.agents import registry
    from frictiongym.agents.evaluation import engine
    from frictiongym.envs.suites import load_suite

    episodes = load_suite("default")
    t0 = time.perf_counter()
    names = registry.default_entries(models)  # the built-ins, the references, then the models
    rows, _ = engine.evaluate_to(out, names, episodes, {"bench": 1}, workers, False, models, ray)
    return time.perf_counter() - t0, len(rows)


def main() -> None:
    ap = parser(__doc__)
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 2, help="processes of the pool runs")
    ap.add_argument("--ray", action="store_true", help="also the Ray backend (pip install -e .[distributed])")
    ap.add_argument("--models", nargs="+", default=[], help="also the suite with these saved-model folders")
    ap.add_argument("--no-serial", dest="serial", action="store_false", help="skip the 1-worker run")
    args = ap.parse_args()
    from frictiongym.agents.evaluation import engine, optimum

    os.environ[optimum.CACHE_VARIABLE] = optimum.CACHE_OFF  # inherited by the workers: no run reads another's

    floor = physics_floor(args.workers)
    floor_models = physics_floor(args.workers, tuple(args.models)) if args.models else 0.0
    with tempfile.TemporaryDirectory() as d:
        times = {"serial": timed(1, Path(d) / "serial")} if args.serial else {}
        times["pool"] = timed(args.workers, Path(d) / "pool")
        if args.models:
            learned = timed(args.workers, Path(d) / "models", models=tuple(args.models))
        if args.ray:
            import ray

            for name, n in (("ray1", 1), ("ray", args.workers)):
                times[name] = timed(n, Path(d) / name, engine.Ray())
                ray.shutdown()
        files = {k: (Path(d) / k / "episodes.csv").read_bytes() for k in times}
    n = times["pool"][1]
    print(f"default suite: {n} episodes (built-in controllers and the reference rows)")
    if args.serial:
        print(f"local, 1 worker:  {times['serial'][0]:6.1f} s")
        speedup = times["serial"][0] / times["pool"][0]
        print(f"local, {args.workers} workers: {times['pool'][0]:6.1f} s   speed-up {speedup:.2f}x")
    else:
        print(f"local, {args.workers} workers: {times['pool'][0]:6.1f} s")
    print(f"  {times['pool'][0] / floor:.2f}x its physics floor of {floor:.1f} s (target <= 1.3x)")
    if args.models:
        ratio = learned[0] / times["pool"][0]
        print(
            f"with the models of {' '.join(args.models)}: {learned[1]} episodes, {learned[0]:6.1f} s on "
            f"{args.workers} workers, {ratio:.2f}x the classical-only time"
        )
        whole = learned[0] / floor_models
        print(f"  {whole:.2f}x its physics floor of {floor_models:.1f} s (target <= 1.4x)")
    if args.ray:
        r1, r = times["ray1"][0], times["ray"][0]
        print(f"ray,   1 worker:  {r1:6.1f} s")
        print(f"ray,   {args.workers} workers: {r:6.1f} s   speed-up {r1 / r:.2f}x")
        print(f"Ray overhead vs the local pool ({args.workers} workers): {r / times['pool'][0] - 1:+.1%}")
    print(f"episodes.csv identical: {len(set(files.values())) == 1} ({', '.join(files)})")


if __name__ == "__main__":
    main()
