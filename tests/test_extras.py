"""Without the optional extras (stable-baselines3, sb3-contrib, torch, rl-zoo: blocked from import in a
subprocess, as on a plain `pip install .`): every sub-command's --help works, a command that needs an
extra ends in one line naming it and the install command, and the leaderboard runs the committed learned
models (numpy layers from policy.safetensors: no torch)."""

from __future__ import annotations

import csv
import subprocess
import sys

import pytest

from frictiongym.scripts.cli import COMMANDS

BLOCK = """
import sys
BLOCKED = {"stable_baselines3", "sb3_contrib", "torch", "rl_zoo3", "sbx", "tensorboard"}
class Block:
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in BLOCKED:
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
        return None
sys.meta_path.insert(0, Block())
from frictiongym.scripts.cli import main
sys.exit(main(sys.argv[1:]))
"""


def without_extras(*args: str, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", BLOCK, *args], capture_output=True, text=True, timeout=timeout
    )


@pytest.mark.parametrize("command", list(COMMANDS))
def test_every_sub_command_s_help_works_without_the_extras(command):
    p = without_extras(command, "--help")
    assert p.returncode == 0 and p.stdout.startswith("usage: frictiongym"), p.stderr[-500:]


@pytest.mark.slow  # fresh interpreters
@pytest.mark.parametrize(
    ("args", "extra"),
    [
        (["train", "--config", "residual_sac"], "rl"),
        (["zoo", "validate", "--algo", "sac", "--env", "frictiongym/KangRobot-Regulation-v1"], "rl,zoo"),
        (["zoo", "train", "--algo", "sac"], "rl,zoo"),
        (["bench-training", "residual_sac", "--scenario", "kang_regulation"], "rl"),
    ],
)
def test_a_command_that_needs_an_extra_names_it_in_one_line(args, extra):
    p = without_extras(*args)
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1, p.stderr[-800:]
    assert f"needs the {extra} extra" in lines[0] and f"[{extra}]" in lines[0] and "pip install" in lines[0]


@pytest.mark.slow  # fresh interpreters
def test_the_leaderboard_runs_the_committed_learned_models_without_torch(tmp_path):
    out = tmp_path / "lb"
    p = without_extras(
        "leaderboard",
        "--scenarios",
        "kang_regulation",
        "--seeds",
        "5000",
        "--workers",
        "1",
        "--out",
        str(out),
        "--no-judging",
    )
    assert p.returncode == 0, p.stderr[-800:]
    learned = {r["controller"] for r in csv.DictReader((out / "episodes.csv").open())} & {
        "ResSAC-kang_regulation-s0",
        "GenSAC-kang-ff-kang_random-s0",
    }
    assert len(learned) == 2
