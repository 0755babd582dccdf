"""The simulated drive against its measurement (EMPS §3.5): the plant preset run in closed loop under the
lab's controller, driven by the measured reference (and the validation set's pulses), compared with the
measured position and force; and the open-loop simulation of the common benchmark protocol (input the
measured ν, output the position).

The closed loop runs through the suite's one evaluation loop (agents/evaluate.py) on the benchmark's own
scenarios (emps_tracking, emps_pulses) with the nominal plant, so what is checked against the
measurement is exactly what the benchmark simulates. Relative errors are those of EMPS eq. (11) as the
description's Simulation_EMPS script computes them: the measured position filtered and differentiated as
in §3.1 against the simulated states, the force gτ·ν, all from the 50th sample on.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import signal

from frictiongym.envs.plants import PlantSpec
from frictiongym.envs.plants.sim import PlantSim
from frictiongym.envs.suites import Episode

from .drive_log import DriveLog, emps_log
from .idim import PUBLISHED, IdimSettings, central_difference, matlab_filtfilt, relative_error

SIGNALS = ("position", "velocity", "acceleration", "force")
SCENARIOS = {"estimation": "emps_tracking", "validation": "emps_pulses"}  # the log each scenario replays


@dataclass(frozen=True)
class Comparison:
    """Measured and simulated signals of one log (SI: m, m/s, m/s², N; from the first kept sample) and
    their relative errors (%, eq. 11), plus the RMSE of the simulated position against the raw measured
    position (m)."""

    log: str
    t: np.ndarray
    measured: dict[str, np.ndarray]
    simulated: dict[str, np.ndarray]
    relative_error_pct: dict[str, float]
    position_rmse_m: float


def measured_states(log: DriveLog, settings: IdimSettings = PUBLISHED) -> dict[str, np.ndarray]:
    """The measured position, velocity and acceleration as EMPS §3.1 processes them (Butterworth forward
    and backward, central differences), and the force gτ·ν, over the whole log."""
    b, a = signal.butter(settings.butterworth_order, settings.cutoff_hz * 2 * log.period)
    q = matlab_filtfilt(b, a, log.position)
    dq = central_difference(q, log.period)
    return {
        "position": q,
        "velocity": dq,
        "acceleration": central_difference(dq, log.period),
        "force": log.force,
    }


def compare(
    name: str, log: DriveLog, simulated: dict[str, np.ndarray], settings: IdimSettings = PUBLISHED
) -> Comparison:
    """The relative errors of simulated against measured signals (the same length as the log)."""
    meas = measured_states(log, settings)
    keep = slice(settings.first_sample - 1, None)
    m = {k: meas[k][keep] for k in SIGNALS}
    s = {k: np.asarray(simulated[k])[keep] for k in SIGNALS}
    errors = {k: relative_error(m[k], s[k]) for k in SIGNALS}
    rmse = float(np.sqrt(np.mean((log.position[keep] - s["position"]) ** 2)))
    return Comparison(name, log.t[keep], m, s, errors, rmse)


def closed_loop(which: str, controller: str = "LabPD", overrides: dict | None = None) -> Comparison:
    """The benchmark scenario that replays log `which` ('estimation' or 'validation'), on the nominal
    plant under `controller`, against that log. The simulated force is gτ·(ν + pulses): the command the
    controller computed at each sample (it acts one sample later, the rig's delay) plus the injected
    pulse, as the logged ν includes it. overrides: scenario overrides (e.g. another friction model)."""
    from ..evaluate import run_episode
    from ..registry import make

    log = emps_log(which)
    n = len(log.t) - 1  # the commands of samples 0..n-1 are logged
    res = run_episode(
        make(controller),
        Episode(SCENARIOS[which], 0, False),
        keep_log=True,
        episode_s=n * log.period,
        overrides=overrides,
    )
    g = res.log
    gain = _nominal().actuator_gain
    v = g["velocity"][:n]
    sim = {
        "position": g["output"][:n],
        "velocity": v,
        "acceleration": central_difference(v, log.period),
        "force": gain * (g["command"][1 : n + 1] + log.disturbance[:n]),
    }
    trimmed = DriveLog(
        log.t[:n],
        log.position[:n],
        log.reference[:n],
        log.command[:n],
        log.disturbance[:n],
        log.drive_gain,
        log.unit,
        log.source,
        log.kp,
        log.kv,
    )
    return compare(which, trimmed, sim)


def open_loop(which: str, spec: PlantSpec | None = None) -> Comparison:
    """The common benchmark protocol's simulation: the plant driven open loop by the measured ν (which
    includes the pulses), from the measured initial position and filtered velocity. The integrator makes
    this a hard test: position errors accumulate."""
    log = emps_log(which)
    sim = PlantSim(spec or _nominal())
    meas = measured_states(log)
    sim.reset(qpos=[log.position[0]], qvel=[meas["velocity"][0]])
    q, v = np.empty(len(log.t)), np.empty(len(log.t))
    q[0], v[0] = log.position[0], meas["velocity"][0]
    for k in range(len(log.t) - 1):
        r = sim.step(float(log.command[k]))
        q[k + 1], v[k + 1] = r.qpos[0], r.qvel[0]
    s = {"position": q, "velocity": v, "acceleration": central_difference(v, log.period), "force": log.force}
    return compare(which, log, s)


def _nominal() -> PlantSpec:
    from frictiongym.envs.plants import plant_spec

    return plant_spec("emps")
