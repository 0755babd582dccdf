"""Environment speed, measured side by side in one run on this machine:

- single env steps/s and its ratio to a bare "Python control + mj_step(nstep=substeps)" loop of the same model
  (target >= 70 %);
- vector env env-steps/s at 8 and 64 envs and the ratio to a bare mujoco.batch.Batch loop
  (target >= 80 % at 64);
- Gymnasium's InvertedPendulum-v5 steps/s, for scale.

    python scripts/bench_envs.py [--scenario kang_regulation] [--seconds 2]
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import gymnasium as gym
import mujoco
import numpy as np
from mujoco.batch import Batch

import frictiongym.envs  # noqa: F401
from frictiongym.envs.servo_env import ServoEnv
from frictiongym.envs.vector import ServoVectorEnv


def _once(fn: Callable[[], None], seconds: float) -> float:
    n, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        fn()
        n += 1
    return n / (time.perf_counter() - t0)


def rate(fn: Callable[[], None], seconds: float, per_call: int = 1) -> float:
    """Best of 3 runs of ~seconds/3: calls of fn per second times per_call."""
    return max(_once(fn, seconds / 3) for _ in range(3)) * per_call


def paired(
    fa: Callable[[], None], fb: Callable[[], None], seconds: float, per_call: int = 1, rounds: int = 8
) -> tuple[float, float]:
    """Rates of fa and fb measured in alternating short rounds (so both see the same machine
    conditions), best round of each, times per_call."""
    a = b = 0.0
    for _ in range(rounds):
        a = max(a, _once(fa, seconds / (2 * rounds)))
        b = max(b, _once(fb, seconds / (2 * rounds)))
    return a * per_call, b * per_call


def stepper(env: gym.Env) -> Callable[[], None]:
    """One env step with a zero action, resetting at the end of an episode."""
    env.reset(seed=0)
    action = np.zeros(1, dtype=np.float32)

    def step() -> None:
        _, _, term, trunc, _ = env.step(action)
        if term or trunc:
            env.reset()

    return step


def bench_single(scenario: str, seconds: float) -> tuple[float, float]:
    env = ServoEnv(scenario)
    env_step = stepper(env)

    core = env.core
    model, data = core.model, mujoco.MjData(core.model)
    n, ctrl_i, dof = core.sc.spec.substeps, core.idx.drive_ctrl, core.track_dof

    def bare_step() -> None:
        data.ctrl[ctrl_i] = -0.0 * data.qpos[dof]  # Python control law, then the physics
        mujoco.mj_step(model, data, n)

    return paired(env_step, bare_step, seconds)


def bench_vector(scenario: str, num_envs: int, seconds: float) -> tuple[float, float]:
    venv = ServoVectorEnv(scenario, num_envs)
    venv.reset(seed=0)
    actions = np.zeros((num_envs, 1), dtype=np.float32)
    core = venv.core
    batch = Batch(core.model, num_envs)
    ctrl, qpos = batch.bind("ctrl"), batch.bind("qpos")
    n, ctrl_i, dof = core.sc.spec.substeps, core.idx.drive_ctrl, core.track_dof

    def bare() -> None:
        ctrl[:, ctrl_i] = -0.0 * qpos[:, dof]
        batch.step(nstep=n)

    return paired(lambda: venv.step(actions), bare, seconds, num_envs)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument(
        "--scenarios", nargs="*", default=["kang_regulation", "m220_regulation", "flexible_speed_step"]
    )
    ap.add_argument("--seconds", type=float, default=4.0, help="measuring time per pair of figures")
    args = ap.parse_args()
    print(f"{'scenario':24s} {'what':10s} {'env steps/s':>12s} {'bare steps/s':>13s} {'ratio':>6s}")
    for sc in args.scenarios:
        e, b = bench_single(sc, args.seconds)
        print(f"{sc:24s} {'single':10s} {e:12.0f} {b:13.0f} {e / b:6.2f}")
        for n in (8, 64):
            e, b = bench_vector(sc, n, args.seconds)
            print(f"{sc:24s} {f'vector {n}':10s} {e:12.0f} {b:13.0f} {e / b:6.2f}")
    try:
        pstep = stepper(gym.make("InvertedPendulum-v5"))
        print(f"{'InvertedPendulum-v5':24s} {'single':10s} {rate(pstep, args.seconds):12.0f}")
    except Exception as err:  # Gymnasium's MuJoCo envs are optional
        print(f"InvertedPendulum-v5 unavailable: {err}")


if __name__ == "__main__":
    main()
