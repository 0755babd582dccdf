"""Render one frame of each plant as a PNG (the docs' pictures): the plant's default scenario, reset on a
seed, a few control periods of a constant command (so that the parts have moved), then the top camera
(640 x 480). A machine without a display needs an offscreen OpenGL, chosen before MuJoCo is imported:

    MUJOCO_GL=egl frictiongym render [--out docs/_static/frames] [--seed 0] [--steps 10] [--action 0.3]

Writes OUT/<plant>.png for m220, flexible_servo, kang_robot and emps, and OUT/plants.png, the four side by
side (the README's picture).
"""

from __future__ import annotations

import sys
from pathlib import Path

import gymnasium as gym
import numpy as np

import frictiongym.envs
from frictiongym.envs.config import ConfigError
from frictiongym.envs.records import atomic_write, pyplot
from frictiongym.scripts.options import parser


def render_frames(out: Path, seed: int = 0, steps: int = 10, action: float = 0.3) -> list[Path]:
    """One PNG per plant into out/ (atomically); the paths written."""
    import matplotlib.image  # start-up cost: --help imports no matplotlib

    from frictiongym.agents.figures import save_figure

    out.mkdir(parents=True, exist_ok=True)
    written, frames = [], {}
    for env_id in frictiongym.envs.ENV_IDS:
        env = gym.make(env_id, render_mode="rgb_array")
        try:
            scenario = env.unwrapped.scenario
            env.reset(seed=seed)
            for _ in range(steps):
                env.step(np.array([action], dtype=np.float32))
            frame = env.render()
        finally:
            env.close()
        path = out / f"{scenario.spec.name}.png"
        atomic_write(path, lambda p, f=frame: matplotlib.image.imsave(p, f, format="png"))
        written.append(path)
        frames[env_id] = frame
    fig, ax = pyplot().subplots(1, len(frames), figsize=(3.2 * len(frames), 2.9))
    for a, (env_id, frame) in zip(ax, frames.items(), strict=True):
        a.imshow(frame)
        a.set_title(env_id.removeprefix("frictiongym/"), fontsize=10)
        a.axis("off")
    written.append(out / save_figure(fig, out, "plants.png", dpi=100))
    return written


def main(argv: list[str] | None = None) -> int:
    ap = parser(__doc__)
    ap.add_argument("--out", type=Path, default=Path("docs/_static/frames"), help="folder of the PNGs")
    ap.add_argument("--seed", type=int, default=0, help="the episode's seed")
    ap.add_argument("--steps", type=int, default=10, help="control periods before the frame")
    ap.add_argument("--action", type=float, default=0.3, help="the constant action meanwhile, in [-1, 1]")
    args = ap.parse_args(argv)
    try:
        for p in render_frames(args.out, args.seed, args.steps, args.action):
            print(p)
    except (ConfigError, ValueError, OSError, RuntimeError) as e:
        print(f"frictiongym render: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
