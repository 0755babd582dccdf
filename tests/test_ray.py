"""The Ray backend (issue: scale out): the same jobs as the local pool, the same rows bit for bit, a killed
worker's job retried without loss or duplicates, a killed driver resumed from episodes.csv. Local Ray with
2 worker processes; skipped without `pip install -e .[distributed]`."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # starts a local Ray
ray = pytest.importorskip("ray")
psutil = pytest.importorskip("psutil")

from frictiongym.agents.evaluation import engine  # noqa: E402
from frictiongym.envs.suites import Episode  # noqa: E402

ROOT = Path(__file__).parents[1]
CONTROLLERS = ["Zero", "PID", "PD"]
EPISODES = [Episode("flexible_speed_step_fast", s, True) for s in range(1, 7)]
OPTIONS = {"test": "ray"}


@pytest.fixture(scope="module")
def local_ray():
    engine.ray_init(2, None)  # a local Ray instance with 2 worker processes
    yield
    ray.shutdown()


def _run(out: Path, **kw) -> str:
    engine.evaluate_to(out, CONTROLLERS, EPISODES, OPTIONS, progress=False, **kw)
    return (out / "episodes.csv").read_text()


def test_ray_rows_equal_the_local_pool_and_serial_bit_for_bit(tmp_path, local_ray):
    serial = _run(tmp_path / "serial", workers=1)
    pool = _run(tmp_path / "pool", workers=2)
    on_ray = _run(tmp_path / "ray", workers=2, ray=engine.Ray())
    # Zero and PID apply to the flexible servo's speed scenario (PD does not): 12 rows and the header
    assert serial == pool == on_ray and serial.count("\n") == 1 + 2 * len(EPISODES)


def _ray_task_pids() -> list[int]:
    out = []
    for p in psutil.process_iter(["cmdline", "name"]):
        text = " ".join(p.info["cmdline"] or []) + " " + (p.info["name"] or "")
        if "_run_chunk_ray" in text:
            out.append(p.pid)
    return out


def test_a_killed_worker_job_is_retried_nothing_lost_nothing_duplicated(tmp_path, local_ray):
    """SIGKILL the worker running a job: Ray retries the task elsewhere; the file equals a clean run."""
    episodes = [Episode("kang_regulation", s, True) for s in range(1, 13)]
    controllers = ["Zero", "PD", "RDFC"]
    reference, _ = engine.evaluate_to(tmp_path / "ref", controllers, episodes, OPTIONS, 1, False)
    killed: list[int] = []

    def killer() -> None:
        deadline = time.monotonic() + 60
        while not killed and time.monotonic() < deadline:
            pids = _ray_task_pids()
            if pids:
                os.kill(pids[0], signal.SIGKILL)
                killed.append(pids[0])
            time.sleep(0.02)

    t = threading.Thread(target=killer)
    t.start()
    rows, _ = engine.evaluate_to(tmp_path / "ray", controllers, episodes, OPTIONS, 2, False, (), engine.Ray())
    t.join()
    assert killed, "no running task was found to kill"
    keys = [r.key() for r in rows]
    assert len(keys) == len(set(keys)) == len(reference)
    assert (tmp_path / "ray" / "episodes.csv").read_text() == (tmp_path / "ref" / "episodes.csv").read_text()


def test_a_killed_driver_resumes_from_the_results_file(tmp_path):
    """SIGKILL scripts/leaderboard.py --backend ray (its whole process group, local Ray included) after
    some rows landed; the rerun finishes the rest and the file equals a clean local run."""
    args = ["--scenarios", "kang_regulation", "--seeds", "1-10", "--randomize", "--controllers", "PD", "RDFC"]
    script = [sys.executable, str(ROOT / "scripts" / "leaderboard.py"), *args, "--models", "--workers", "2"]
    subprocess.run([*script, "--out", str(tmp_path / "clean")], check=True, capture_output=True)
    out = tmp_path / "ray"
    p = subprocess.Popen(
        [*script, "--backend", "ray", "--out", str(out)],
        start_new_session=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        f = out / "episodes.csv"
        if f.exists() and f.read_text().count("\n") >= 3:
            break
        time.sleep(0.05)
    os.killpg(p.pid, signal.SIGKILL)
    p.wait()
    partial = (out / "episodes.csv").read_text().count("\n") - 1
    assert 2 <= partial < 30, partial
    subprocess.run([*script, "--backend", "ray", "--out", str(out)], check=True, capture_output=True)
    assert (out / "episodes.csv").read_text() == (tmp_path / "clean" / "episodes.csv").read_text()


def test_a_grid_sweep_on_tune_writes_a_model_folder_per_trial(tmp_path, local_ray):
    """scripts/train.py --sweep: seeds x a grid on Ray Tune; every trial is a normal training run with its
    manifest, and reports its validation metric (the trials' table)."""
    import yaml

    from frictiongym.scripts.train import main

    cfg = {
        "name": "SweepSmoke",
        "algorithm": "SAC",
        "defaults": {
            "total_timesteps": 128,
            "validation": {"every_steps": 128, "episodes": 1, "max_effort_ratio": 100.0},
            "hyperparams": {"learning_starts": 0, "batch_size": 16, "buffer_size": 500},
        },
        "scenarios": {"flexible_speed_step": {"residual": {"base": "PID", "alpha": 0.1}}},
    }
    (tmp_path / "cfg.yaml").write_text(yaml.safe_dump(cfg))
    sweep = {
        "config": str(tmp_path / "cfg.yaml"),
        "scenario": "flexible_speed_step",
        "seeds": [0, 1],
        "search": "grid",
        "space": {"residual.alpha": {"grid": [0.05]}},
    }
    (tmp_path / "sweep.yaml").write_text(yaml.safe_dump(sweep))
    assert (
        main(["--sweep", str(tmp_path / "sweep.yaml"), "--workers", "2", "--out", str(tmp_path / "out")]) == 0
    )
    manifests = sorted((tmp_path / "out").glob("sweep/flexible_speed_step/*/manifest.yaml"))
    assert len(manifests) == 2
    got = {yaml.safe_load(m.read_text())["seed"] for m in manifests}
    assert got == {0, 1} and all(yaml.safe_load(m.read_text())["alpha"] == 0.05 for m in manifests)
    table = (tmp_path / "out" / "sweep.csv").read_text().splitlines()
    assert len(table) == 3 and "validation_main" in table[0] and "seed" in table[0].split(",")
