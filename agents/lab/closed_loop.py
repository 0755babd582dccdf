"""The simulated drive against its measurement (EMPS §3.5): the plant preset run in closed loop under the
lab's controller, driven by the measured reference (and the validation set's pulses), compared with the
measured position and force; and the open-loop simulation of the common benchmark protocol (input the
measured ν, output the position).

The closed loop runs through the suite's one evaluation loop (agents/evaluation/evaluate.py) on the
benchmark's own scenarios (the paper suite's emps_tracking_full, emps_pulses_full: the headline
scenarios over the whole recordings) with the nominal plant, so what is checked against the measurement
is what the benchmark simulates. Relative errors are those of EMPS eq. (11) as the description's
Simulation_EMPS script computes them: the measured position filtered and differentiated as in §3.1
against the simulated states, the force gτ·ν, all from the 50th sample on.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from frictiongym.agents.evaluation.evaluate import run_episode
from frictiongym.envs.plants import PlantSpec, plant_spec
from frictiongym.envs.plants.sim import PlantSim
from frictiongym.envs.suites import Episode

from ..registry import make
from .drive_log import DriveLog, emps_log
from .idim import PUBLISHED, IdimSettings, central_difference, relative_error, states

SIGNALS = ("position", "velocity", "acceleration", "force")
ARRAYS = ("t", "position", "reference", "command", "disturbance")  # DriveLog's per-sample fields
SCENARIOS = {"estimation": "emps_tracking_full", "validation": "emps_pulses_full"}  # the log each replays


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
    """The measured position, velocity and acceleration as EMPS §3.1 processes them (idim.states: the
    Butterworth forward and backward, central differences), and the force gτ·ν, over the whole log."""
    s = states(log, replace(settings, first_sample=1, delay_samples=0))
    return {"position": s.q, "velocity": s.dq, "acceleration": s.ddq, "force": s.force}


def compare(
    name: str, log: DriveLog, simulated: dict[str, np.ndarray], settings: IdimSettings = PUBLISHED
) -> Comparison:
    """The relative errors of simulated against measured signals (the same length as the log; a signal
    the simulation does not give, e.g. the force of an open-loop run, has error nan)."""
    meas = measured_states(log, settings)
    keep = slice(settings.first_sample - 1, None)
    m = {k: meas[k][keep] for k in SIGNALS}
    s = {k: np.asarray(simulated[k])[keep] for k in SIGNALS if k in simulated}
    errors = {k: relative_error(m[k], s[k]) if k in s else float("nan") for k in SIGNALS}
    rmse = float(np.sqrt(np.mean((log.position[keep] - s["position"]) ** 2)))
    return Comparison(name, log.t[keep], m, s, errors, rmse)


def closed_loop(
    which: str | DriveLog,
    controller: str = "LabPD",
    overrides: dict | None = None,
    plant: str | None = None,
) -> Comparison:
    """A log replayed in closed loop on the nominal plant under `controller`, against that log: the EMPS
    'estimation' or 'validation' set through its paper-suite scenario (emps_tracking_full, emps_pulses_full),
    or any drive log through emps_tracking_full with the log's reference and disturbance (DriveLog.replay)
    on preset `plant` (a configs/plants name; default the scenario's). The simulated force is
    gτ·(ν + disturbance): the command the controller computed at each sample plus the injected part,
    as the logged ν includes it. overrides: further scenario overrides (e.g. another friction model)."""

    if isinstance(which, str):
        log, scenario, ov = emps_log(which), SCENARIOS[which], {}
    else:
        log, scenario, ov = which, SCENARIOS["estimation"], which.replay()
        q0 = float(log.position[0])
        ov["initial_state"] = {"qpos": [[q0, q0]], "qvel": [[0.0, 0.0]]}  # the log's start, at rest
    if plant is not None:
        ov["plant"] = plant
    ov.update(overrides or {})
    n = len(log.t) - 1  # the commands of samples 0..n-1 are logged
    res = run_episode(
        make(controller),
        Episode(scenario, 0, False),
        keep_log=True,
        episode_s=round(n * log.period, 9),
        overrides=ov or None,
        control_period_s=log.period if not isinstance(which, str) else None,
    )
    g = res.log
    gain = _nominal(plant).actuator_gain
    v = g["velocity"][:n]
    sim = {
        "position": g["output"][:n],
        "velocity": v,
        "acceleration": central_difference(v, log.period),
        "force": gain * (g["command"][1 : n + 1] + log.disturbance[:n]),
    }
    name = which if isinstance(which, str) else log.source
    return compare(name, replace(log, **{k: getattr(log, k)[:n] for k in ARRAYS}), sim)


def open_loop(which: str | DriveLog, plant: str | None = None) -> Comparison:
    """The common benchmark protocol's simulation: the plant (preset `plant`, default the EMPS) driven
    open loop by the measured ν (which includes the pulses), from the measured initial position and
    filtered velocity. The integrator makes this a hard test: position errors accumulate."""
    log = emps_log(which) if isinstance(which, str) else which
    spec = _nominal(plant)
    if abs(spec.control_period - log.period) > 1e-3 * log.period:
        spec = plant_spec(plant or "emps", {"sampling": {"control_period_s": round(log.period, 9)}})
    sim = PlantSim(spec)
    meas = measured_states(log)
    sim.reset(qpos=[log.position[0]], qvel=[meas["velocity"][0]])
    q, v = np.empty(len(log.t)), np.empty(len(log.t))
    q[0], v[0] = log.position[0], meas["velocity"][0]
    for k in range(len(log.t) - 1):
        r = sim.step(float(log.command[k]))
        q[k + 1], v[k + 1] = r.qpos[0], r.qvel[0]
    s = {"position": q, "velocity": v, "acceleration": central_difference(v, log.period)}  # ν is the input
    return compare(which if isinstance(which, str) else log.source, log, s)


def _nominal(plant: str | None = None) -> PlantSpec:

    return plant_spec(plant or "emps")
