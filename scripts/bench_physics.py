"""Physics speed per plant: steps/s of the full model (LuGre friction, delay buffer) and its ratio to a
bare mj_step(nstep) loop of the same model with friction removed, measured side by side in one run.

    frictiongym bench-physics [--seconds 1.0]
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

from frictiongym.envs.config import plant_names
from frictiongym.scripts.options import parser

if TYPE_CHECKING:
    import mujoco


def steps_per_second(model: mujoco.MjModel, seconds: float, nstep: int = 1000) -> float:
    """Best of 5 repetitions of mj_step(nstep) calls lasting ~seconds/5 each."""
    import mujoco

    data = mujoco.MjData(model)
    best = 0.0
    for _ in range(5):
        n, t0 = 0, time.perf_counter()
        while time.perf_counter() - t0 < seconds / 5:
            mujoco.mj_step(model, data, nstep)
            n += nstep
        best = max(best, n / (time.perf_counter() - t0))
    return best


def main() -> None:
    ap = parser(__doc__)
    ap.add_argument("--seconds", type=float, default=1.0, help="measuring time per model")
    args = ap.parse_args()
    import mujoco  # start-up cost: --help imports no MuJoCo

    from frictiongym.envs.plants import plant_spec
    from frictiongym.envs.plants.mjcf import to_mjcf

    print(f"{'plant':16s} {'full steps/s':>14s} {'bare steps/s':>14s} {'ratio':>7s}")
    for name in plant_names():
        full = mujoco.MjModel.from_xml_string(to_mjcf(plant_spec(name)))
        bare = mujoco.MjModel.from_xml_string(to_mjcf(plant_spec(name, friction_model="none")))
        # interleave to share machine conditions
        f1, b1 = steps_per_second(full, args.seconds / 2), steps_per_second(bare, args.seconds / 2)
        f2, b2 = steps_per_second(full, args.seconds / 2), steps_per_second(bare, args.seconds / 2)
        f, b = max(f1, f2), max(b1, b2)
        print(f"{name:16s} {f:14.3e} {b:14.3e} {f / b:7.2f}")


if __name__ == "__main__":
    main()
