"""The leaderboard ranks controllers on identical episodes and writes its files."""

import csv
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from frictiongym.agents import leaderboard

ROOT = Path(__file__).parents[1]


def test_bootstrap_interval_brackets_the_mean_and_is_reproducible():
    x = np.array([1.0, 2.0, 3.0, 4.0, 10.0])
    m, lo, hi = leaderboard.bootstrap_ci(x)
    assert m == pytest.approx(4.0) and lo < m < hi
    assert leaderboard.bootstrap_ci(x) == (m, lo, hi)
    assert leaderboard.bootstrap_ci(np.array([np.nan, 2.0])) == (2.0, 2.0, 2.0)


def test_same_episodes_for_every_controller_and_sorted_table():
    results, table = leaderboard.run("paper", ["PD", "RDFC"], out=None, progress=False)
    kang = [r for r in results if r.scenario == "kang_regulation"]
    assert {r.controller for r in kang} == {"PD", "RDFC"} and {r.seed for r in kang} == {0}
    rows = table["kang_regulation"]
    assert [r["controller"] for r in rows] == ["RDFC", "PD"]  # sorted by IAE: RDFC removes the PD error
    assert "flexible_speed_step" not in table  # neither controller applies there


def test_unknown_controller_is_a_clear_error():
    with pytest.raises(ValueError, match="unknown controllers"):
        leaderboard.run("paper", ["LQG"], out=None, progress=False)


def test_script_writes_markdown_csv_and_plots(tmp_path):
    proc = subprocess.run(
        [
            sys.executable,
            str(ROOT / "scripts/leaderboard.py"),
            "--suite",
            "paper",
            "--controllers",
            "PD",
            "PID",
            "--out",
            str(tmp_path),
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    assert "## kang_regulation" in proc.stdout
    rows = list(csv.DictReader((tmp_path / "leaderboard.csv").read_text().splitlines()))
    assert {r["controller"] for r in rows} == {"PD", "PID"}
    episodes = list(csv.DictReader((tmp_path / "episodes.csv").read_text().splitlines()))
    assert {(r["controller"], r["scenario"]) for r in episodes} >= {
        ("PD", "kang_regulation"),
        ("PID", "m220_regulation"),
    }
    assert (tmp_path / "leaderboard.md").read_text().startswith("# frictiongym leaderboard")
    assert (tmp_path / "bar_iae.png").stat().st_size > 5000
    assert (tmp_path / "response_kang_regulation.png").stat().st_size > 5000
