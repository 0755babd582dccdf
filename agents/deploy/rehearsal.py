"""Rehearsals: an exported controller's loop (run_drive) against the virtual drive, the drive in a process of
its own as a drive is a machine of its own (in a thread of the loop's process, the two would share one
interpreter lock), run several times in a row on loopback (frictiongym rehearse).

Each rehearsal's figures: the loop's periods and stop, its deadline misses (answers later than half a
period after their readings arrived), the compute per period (median, 99th percentile) split into the
controller's step, the send call (on loopback the kernel's delivery: it wakes the drive's process unless
the drive polls for its command, virtual_drive.serve's poll_s) and the loop's own overhead (the rest),
the commands missing at the drive (held there), and the tracking error over the log (mean and max
|r - y|, the tracked output's unit).
"""

from __future__ import annotations

import multiprocessing
import queue
import socket
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from frictiongym.agents.deploy.drive_loop import run_drive
from frictiongym.agents.deploy.runtime import Runtime
from frictiongym.agents.lab.drive_log import read_drive_log
from frictiongym.envs.virtual_drive import Faults, serve

DRIVE_START_S = 120.0  # s: the drive's process must have bound its socket within this (imports included)


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _drive(args: tuple, poll_s: float | None, ready: Any, out: Any) -> None:
    """The virtual drive in its process: its figures (without the logged arrays) onto `out`."""
    figures = serve(*args, ready=ready, poll_s=poll_s)
    out.put({k: v for k, v in figures.items() if k not in ("output", "command")})


def rehearse(
    artefact: Path,
    out: Path,
    runs: int = 10,
    duration_s: float = 6.0,
    faults: Faults | None = None,
    seed: int = 0,
    backend: str = "numpy",
    limits: dict[str, Any] | None = None,
    poll_s: float | None = None,
) -> Iterator[dict[str, Any]]:
    """`runs` rehearsals of duration_s each, one after another, each against a new virtual drive of the
    artefact's scenario (seed: its episode) in its own process; yields each one's figures (module
    docstring) as it ends; logs go to out/run<i>.csv. poll_s: how long the drive polls for each command
    before it sleeps (virtual_drive.serve; None: half a period)."""
    faults = faults or Faults()
    rt = Runtime.load(artefact, backend)
    sc = rt.scenario
    ctx = multiprocessing.get_context("spawn")  # a clean interpreter: no MuJoCo state forked
    for i in range(runs):
        drive, ctrl = ("127.0.0.1", _free_port()), ("127.0.0.1", _free_port())
        ready, figures = ctx.Event(), ctx.Queue()
        args = ((sc.name, drive, ctrl, duration_s, faults, seed), poll_s, ready, figures)
        process = ctx.Process(target=_drive, args=args, daemon=True)
        process.start()
        try:
            deadline = time.monotonic() + DRIVE_START_S
            while not ready.wait(0.1):
                if not process.is_alive():
                    raise RuntimeError(f"the virtual drive's process ended (exit code {process.exitcode})")
                if time.monotonic() > deadline:
                    raise TimeoutError(f"the virtual drive did not start within {DRIVE_START_S} s")
            log = Path(out) / f"run{i}.csv"
            loop = run_drive(rt, ctrl, drive, duration_s, log, limits, seed=seed)
            try:
                at_drive = figures.get(timeout=30)
            except queue.Empty:
                why = "the virtual drive sent no figures within 30 s of the loop's end"
                raise TimeoutError(why) from None
        finally:
            process.join(30)
            if process.is_alive():
                process.kill()
        yield {"run": i, **summary(loop, at_drive, log)}


def summary(loop: dict[str, Any], drive: dict[str, Any], log: Path) -> dict[str, Any]:
    """One rehearsal's figures from the loop's, the drive's and the log."""
    g = read_drive_log(log)
    e = np.abs(g.reference - g.position) if len(g.t) else np.zeros(1)
    return {
        "periods": loop["periods"],
        "stop": loop["stop"],
        "deadline_misses": loop["deadline_misses"],
        "compute_median_s": loop["compute_s"]["median"],
        "compute_p99_s": loop["compute_s"]["p99"],
        "step_median_s": loop["step_s"]["median"],
        "send_median_s": loop["send_s"]["median"],
        "overhead_median_s": loop["overhead_s"]["median"],
        "missing_at_drive": drive["missing_commands"],
        "late_at_drive": drive["late_commands"],
        "mean_abs_error": float(e.mean()),
        "max_abs_error": float(e.max()),
    }
