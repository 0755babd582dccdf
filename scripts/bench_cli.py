"""Time how long `frictiongym --help` and every command's `--help` take to answer, each in a fresh
process as a user types it (best of --repeat runs), and say which heavy module any of them imports.

    frictiongym bench-cli [--repeat 3]

Target: under 1 s each on a quiet 2-core machine; a help imports none of MuJoCo, torch,
stable-baselines3 or Ray (tests/test_cli.py checks the imports).
"""

from __future__ import annotations

import subprocess
import sys
import time

from frictiongym.scripts.cli import COMMANDS
from frictiongym.scripts.options import parser

HEAVY = ("mujoco", "torch", "stable_baselines3", "ray", "jax", "onnxruntime")
# Runs the command's --help in this process after the interpreter starts, then names the heavy modules it
# imported (stdout: one line, comma-separated).
PROBE = """
import contextlib, io, sys
from frictiongym.scripts.cli import main
with contextlib.redirect_stdout(io.StringIO()):
    try:
        main(sys.argv[1:])
    except SystemExit:
        pass
print(",".join(m for m in sys.argv[0].split(",") if m in sys.modules))
"""


def heavy_imports(argv: list[str]) -> list[str]:
    """The heavy modules (HEAVY) a fresh interpreter has imported after running `frictiongym *argv`."""
    out = subprocess.run(
        [sys.executable, "-c", PROBE.replace("sys.argv[0]", repr(",".join(HEAVY))), *argv],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    return [m for m in out.split(",") if m]


def help_time(argv: list[str], repeat: int) -> float:
    """Best wall time (s) of a fresh `python -m frictiongym.scripts.cli *argv` over `repeat` runs."""
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        subprocess.run(
            [sys.executable, "-m", "frictiongym.scripts.cli", *argv], capture_output=True, check=False
        )
        best = min(best, time.perf_counter() - t0)
    return best


def main(argv: list[str] | None = None) -> int:
    ap = parser(__doc__)
    ap.add_argument("--repeat", type=int, default=3, help="runs per command (the best is printed)")
    args = ap.parse_args(argv)
    if args.repeat < 1:
        ap.error("--repeat must be >= 1")
    rows = [("frictiongym --help", ["--help"])] + [
        (f"frictiongym {c} --help", [c, "--help"]) for c in COMMANDS
    ]
    worst = 0.0
    for label, cmd in rows:
        t, heavy = help_time(cmd, args.repeat), heavy_imports(cmd)
        worst = max(worst, t)
        print(f"{label:42s} {t:6.2f} s  {'imports ' + ', '.join(heavy) if heavy else ''}")
    print(f"slowest: {worst:.2f} s (target < 1 s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
