"""Environment speed, measured side by side in one run on this machine:

- single env steps/s and its ratio to a bare "Python control + mj_step(nstep=substeps)" loop of the same model
  (target >= 70 %);
- vector env env-steps/s at 8 and 64 envs and the ratio to a bare mujoco.batch.Batch loop
  (target >= 80 % at 64);
- Gymnasium's InvertedPendulum-v5 steps/s, for scale.

The bare loops step the same physics as the env: they start from the env's initial state and start
again from it when an episode would end. (A fresh MjData at exact rest steps measurably faster than the
same model in an episode's state, ~1 µs of 27 µs on the M220, which is not the env's overhead.)

    frictiongym bench-envs [--scenarios kang_regulation ...] [--seconds 2]
                                 [--friction-models lugre maxwell_slip ...]
    frictiongym bench-envs --all-ids [--seconds 2]

With several friction structures (envs/friction.py), each scenario is measured on each of them, and the
env steps/s of every structure relative to LuGre's, on the same scenario in the same run.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from frictiongym.envs.friction import FRICTION_MODELS
from frictiongym.scripts.options import parser

if TYPE_CHECKING:  # start-up cost: --help imports no MuJoCo; the functions import what they time
    import gymnasium as gym
    import mujoco

    from frictiongym.envs.core import ServoCore


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


def bare_single(core: ServoCore) -> tuple[Callable[[], None], mujoco.MjData]:
    """The bare loop for a single env's core (after its reset): one step and the MjData it steps."""
    import mujoco

    model, start, data = core.model, mujoco.MjData(core.model), mujoco.MjData(core.model)
    mujoco.mj_copyData(start, model, core.backend.data)  # the env's state after its reset
    mujoco.mj_copyData(data, model, start)
    n, ctrl_i, dof, steps = core.sc.spec.substeps, core.idx.drive_ctrl, core.track_dof, core.sc.episode_steps
    k = 0

    def step() -> None:
        nonlocal k
        data.ctrl[ctrl_i] = -0.0 * data.qpos[dof]  # Python control law, then the physics
        mujoco.mj_step(model, data, n)
        k += 1
        if k == steps:
            k = 0
            mujoco.mj_copyData(data, model, start)

    return step, data


def bare_vector(core: ServoCore) -> tuple[Callable[[], None], np.ndarray]:
    """The bare loop for a vector env's core (after its reset): one step of a Batch of as many
    simulations, and the Batch's qpos."""
    import mujoco
    from mujoco.batch import Batch

    num_envs = core.n
    batch = Batch(core.model, num_envs)
    ctrl, qpos, qvel = batch.bind("ctrl"), batch.bind("qpos"), batch.bind("qvel")
    env_qpos, env_qvel, _, _ = core.backend.state()
    start_qpos, start_qvel = env_qpos.copy(), env_qvel.copy()  # the env's states after its reset
    n, ctrl_i, dof, steps = core.sc.spec.substeps, core.idx.drive_ctrl, core.track_dof, core.sc.episode_steps
    k = steps

    def step() -> None:
        nonlocal k
        if k == steps:  # as the env's reset: MuJoCo's reset, the initial state, forward
            k = 0
            batch.reset(stage=mujoco.mjtStage.mjSTAGE_NONE)
            qpos[:], qvel[:] = start_qpos, start_qvel
            batch.forward()
        ctrl[:, ctrl_i] = -0.0 * qpos[:, dof]
        batch.step(nstep=n)
        k += 1

    return step, qpos


def bench_single(scenario: str, seconds: float, overrides: dict | None = None) -> tuple[float, float]:
    from frictiongym.envs.servo_env import ServoEnv

    env = ServoEnv(scenario, overrides=overrides)
    env_step = stepper(env)  # resets with seed 0 first
    return paired(env_step, bare_single(env.core)[0], seconds)


def bench_vector(
    scenario: str, num_envs: int, seconds: float, overrides: dict | None = None
) -> tuple[float, float]:
    from frictiongym.envs.vector import ServoVectorEnv

    venv = ServoVectorEnv(scenario, num_envs, overrides=overrides)
    venv.reset(seed=0)
    actions = np.zeros((num_envs, 1), dtype=np.float32)
    return paired(lambda: venv.step(actions), bare_vector(venv.core)[0], seconds, num_envs)


def every_id(seconds: float) -> None:
    """The single env of every registered frictiongym id (a per-plant id runs its default scenario)
    against its bare loop, side by side, and how many reach 0.7 of it."""
    import gymnasium as gym

    import frictiongym.envs  # noqa: F401  (registers the ids)

    ids = sorted(i for i in gym.registry if i.startswith("frictiongym/"))
    print(f"{'id':44s} {'scenario':28s} {'env steps/s':>12s} {'bare steps/s':>13s} {'ratio':>6s}")
    met = 0
    for i in ids:
        scenario = gym.registry[i].scenario
        e, b = bench_single(scenario, seconds)
        met += e / b >= 0.7
        print(f"{i:44s} {scenario:28s} {e:12.0f} {b:13.0f} {e / b:6.2f}", flush=True)
    print(f"{met} of {len(ids)} ids at least 0.7 of their bare loop")


def main() -> None:
    ap = parser(__doc__)
    ap.add_argument(
        "--scenarios",
        nargs="*",
        default=["kang_regulation", "m220_regulation", "flexible_speed_step"],
        help="the scenarios whose envs are timed",
    )
    ap.add_argument("--seconds", type=float, default=4.0, help="measuring time per pair of figures")
    ap.add_argument(
        "--all-ids",
        action="store_true",
        help="the single env of every registered id against its bare loop (target >= 0.7), then stop",
    )
    ap.add_argument(
        "--friction-models",
        nargs="+",
        default=["lugre"],
        choices=FRICTION_MODELS,
        help="the friction structures",
    )
    args = ap.parse_args()
    if args.all_ids:
        every_id(args.seconds)
        return
    print(f"{'scenario':36s} {'what':10s} {'env steps/s':>12s} {'bare steps/s':>13s} {'ratio':>6s}")
    for sc in args.scenarios:
        lugre: dict[str, float] = {}
        for model in args.friction_models:
            ov = {"friction_model": model}
            name = sc if model == "lugre" else f"{sc} [{model}]"
            rows = [("single", bench_single(sc, args.seconds, ov))]
            rows += [(f"vector {n}", bench_vector(sc, n, args.seconds, ov)) for n in (8, 64)]
            for what, (e, b) in rows:
                vs = f"  {e / lugre[what]:5.2f}x LuGre's env steps/s" if what in lugre else ""
                print(f"{name:36s} {what:10s} {e:12.0f} {b:13.0f} {e / b:6.2f}{vs}")
                if model == "lugre":
                    lugre[what] = e
    try:
        import gymnasium as gym

        pstep = stepper(gym.make("InvertedPendulum-v5"))
        print(f"{'InvertedPendulum-v5':24s} {'single':10s} {rate(pstep, args.seconds):12.0f}")
    except Exception as err:  # Gymnasium's MuJoCo envs are optional
        print(f"InvertedPendulum-v5 unavailable: {err}")


if __name__ == "__main__":
    main()
