"""The EMPS plant (envs/plants/emps.py, configs/plants/emps.yaml), its scenarios and the lab PD: the preset
is the published identification, the slide joint obeys eq. (1), the lab controller reproduces the logged
command from the logged positions, and the simulated loop is checked against the measurement."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import frictiongym.envs  # noqa: F401  (registers the ids)
from frictiongym.agents.base import EpisodeContext
from frictiongym.agents.classical import LabPD
from frictiongym.agents.evaluation.evaluate import run_episode
from frictiongym.agents.lab import closed_loop, idim
from frictiongym.agents.lab.drive_log import DriveLog, emps_log
from frictiongym.agents.registry import make
from frictiongym.agents.reproduce import janot2019
from frictiongym.agents.reproduce.report import published_node
from frictiongym.envs.config import ConfigError
from frictiongym.envs.plants import plant_spec
from frictiongym.envs.plants.mjcf import to_mjcf
from frictiongym.envs.plants.sim import PlantSim
from frictiongym.envs.scenario import load_scenario
from frictiongym.envs.suites import Episode


@pytest.fixture(scope="module")
def spec():
    return plant_spec("emps")


def test_the_preset_is_the_published_symmetric_identification(spec):
    sym = published_node("emps2019").section("idim_ls").section("symmetric")
    (carriage,) = spec.joints
    f = carriage.friction
    assert carriage.kind == "slide"
    assert carriage.inertia == sym.get("mass_kg")[0]
    assert f.fc == sym.get("coulomb_n")[0] and f.sigma2 == sym.get("viscous_n_s_per_m")[0]
    assert f.bias == -sym.get("offset_n")[0]  # eq. (1): the offset is a constant force, -offset on the load
    assert spec.actuator_gain == published_node("emps2019").number("drive_gain_n_per_v")
    assert spec.command_limit == 10.0 and spec.control_period == 1e-3


def test_a_joint_of_an_unknown_kind_is_refused():
    from frictiongym.envs.plants.spec import JointSpec

    with pytest.raises(
        ConfigError, match=r"joint\[carriage\]\.kind: 'prismatic' not in \['hinge', 'slide'\]"
    ):
        JointSpec("carriage", 1.0, kind="prismatic")


def test_the_carriage_is_a_slide_joint_of_the_preset_mass(spec):
    sim = PlantSim(spec)
    assert 'type="slide"' in to_mjcf(spec)
    total = sim.model.dof_armature[0] + sim.model.body_mass[1]
    assert total == pytest.approx(95.1089, rel=1e-12)


@pytest.mark.parametrize("u_v", [2.0, -2.0])
def test_a_constant_command_reaches_the_speed_eq1_gives(spec, u_v):
    # M q̈ = gτ·u - Fv·v - Fc·sign(v) - offset = 0  ->  v = (gτ·u - Fc·sign(u) - offset)/Fv
    sim = PlantSim(spec)
    sim.reset()
    for _ in range(5000):  # 5 s = 10.6 time constants M/Fv
        r = sim.step(u_v)
    v = (35.15 * u_v - 20.3935 * np.sign(u_v) + 3.1648) / 203.5034
    assert r.qvel[0] == pytest.approx(v, rel=1e-3)


def test_below_breakaway_the_carriage_only_presliding(spec):
    # 15 N plus the 3.16 N bias (-offset) load the bristles with F = 18.16 N < Fc = 20.39 N: LuGre
    # (g = Fc) deflects them by L·ln(Fc/(Fc - F)), L = Fc/σ0 (the motion's inertia can add to it), no slide
    sim = PlantSim(spec)
    sim.reset()
    for _ in range(2000):
        r = sim.step(15.0 / 35.15)
    assert abs(r.qvel[0]) < 1e-9
    presliding = 20.3935 / 2.6e7 * np.log(20.3935 / (20.3935 - 18.1648))
    assert presliding <= r.qpos[0] <= 2 * presliding


def test_the_encoder_reads_the_50_nm_grid(spec):
    sim = PlantSim(spec)
    sim.reset(qpos=[0.123456789])
    m = sim.read().measurement[0]
    assert m / 5e-8 == pytest.approx(round(m / 5e-8), abs=1e-9)
    assert 0 <= 0.123456789 - m < 5e-8  # an incremental encoder counts whole steps


def test_the_lab_pd_gives_the_logged_command_from_the_logged_positions():
    # the controller of eq. (6) with the 2-tap FIR, fed the measured qm and qg, reproduces the logged ν
    log = emps_log("estimation")
    sc = load_scenario("emps_tracking")
    c = LabPD()
    c.reset(EpisodeContext(sc, plant_spec("emps")))
    nu = np.array([c.command(q, r) for q, r in zip(log.position, log.reference, strict=True)])
    assert np.abs(nu - log.command)[2:].max() < 0.02  # V; the logged ν spans ±4.3 V
    assert c.gains.kp == pytest.approx(160.18 * 243.45) and c.gains.kd == 243.45


def test_lab_pd_applies_only_where_the_plant_has_a_lab_controller():
    assert (
        LabPD().why_not(load_scenario("m220_regulation"))
        == "plant m220 has no lab controller in its document"
    )
    assert LabPD().why_not(load_scenario("emps_tracking")) is None
    assert make("PD").why_not(load_scenario("emps_tracking")).startswith("the plant's PD loop is its lab")


def test_the_scenarios_replay_the_measured_reference_and_pulses():
    log = emps_log("validation")
    sc = load_scenario("emps_pulses")
    t = np.arange(sc.episode_steps) * sc.control_period
    # sample for sample, although the log's clock wanders by 2e-8 s around k·1 ms
    np.testing.assert_array_equal(sc.reference(t), log.reference[: len(t)])
    np.testing.assert_array_equal(sc.disturbance(t), 35.15 * log.disturbance[: len(t)])
    assert load_scenario("emps_tracking").reference(t[:5]) == pytest.approx(
        emps_log("estimation").reference[:5]
    )


def test_an_episode_longer_than_the_recording_is_refused():
    with pytest.raises(ConfigError, match="longer than the recorded reference"):
        load_scenario("emps_tracking_full", episode_s=30.0)


def test_a_recording_beyond_the_envelope_is_refused():
    ov = {"reference": {"scale": 10.0}}  # 2.5 m: beyond the 0.5 m stroke
    with pytest.raises(ConfigError, match=r"reference\.signal: the recording reaches"):
        load_scenario("emps_tracking", overrides=ov)


def test_a_recorded_reference_naming_a_missing_signal_is_refused():
    with pytest.raises(ConfigError, match=r"reference\.file: .*qx: no such signal"):
        load_scenario("emps_tracking", overrides={"reference": {"signal": "qx"}})


def test_the_emps_env_runs_and_its_episode_is_the_recordings_first_cycle():
    env = gym.make("frictiongym/EMPS-Tracking-v1")
    obs, _ = env.reset(seed=3)
    assert env.spec.max_episode_steps == 6200 and obs.dtype == np.float32
    _, _, term, trunc, info = env.step(np.zeros(1, dtype=np.float32))
    assert not term and not trunc and info["reference"] == pytest.approx(emps_log("estimation").reference[1])


def test_idim_on_the_simulated_log_recovers_the_preset(spec):
    # the lab's identification, run on the simulator's own closed-loop log, finds the plant it simulates
    r = run_episode(make("LabPD"), Episode("emps_tracking", 0, False), keep_log=True, episode_s=24.84)
    g, n = r.log, len(r.log["t"]) - 1
    q = np.round(g["output"][:n] / 5e-8) * 5e-8  # what the encoder reads
    log = DriveLog(g["t"][:n], q, g["reference"][:n], g["command"][1 : n + 1], np.zeros(n), 35.15, "m", "sim")
    f = idim.fit("coulomb_viscous", idim.states(log))
    assert f.value("mass_kg") == pytest.approx(95.1089, rel=0.01)
    assert f.value("viscous_n_s_per_m") == pytest.approx(203.5034, rel=0.03)
    assert f.value("coulomb_n") == pytest.approx(20.3935, rel=0.03)
    assert f.value("offset_n") == pytest.approx(-3.1648, abs=0.1)


@pytest.mark.slow
def test_the_simulated_loop_is_at_least_as_close_to_the_measurement_as_the_descriptions():
    rows = list(janot2019.simulation_rows(janot2019.simulation_runs()))
    assert all(r["pass"] for r in rows), [r for r in rows if not r["pass"]]
    c = closed_loop.closed_loop("estimation")
    lag = emps_log("estimation").reference - emps_log("estimation").position
    assert c.position_rmse_m < 0.01 * np.sqrt(np.mean(lag**2))  # 1 % of the lab PD's own tracking error
