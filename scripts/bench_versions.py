"""The leaderboard's wall time at this checkout against another commit's, side by side in one run: the two
versions' `frictiongym leaderboard` with the same arguments, in turn, each in a fresh folder, for
--rounds rounds, then each version's median and their ratio.

    frictiongym bench-versions --against 1be9b27 [--rounds 1] -- --suite default --workers 2

The other commit is checked out into a temporary git worktree and imported from there (its own configs
and committed models: a relative path in the arguments is each version's own); the worktree is removed
at the end. The friction-free optimum's cache is off (FRICTIONGYM_CACHE=off): each run pays what a first
run pays. Run it on a quiet machine: the two versions share it in turn, never at once.
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from frictiongym.scripts.options import parser

ROOT = Path(__file__).resolve().parents[1]  # this checkout (setup.cfg's package_dir maps it)
PACKAGES = ("envs", "agents", "configs", "scripts")


def checkout(commit: str, where: Path) -> tuple[Path, Path]:
    """(the commit's tree, a folder to put on PYTHONPATH that imports it as frictiongym)."""
    tree = where / "tree"
    subprocess.run(
        ["git", "-C", str(ROOT), "worktree", "add", "--detach", "--quiet", str(tree), commit],
        check=True,
    )
    path = where / "path" / "frictiongym"
    path.mkdir(parents=True)
    for p in PACKAGES:
        (path / p).symlink_to(tree / p, target_is_directory=True)
    return tree, path.parent


def timed(args: list[str], cwd: Path, out: Path, pythonpath: Path | None) -> float:
    """Wall time (s) of `frictiongym leaderboard *args --out out` run from cwd."""
    # here, not at the top: --help imports no MuJoCo (the optimum's module imports the engine's)
    from frictiongym.agents.evaluation.optimum import CACHE_OFF, CACHE_VARIABLE

    env = {**os.environ, CACHE_VARIABLE: CACHE_OFF}  # no version reads programs another run solved
    if pythonpath is not None:
        env["PYTHONPATH"] = str(pythonpath)
    cmd = [sys.executable, "-m", "frictiongym.scripts.cli", "leaderboard", *args, "--out", str(out)]
    start = time.perf_counter()
    done = subprocess.run(cmd, cwd=cwd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if done.returncode != 0:
        last = (done.stderr.strip().splitlines() or ["no message"])[-1]
        raise SystemExit(f"bench-versions: the leaderboard in {cwd} failed: {last}")
    return time.perf_counter() - start


def main(argv: list[str] | None = None) -> int:
    ap = parser(__doc__)
    ap.add_argument("--against", required=True, help="the commit to compare with (e.g. a hash or HEAD~3)")
    ap.add_argument("--rounds", type=int, default=1, help="runs of each version, alternating")
    ap.add_argument("args", nargs="*", help="the leaderboard's arguments, after --")
    a = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        where = Path(tmp)
        tree, path = checkout(a.against, where)
        try:
            times: dict[str, list[float]] = {"this checkout": [], a.against: []}
            for r in range(a.rounds):
                for i, (name, cwd, pp) in enumerate((("this checkout", ROOT, None), (a.against, tree, path))):
                    t = timed(a.args, cwd, where / f"out-{i}-{r}", pp)
                    times[name].append(t)
                    print(f"round {r + 1}: {name}: {t:.1f} s", flush=True)
            new, old = (statistics.median(v) for v in times.values())
            print(f"median: this checkout {new:.1f} s, {a.against} {old:.1f} s: {new / old:.2f}x")
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(tree)], check=False)
    return 0


if __name__ == "__main__":
    sys.exit(main())
