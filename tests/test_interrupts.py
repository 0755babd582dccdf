"""Real signals on a real pool: Ctrl-C (SIGINT to the process group, as a terminal sends it) and SIGTERM
stop a leaderboard within seconds, keep the finished rows, say how to resume and exit 128 + signal; a
SIGKILLed parent leaves no process behind. Resuming an interrupted run gives the clean run's file."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

psutil = pytest.importorskip("psutil")
pytestmark = pytest.mark.slow

SCRIPT = str(Path(__file__).parents[1] / "scripts" / "leaderboard.py")
# M220 point-to-point moves under PID (and Zero, always run): about 0.1 s per episode on 2 workers
SEEDS, RESUME_SEEDS = 150, 30  # 300 episodes (~30 s of work, several times what a stop may take); 60


def _args(seeds: int) -> list[str]:
    suite = ["--scenarios", "m220_point_to_point", "--seeds", f"1-{seeds}", "--randomize"]
    return [*suite, "--controllers", "PID", "--models", "--workers", "2"]


STOP_S = 8.0  # an interrupted run ends within this (the remaining work takes several times longer)


def _terminal_signals() -> None:
    """In the child before exec: SIGINT as a terminal's foreground job has it. A shell without job
    control starts background jobs with SIGINT ignored, and Python keeps an inherited SIG_IGN, so a
    test run launched with `&` would otherwise send Ctrl-C to processes that cannot receive it."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _rows(out: Path) -> int:
    f = out / "episodes.csv"
    return f.read_text().count("\n") - 1 if f.exists() else -1


def _start(out: Path, seeds: int = SEEDS) -> tuple[subprocess.Popen, list]:
    """The leaderboard in a session of its own, once its pool runs and a first chunk of rows is on disk;
    with the processes it started (pool workers, resource tracker)."""
    proc = subprocess.Popen(
        [sys.executable, SCRIPT, *_args(seeds), "--out", str(out)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        preexec_fn=_terminal_signals,
    )
    deadline = time.monotonic() + 180
    while _rows(out) < 1 and time.monotonic() < deadline:
        time.sleep(0.05)
    assert _rows(out) >= 1, "no row was written"
    return proc, psutil.Process(proc.pid).children(recursive=True)


def _gone(children: list, within_s: float) -> list:
    """The processes of `children` still alive after within_s seconds."""
    _, alive = psutil.wait_procs(children, timeout=within_s)
    return [p for p in alive if p.status() != psutil.STATUS_ZOMBIE]


@pytest.mark.parametrize(
    ("signum", "to_group"), [(signal.SIGINT, True), (signal.SIGTERM, False)], ids=["ctrl-c", "sigterm"]
)
def test_a_signal_stops_the_run_within_seconds_and_keeps_its_rows(tmp_path, signum, to_group):
    proc, children = _start(tmp_path / "run")
    assert len(children) >= 2  # the two pool workers (and the resource tracker)
    before, t0 = _rows(tmp_path / "run"), time.monotonic()
    (os.killpg if to_group else os.kill)(proc.pid, signum)
    _, err = proc.communicate(timeout=60)
    took = time.monotonic() - t0
    assert proc.returncode == 128 + signum, err
    assert took < STOP_S, f"took {took:.1f} s to stop"
    assert "rerun the same command to resume" in err and "episodes.csv" in err
    assert before <= _rows(tmp_path / "run") < 2 * SEEDS  # every finished row kept, the run not finished
    assert _gone(children, 5.0) == []


def test_a_killed_parent_leaves_no_process_behind(tmp_path):
    proc, children = _start(tmp_path / "run")
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert _gone(children, 10.0) == []


def test_an_interrupted_run_resumes_to_the_clean_runs_file(tmp_path):
    proc, _ = _start(tmp_path / "stopped", RESUME_SEEDS)
    os.killpg(proc.pid, signal.SIGINT)
    proc.communicate(timeout=60)
    assert _rows(tmp_path / "stopped") < 2 * RESUME_SEEDS
    for out in (tmp_path / "stopped", tmp_path / "clean"):
        args = [sys.executable, SCRIPT, *_args(RESUME_SEEDS), "--out", str(out)]
        run = subprocess.run(args, capture_output=True, timeout=600)
        assert run.returncode == 0, run.stderr
    stopped, clean = (tmp_path / d / "episodes.csv" for d in ("stopped", "clean"))
    assert stopped.read_bytes() == clean.read_bytes()


def test_ctrl_c_stops_parallel_training_and_leaves_no_worker(tmp_path):
    """Two training runs on training's own spawn pool: Ctrl-C to the group ends them within seconds,
    says how to continue (--resume) and leaves no worker behind."""
    script = str(Path(__file__).parents[1] / "scripts" / "train.py")
    config = ["--config", "residual_sac", "--scenario", "m220_reversal_tracking", "--seed", "0", "1"]
    proc = subprocess.Popen(
        [sys.executable, script, *config, "--workers", "2", "--out", str(tmp_path)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        preexec_fn=_terminal_signals,
    )
    deadline = time.monotonic() + 180  # until both runs have written something (their folders)
    while len(list(tmp_path.glob("*/*/*/*"))) < 2 and time.monotonic() < deadline:
        time.sleep(0.2)
    children = psutil.Process(proc.pid).children(recursive=True)
    assert len(children) >= 2
    t0 = time.monotonic()
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 128 + signal.SIGINT, err
    assert time.monotonic() - t0 < STOP_S
    assert "--resume" in err
    assert _gone(children, 5.0) == []


def test_ctrl_c_stops_a_sweep_on_ray_tune_and_leaves_no_process(tmp_path):
    """A training sweep on a local Ray (Tune would first wind its trials down on Ctrl-C; the suite stops
    at once, as everywhere): exit 130 within seconds, no Ray process left."""
    pytest.importorskip("ray")
    script = str(Path(__file__).parents[1] / "scripts" / "train.py")
    proc = subprocess.Popen(
        [sys.executable, script, "--sweep", "residual_sac_alpha", "--workers", "2", "--out", str(tmp_path)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        preexec_fn=_terminal_signals,
    )
    deadline = time.monotonic() + 240  # until a trial has started training (its model folder)
    while not list(tmp_path.glob("residual_sac_alpha/*/seed*")) and time.monotonic() < deadline:
        time.sleep(0.5)
    children = psutil.Process(proc.pid).children(recursive=True)
    assert children  # Ray's processes and the trials' workers
    t0 = time.monotonic()
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 128 + signal.SIGINT, err
    assert time.monotonic() - t0 < 2 * STOP_S  # Ray's shutdown takes a few seconds more than a pool's
    assert "interrupted (SIGINT)" in err
    assert _gone(children, 10.0) == []
