"""The command-line front ends run and write what they promise."""

import json
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest
from conftest import load_script

from frictiongym.agents import reproduce
from frictiongym.envs.servo_env import ServoEnv
from frictiongym.envs.vector import ServoVectorEnv

ROOT = Path(__file__).parents[1]
REQUIRED = [
    "m220.reflected_inertia.default",
    "m220.step_id.a",
    "m220.step_id.k",
    "flexible.G1.1Hz.lin.mag",
    "flexible.G2.10Hz.sine.phase_deg",
    "kang.theta_H_deg",
    "kang.theta_L_deg",
    "kang.pd.final_error_deg",
    "kang.southward.amp_deg.20ms",
    "kang.rdfc.0.02.cycles",
    "wallenborg.gains.digital_wcl12_y1",
    "wallenborg.regulator_stability_limit",
    "wallenborg.nyquist_crossing",
    "wallenborg.df_amplitude",
    "wallenborg.limit_cycle.wcl12_y1_highgain.amp_v",
]


@pytest.mark.slow
def test_reproduce_writes_passing_report(tmp_path):
    """Every section but `friction` (its rows are the Radau comparisons tests/test_friction.py and
    tests/test_structures.py run on the same functions; it alone takes about 70 s) passes, and the report
    and figures are written."""
    out = tmp_path / "rep"
    sections = [s for s in reproduce.section_names() if s != "friction"]
    proc = subprocess.run(
        [sys.executable, str(ROOT / "scripts/reproduce.py"), "--out", str(out), "--sections", *sections],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    rows = json.loads((out / "report.json").read_text())
    ids = {r["id"] for r in rows}
    assert set(REQUIRED) <= ids
    assert all(set(r) >= {"id", "document", "simulated", "tolerance", "pass"} for r in rows)
    assert all(r["pass"] for r in rows)
    assert (out / "report.md").read_text().startswith("# frictiongym reproduction report")
    assert (out / "m220_step.png").stat().st_size > 10_000 and (
        out / "flexible_bode.png"
    ).stat().st_size > 10_000


@pytest.mark.slow  # a benchmark
def test_bench_physics_prints_a_ratio_per_plant():
    proc = subprocess.run(
        [sys.executable, str(ROOT / "scripts/bench_physics.py"), "--seconds", "0.2"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.strip().splitlines()[1:]
    assert {ln.split()[0] for ln in lines} == {"kang_robot", "flexible_servo", "m220", "emps"}
    assert all(0.1 < float(ln.split()[-1]) < 10 for ln in lines)


@pytest.mark.slow  # two small leaderboards
def test_bench_versions_times_both_versions_and_removes_its_worktree():
    """Both versions run the same small leaderboard, each time is printed and the ratio of the medians;
    the other version's temporary worktree is gone afterwards."""
    worktrees = ["git", "-C", str(ROOT), "worktree", "list"]
    before = subprocess.run(worktrees, capture_output=True, text=True).stdout
    args = ["--scenarios", "kang_regulation", "--seeds", "5000", "--controllers", "PD", "--models"]
    args += ["--workers", "1"]
    proc = subprocess.run(
        [sys.executable, "-m", "frictiongym.scripts.cli", "bench-versions", "--against", "HEAD", "--", *args],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.strip().splitlines()
    assert lines[0].startswith("round 1: this checkout: ") and lines[1].startswith("round 1: HEAD: ")
    times = [float(ln.split(": ")[-1].removesuffix(" s")) for ln in lines[:2]]
    assert lines[2].startswith(f"median: this checkout {times[0]:.1f} s, HEAD {times[1]:.1f} s: ")
    assert float(lines[2].split(": ")[-1].removesuffix("x")) == pytest.approx(times[0] / times[1], abs=0.03)
    assert subprocess.run(worktrees, capture_output=True, text=True).stdout == before


@pytest.mark.parametrize("scenario", ["m220_regulation", "kang_regulation", "flexible_speed_step"])
def test_bench_envs_bare_loops_step_the_envs_physics(scenario):
    """The speed ratios compare like with like: with a zero action, the bare loops (single and Batch)
    follow the env's own trajectory bit for bit, from the env's initial state."""
    bench = load_script("bench_envs")
    env = ServoEnv(scenario)
    env.reset(seed=0)
    bare, data = bench.bare_single(env.core)
    venv = ServoVectorEnv(scenario, 3)
    venv.reset(seed=0)
    vbare, vqpos = bench.bare_vector(venv.core)
    for _ in range(25):
        env.step(np.zeros(1, dtype=np.float32))
        bare()
        venv.step(np.zeros((3, 1), dtype=np.float32))
        vbare()
    assert np.array_equal(data.qpos, env.core.backend.data.qpos)
    assert np.array_equal(vqpos, venv.core.backend.state()[0])
    assert not np.array_equal(data.qpos, mujoco.MjData(env.core.model).qpos)  # not a plant at rest


@pytest.mark.slow  # a benchmark
def test_bench_envs_prints_ratios():
    proc = subprocess.run(
        [
            sys.executable,
            str(ROOT / "scripts/bench_envs.py"),
            "--scenarios",
            "kang_regulation",
            "--seconds",
            "0.3",
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    rows = [ln.split() for ln in proc.stdout.splitlines()[1:] if ln.startswith("kang_regulation")]
    assert [r[1:-3] for r in rows] == [["single"], ["vector", "8"], ["vector", "64"]]
    assert all(0.05 < float(r[-1]) < 2 for r in rows)


@pytest.mark.slow  # a benchmark of 44 envs
def test_bench_envs_measures_every_registered_id():
    """--all-ids: one line per registered id with its scenario and ratio, then how many reach 0.7."""
    import gymnasium as gym

    proc = subprocess.run(
        [sys.executable, str(ROOT / "scripts/bench_envs.py"), "--all-ids", "--seconds", "0.05"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    ids = sorted(i for i in gym.registry if i.startswith("frictiongym/"))
    lines = proc.stdout.splitlines()
    assert [ln.split()[0] for ln in lines[1:-1]] == ids
    assert all(0.05 < float(ln.split()[-1]) < 2 for ln in lines[1:-1])
    assert lines[-1].endswith(f"of {len(ids)} ids at least 0.7 of their bare loop")


@pytest.mark.slow  # fresh interpreters
def test_the_frictiongym_command_is_installed_and_runs_a_front_end(tmp_path):
    """The console script (setup.cfg) runs scripts/reproduce.py's main: its usage names the command and a
    section runs and writes its report, as `python scripts/reproduce.py` does."""
    import shutil

    exe = shutil.which("frictiongym")
    assert exe is not None, "pip install -e . puts the frictiongym command on PATH"
    out = subprocess.run([exe, "reproduce", "--help"], capture_output=True, text=True, check=True).stdout
    assert out.startswith("usage: frictiongym reproduce")
    subprocess.run([exe, "reproduce", "--sections", "kang", "--out", str(tmp_path)], check=True)
    rows = json.loads((tmp_path / "report.json").read_text())
    assert rows and all(r["id"].startswith("kang.") and r["pass"] for r in rows)


def test_the_frictiongym_command_lists_every_front_end_and_refuses_unknown_ones(capsys):
    from frictiongym.scripts import cli

    assert cli.main(["--help"]) == 0
    listed = capsys.readouterr().out
    for command, module in cli.COMMANDS.items():
        assert f"  {command} " in listed
        assert (ROOT / "scripts" / f"{module}.py").is_file()
    scripts = {p.stem for p in (ROOT / "scripts").glob("*.py")} - {"__init__", "cli", "options"}
    assert scripts == set(cli.COMMANDS.values())  # every front end has its command
    assert cli.main(["leaderbord"]) == 2
    assert "unknown command 'leaderbord'" in capsys.readouterr().err
    assert cli.main([]) == 2


@pytest.mark.slow
def test_check_draws_script_reports_zero_rejections():
    proc = subprocess.run(
        [sys.executable, str(ROOT / "scripts/check_draws.py"), "--seeds", "300", "--workers", "1"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    rows = [ln.split() for ln in proc.stdout.splitlines()[1:]]
    assert {r[1] for r in rows} >= {"kang_robot", "m220", "flexible_servo", "kang_regulation"}
    assert all(r[2:4] == ["300", "0"] for r in rows)


def test_a_dangling_out_link_is_one_line_naming_the_path(tmp_path, capsys):
    """--out a symbolic link to nowhere: the leaderboard stops with one line naming the path (rc 1), no
    traceback."""
    out = tmp_path / "out"
    out.symlink_to(tmp_path / "missing" / "deeper")
    args = ["--scenarios", "kang_regulation", "--seeds", "5000", "--workers", "1", "--controllers", "PD"]
    assert load_script("leaderboard").main([*args, "--out", str(out)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and str(out) in err[0], err


def test_a_finished_run_is_reported_from_read_only_results(tmp_path, capsys):
    """--report-from DIR writes a finished run's report elsewhere and writes nothing into DIR (here made
    read-only); an unfinished run is refused, naming what is missing."""
    import stat

    board = load_script("leaderboard").main
    args = ["--scenarios", "kang_regulation", "--seeds", "5000", "--workers", "1", "--controllers", "PD"]
    run = tmp_path / "run"
    assert board([*args, "--models", "--out", str(run)]) == 0
    before = {p: p.read_bytes() for p in run.iterdir() if p.is_file()}
    for p in [run, *run.iterdir()]:
        p.chmod(p.stat().st_mode & ~(stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH))
    try:  # (root ignores the mode bits: the folder's bytes are compared below all the same)
        assert board(["--report-from", str(run), "--out", str(tmp_path / "report")]) == 0
    finally:
        for p in [run, *run.iterdir()]:
            p.chmod(p.stat().st_mode | stat.S_IWUSR)
    assert {p: p.read_bytes() for p in run.iterdir() if p.is_file()} == before
    assert (tmp_path / "report" / "leaderboard.md").read_text() == (run / "leaderboard.md").read_text()
    lines = (run / "episodes.csv").read_text().splitlines(keepends=True)
    (run / "episodes.csv").write_text("".join(lines[:-1]))
    capsys.readouterr()
    assert board(["--report-from", str(run), "--out", str(tmp_path / "again")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "1 of" in err[0] and "episodes missing" in err[0] and "resume it first" in err[0]


def test_a_full_disk_ends_in_one_line_and_keeps_whole_rows(tmp_path, capsys, monkeypatch):
    """ENOSPC while episode rows are appended: one line naming the error and the folder (rc 1), and
    episodes.csv holds whole rows only (a rerun resumes from them)."""
    import errno

    from frictiongym.agents.evaluation import engine

    real, calls = engine.os.write, []

    def write(fd, data):  # the second chunk finds the disk full after writing half of itself
        calls.append(len(data))
        if len(calls) == 2:
            real(fd, bytes(data[: len(data) // 2]))
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(fd, data)

    monkeypatch.setattr(engine.os, "write", write)
    out = tmp_path / "out"
    args = ["--scenarios", "kang_regulation", "--seeds", "5000-5001", "--workers", "1", "--controllers", "PD"]
    assert load_script("leaderboard").main([*args, "--models", "--out", str(out)]) == 1
    err = [line for line in capsys.readouterr().err.replace("\r", "\n").splitlines() if "error" in line]
    assert len(err) == 1 and "No space left on device" in err[0] and str(out) in err[0], err  # the bar aside
    monkeypatch.setattr(engine.os, "write", real)
    assert load_script("leaderboard").main([*args, "--models", "--out", str(out)]) == 0
    lines = (out / "episodes.csv").read_text().splitlines()
    assert len(lines) == 1 + len({tuple(x.split(",")[:3]) for x in lines[1:]})  # no torn or repeated row
