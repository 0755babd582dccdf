"""Classical baselines behave as their papers say on the simulated plants."""

import dataclasses
import math

import numpy as np
import pytest

from frictiongym.agents import registry
from frictiongym.agents.base import EpisodeContext
from frictiongym.agents.classical import PD, PID, RDFC, Southward, design_pid
from frictiongym.agents.evaluation.evaluate import evaluate, run_episode
from frictiongym.envs.config import ConfigError
from frictiongym.envs.plants import plant_spec
from frictiongym.envs.plants.params import EpisodeParams
from frictiongym.envs.scenario import load_scenario
from frictiongym.envs.suites import Episode

KANG = Episode("kang_regulation_20deg", 0, False)


def test_kang_pd_gains_follow_from_the_document():
    sc = load_scenario("kang_regulation")
    g = design_pid(EpisodeContext(sc, sc.spec), integral=False)
    J, c = sc.spec.joints[0].inertia, sc.spec.joints[0].friction.sigma2
    assert g.kp == pytest.approx(0.20667 * 180 / math.pi)  # N·m/rad, resolved K_p
    wn = math.sqrt(g.kp / J)
    assert wn / (2 * math.pi) == pytest.approx(0.5, rel=0.01)  # ω_n = 0.5 Hz, §6
    assert (g.kd + c) / (2 * wn * J) == pytest.approx(0.83)  # ζ incl. viscous friction


def test_pd_sticks_inside_the_equilibrium_region():
    e = math.degrees(run_episode(PD(), KANG, keep_log=True).log["output"][-1])
    assert -8.64 <= e <= 6.97 and abs(e) > 0.05  # eq. (6): a steady error that PD cannot remove


def test_southward_limit_cycle_grows_with_the_sampling_period():
    amp = [
        run_episode(Southward(), KANG, control_period_s=T).metrics["limit_cycle_amp"]
        for T in (0.005, 0.02, 0.04)
    ]
    res = plant_spec("kang_robot").sensors[0].resolution
    assert amp[1] > 10 * res  # sustained at 20 ms (§6, Fig. 8)
    assert amp[0] < amp[1] < amp[2]


@pytest.mark.parametrize("delta", [0.02, 0.04])
def test_rdfc_converges_into_the_dead_band_and_switches_off(delta):
    r = run_episode(RDFC(delta), KANG, keep_log=True)
    e = math.degrees(r.log["output"][-1])
    assert abs(e) <= delta  # Theorem 2: S_δ is asymptotically stable
    assert np.all(r.log["command"][-25:] == 0.0)  # inside the dead band the compensation is off
    assert r.metrics["limit_cycle_amp"] == 0.0


def test_rdfc_brings_its_analog_rate_loop_as_plant_hardware():
    sc = load_scenario("kang_regulation")
    hw = RDFC().plant_overrides(sc)
    kd = design_pid(EpisodeContext(sc, sc.spec), integral=False).kd
    assert hw["actuator"]["rate_feedback_nm_s_per_deg"] == pytest.approx(kd * math.pi / 180)


def test_friction_knowledge_is_configurable():
    """A compensator that underestimates static friction by half cannot push the rotor out of the
    stick region: it stalls outside the dead band."""
    r = run_episode(RDFC(0.02), KANG, keep_log=True, knowledge={"static_friction_scale": 0.5})
    assert abs(math.degrees(r.log["output"][-1])) > 0.02


def test_pid_integrator_removes_the_m220_steady_error_and_antiwindup_limits_overshoot():
    ep = Episode("m220_regulation", 0, False)
    pd, pid = run_episode(PD(), ep), run_episode(PID(), ep)
    assert pid.metrics["final_error"] < pd.metrics["final_error"]
    assert pid.metrics["overshoot_pct"] < 50.0


@pytest.mark.parametrize(
    ("friction_scale", "asymmetry_shift", "sticks"),
    [(1.0, 0.0, False), (1.2, -0.1, False), (1.2, 0.0, True), (1.1, 0.1, True)],
)
def test_southward_sticks_where_the_static_level_of_the_approach_reaches_its_push(
    friction_scale, asymmetry_shift, sticks
):
    """Southward's bang-bang push is margin·T_s of the nominal plant (Kang §6: 1.2). The M220 set-point
    is approached from above, so the drive must break away in the negative direction: where that
    direction's static level (f_s + bias, the asymmetry shifting it) comes within 1 % of the push,
    Southward stalls outside its last count (the validation draws where it does, docs/research.md "The
    M220 set-points"); below it, the drive stops within one encoder count (2π/16000 rad)."""
    spec = plant_spec("m220")
    values = {"friction_scale": friction_scale, "asymmetry_shift": asymmetry_shift}
    f = EpisodeParams.from_values(spec, values).friction[0]
    c = Southward()
    ep = Episode("m220_regulation", 0, False, tuple(sorted(values.items())))
    r = run_episode(c, ep)
    push = -c.ts_neg  # N·m, after the episode's start
    assert (f.fs + f.bias >= 0.99 * push) == sticks
    if sticks:
        assert r.metrics["final_error"] > 1e-3
    else:
        assert r.metrics["final_error"] < 2 * math.pi / 16000


def test_evaluate_runs_only_applicable_controllers():
    eps = [Episode("flexible_speed_step", 0, False), Episode("kang_regulation", 0, False)]
    res = evaluate([PD(), PID(), RDFC()], eps, progress=False)
    assert [(r.controller, r.scenario) for r in res] == [
        ("PID", "flexible_speed_step"),
        ("PD", "kang_regulation"),
        ("PID", "kang_regulation"),
        ("RDFC", "kang_regulation"),
    ]


def test_flexible_pi_tracks_the_speed_step_at_40ms():
    """Designed on the rigid body with the colocated high-frequency gain in mind (controllers.yaml)."""
    r = run_episode(PID(), Episode("flexible_speed_step", 0, False), keep_log=True)
    g = r.log
    at = lambda t: g["output"][np.searchsorted(g["t"], t)]  # noqa: E731
    assert at(4.9) == pytest.approx(1.0, abs=0.02)  # y1 follows y_r = 1 V before the step down
    assert np.max(np.abs(g["command"])) < 10.0  # no saturation
    assert r.metrics["final_error"] < 0.01


def test_lugre_observer_compensation_removes_kangs_steady_error():
    from frictiongym.agents.classical import LuGreObserver

    pd, obs = run_episode(PD(), KANG), run_episode(LuGreObserver(), KANG)
    assert obs.metrics["final_error"] < 0.01 * pd.metrics["final_error"]


def test_lugre_observer_estimate_converges_to_the_sliding_friction():
    """At constant speed ẑ settles at g(v)/σ0·sgn(v), so F̂ = g(v) + σ2 v (the LuGre steady state)."""
    from frictiongym.agents.classical import LuGreObserver

    c = LuGreObserver()
    sc = load_scenario("kang_regulation")
    c.reset(EpisodeContext(sc, sc.spec, {}))
    v = 0.3
    for _ in range(50):
        F = c.friction_estimate(one(v), one(0.0))[0]
    assert pytest.approx(-c.p.steady_state(v) + c.p.bias, rel=1e-6) == F


def test_lugre_observer_update_keeps_its_state_at_vanishing_speeds():
    """At a velocity far below an encoder count per period (as a filtered velocity decays to) the observer's
    update tends to ẑ + (v - k e)·h; the exact form drive/a + (ẑ - drive/a)·e^{-ah} would lose ẑ in the
    rounding of drive/a (about 1e290 here)."""
    from frictiongym.agents.classical import LuGreObserver

    c = LuGreObserver()
    sc = load_scenario("m220_reversal_tracking")
    c.reset(EpisodeContext(sc, sc.spec, {}))
    c.z = one(1e-3)
    c.friction_estimate(one(1e-290), one(1e-2))
    assert c.z[0] == pytest.approx(1e-3 - c.k_obs * 1e-2 * c.h, rel=1e-12)


def test_lugre_observer_velocity_filter_is_a_first_order_lag_and_off_for_the_baseline():
    """velocity_filter_s = τ: the observer runs on v_f, starting at the first velocity and moving by
    1 - e^{-h/τ} of the gap each period; the baseline (controllers.yaml: 0) runs on the raw difference."""
    from frictiongym.agents.classical import LuGreObserver

    sc = load_scenario("m220_reversal_tracking")
    raw, filt = LuGreObserver(), LuGreObserver(velocity_filter_s=0.01)
    for c in (raw, filt):
        c.reset(EpisodeContext(sc, sc.spec, {}))
    assert raw.observer.velocity_filter_s == 0.0
    h = raw.h
    assert raw.velocity(one(0.0), None)[0] == filt.velocity(one(0.0), None)[0] == 0.0
    assert raw.velocity(one(1e-3), one(0.0))[0] == pytest.approx(0.2)
    assert filt.velocity(one(1e-3), one(0.0))[0] == pytest.approx(0.2 * (1 - math.exp(-h / 0.01)))
    for _ in range(round(0.1 / h)):  # ten time constants at a steady 0.2 rad/s
        v = filt.velocity(one(1e-3), one(0.0))[0]
    assert v == pytest.approx(0.2, rel=1e-4)


def test_coulomb_viscous_feedforward_reduces_reversal_errors():
    from frictiongym.agents.classical import CoulombViscousFF

    ep = Episode("m220_reversal_tracking", 0, False)
    pd, ff = run_episode(PD(), ep), run_episode(CoulombViscousFF(), ep)
    assert ff.metrics["reversal_peak_error"] < 0.5 * pd.metrics["reversal_peak_error"]
    assert ff.metrics["iae"] < pd.metrics["iae"]


def test_pid_feedforward_takes_the_coulomb_step_off_the_integrator():
    """On the EMPS's stiff PID loop a reversal's error is mostly the integrator winding through the
    Coulomb step (2 F_C); the identified feed-forward supplies that step at the reference's reversal, so
    the reversal peak falls (nominal episode: 1.670e-4 to 1.477e-4 m) at the same effort, and on the M220
    the feed-forward does better on the PID loop than on the PD loop it was published with."""
    for scenario, gain in (("emps_tracking", 0.95), ("m220_reversal_tracking", 0.8)):
        ep = Episode(scenario, 0, False)
        pid, pidff = run_episode(PID(), ep), run_episode(registry.make("PID+FF"), ep)
        assert pidff.controller == "PID+FF"
        assert pidff.metrics["reversal_peak_error"] < gain * pid.metrics["reversal_peak_error"]
        assert pidff.metrics["iae"] < pid.metrics["iae"]
        assert pidff.metrics["effort_rms"] < 1.05 * pid.metrics["effort_rms"]
    pdff = run_episode(registry.make("CoulombViscousFF"), ep)
    assert pidff.metrics["reversal_peak_error"] < 0.8 * pdff.metrics["reversal_peak_error"]


def test_controllers_yaml_unknown_keys_name_the_file(monkeypatch):
    from frictiongym.agents import classical, settings

    assert classical.PIDSettings.SECTION in settings.FamilySettings.sections
    raw = settings.load_yaml(settings.configs_dir() / settings.FILE)
    for bad, match in (
        ({**raw, "southwrd": {}}, r"controllers\.yaml: southwrd: unknown section"),
        ({**raw, "pid": {**raw["pid"], "zta": 1.0}}, r"controllers\.yaml: pid\.zta: unknown key"),
    ):
        monkeypatch.setattr(settings, "load_yaml", lambda *_a, bad=bad, **_k: bad)
        settings._raw.cache_clear()
        with pytest.raises(ConfigError, match=match):
            settings.read("pid", lambda s: (s.get("integrator_pole_ratio"), s.get("loops")))
    settings._raw.cache_clear()


def _fresh(controller, scenario: str):
    sc = load_scenario(scenario)
    controller.reset(EpisodeContext(sc, sc.spec, {}))
    return controller


def one(x: float) -> np.ndarray:
    """One episode's value, as an array controller takes it."""
    return np.array([x], dtype=float)


def schedule(**options):
    """SpeedScheduled on the M220 with its controllers.yaml schedule's options changed; plain: none of
    them (no bumpless transfer, no filter, PID below speed_low on every task, no residual gate)."""
    from frictiongym.agents.classical import SpeedScheduled, SpeedScheduledSettings
    from frictiongym.agents.registry import builtin

    default = SpeedScheduledSettings.defaults().schedules["m220"]
    return SpeedScheduled(builtin, SpeedScheduledSettings({"m220": dataclasses.replace(default, **options)}))


PLAIN = {
    "bumpless": False,
    "high_velocity_filter_s": None,
    "low_tracking": None,
    "residual_gate": "none",
    "residual_floor": 0.0,
}


def test_speed_scheduled_is_its_low_loop_at_rest_and_its_high_loop_in_fast_motion():
    """u = (1 - w)·u_low + w·u_high: at w = 0 (a constant reference) PID's commands, at w = 1 (a ramp
    faster than speed_high, from its second sample) the LuGre observer's, bit for bit; in between the
    blend with w = (v - speed_low)/(speed_high - speed_low)."""
    from frictiongym.agents.classical import LuGreObserver

    sched = _fresh(schedule(**PLAIN), "m220_reversal_tracking")
    s, h = sched.s, sched.h
    assert (s.low, s.high) == ("PID", "LuGreObserver") and s.speed_low < s.speed_high
    rng = np.random.default_rng(0)
    ys = np.cumsum(rng.normal(0, 1e-3, 200))  # readings (rad)

    def commands(c, refs):
        return [c.command(y, r) for y, r in zip(ys, refs, strict=True)]

    def run(refs):
        mine = commands(_fresh(schedule(**PLAIN), "m220_reversal_tracking"), refs)
        lo = commands(_fresh(PID(), "m220_reversal_tracking"), refs)
        hi = commands(_fresh(LuGreObserver(), "m220_reversal_tracking"), refs)
        return mine, lo, hi

    mine, lo, _ = run(np.full(200, 0.3))
    assert mine == lo
    fast = 1.5 * s.speed_high * h * np.arange(200)
    mine, lo, hi = run(fast)
    assert mine[0] == lo[0] and mine[1:] == hi[1:] and lo[1:] != hi[1:]
    v = 0.5 * (s.speed_low + s.speed_high)
    mine, lo, hi = run(v * h * np.arange(200))
    w = (v - s.speed_low) / (s.speed_high - s.speed_low)
    np.testing.assert_allclose(mine[1:], (1 - w) * np.array(lo[1:]) + w * np.array(hi[1:]), rtol=1e-9)


def test_speed_scheduled_holds_a_motions_weight_and_decays_it_over_hold_s():
    """After a motion at speed v0 stops, the envelope is v0·exp(-t/hold_s): the weight goes back to the
    low loop once it is below speed_low, at t = hold_s·ln(v0/speed_low)."""
    c = _fresh(schedule(), "m220_reversal_tracking")
    s, h = c.s, c.h
    v0 = 2 * s.speed_high
    for k in range(10):
        assert c.weight(one(v0 * h * k))[0] == (0.0 if k == 0 else 1.0)
    stop = v0 * h * 9
    t_low = s.hold_s * math.log(v0 / s.speed_low)  # s
    ws = [c.weight(one(stop))[0] for _ in range(int(2 * t_low / h))]
    t = h * np.arange(1, len(ws) + 1)
    expected = np.clip((v0 * np.exp(-t / s.hold_s) - s.speed_low) / (s.speed_high - s.speed_low), 0, 1)
    np.testing.assert_allclose(ws, expected, atol=1e-12)
    assert ws[int(0.9 * t_low / h)] > 0 and ws[int(1.1 * t_low / h)] == 0


def test_speed_scheduled_runs_on_a_scheduled_position_loop_only_and_is_pid_at_set_points():
    """The registry's SpeedScheduled (the committed M220 generalists' base, every option on) at a
    set-point is PID's episode to the last bit (w = 0 throughout, PID below speed_low at set-points)."""
    from frictiongym.agents import registry

    c = registry.make("SpeedScheduled")
    assert "no schedule for plant 'kang_robot'" in c.why_not(load_scenario("kang_regulation"))
    assert "encoder" in c.why_not(load_scenario("flexible_speed_step"))
    ep = Episode("m220_regulation", 500000, True)  # a constant reference: w = 0 throughout
    np.testing.assert_equal(run_episode(c, ep).metrics, run_episode(PID(), ep).metrics)  # NaN == NaN


def test_a_pid_told_its_share_integrates_only_that_share():
    """authority(s): the integrator grows by s·ki·e·h (the blend's bumpless transfer); s = 1 is PID
    alone, bit for bit, and s = 0 holds the integral."""
    for share in (0.0, 0.25, 1.0):
        c = _fresh(PID(), "m220_reversal_tracking")
        c.authority(share)
        c.command(0.0, 1e-3)  # e = 1 mrad, far from saturation
        assert c.i_term[0] == share * c.gains.ki * 1e-3 * c.h
    a, b = _fresh(PID(), "m220_reversal_tracking"), _fresh(PID(), "m220_reversal_tracking")
    b.authority(1.0)
    ys = np.cumsum(np.random.default_rng(1).normal(0, 1e-3, 100))
    assert [a.command(y, 0.2) for y in ys] == [b.command(y, 0.2) for y in ys]


def test_the_bumpless_schedule_holds_the_low_loops_integral_while_the_high_loop_commands():
    """At w = 1 (a ramp faster than speed_high) the bumpless schedule applies the observer's command, as
    the plain one does, but its PID integrates nothing, so it hands back the integral it had before the
    motion; the plain schedule's PID winds up over the same motion. At w = 0 both are PID, bit for bit."""
    ys = np.cumsum(np.random.default_rng(0).normal(0, 1e-3, 100))
    plain, bumpless = (
        _fresh(schedule(**{**PLAIN, **extra}), "m220_reversal_tracking") for extra in ({}, {"bumpless": True})
    )

    def commands(c, refs):  # readings within a few mrad of the reference: no saturation
        return [c.command(r + y, r) for y, r in zip(ys, refs, strict=True)]

    rest = np.full(100, 0.3)
    assert commands(plain, rest) == commands(bumpless, rest)
    held = bumpless.low.i_term[0]
    assert held != 0.0
    fast = 0.3 + 1.5 * plain.s.speed_high * plain.h * np.arange(1, 101)
    # the observer's command: PID's integrator does not reach the output at w = 1
    assert commands(plain, fast) == commands(bumpless, fast)
    assert bumpless.low.i_term[0] == held and plain.low.i_term[0] != held


def test_the_bumpless_schedule_cuts_the_reversal_peak_on_a_validation_episode():
    """What the transfer is for (scheduled.py's docstring, 10 episodes: 0.0087 against 0.0157 rad): on
    the first validation episode of the 0.2 Hz reversals PID no longer hands back an integral wound up
    under the observer, so the peak error at the reversals is lower at no more effort."""
    ep = Episode("m220_reversal_tracking", 500000, True)
    plain, bumpless = (
        run_episode(schedule(**{**PLAIN, **extra}), ep).metrics for extra in ({}, {"bumpless": True})
    )
    assert bumpless["reversal_peak_error"] < 0.75 * plain["reversal_peak_error"]
    assert bumpless["effort_rms"] <= plain["effort_rms"]


def test_the_filtered_schedule_cuts_the_jittered_reversals_effort_on_a_validation_episode():
    """What the velocity filter is for (controllers.yaml speed_scheduled.m220): under the jittered
    scenario's encoder noise the observer's velocity (an encoder difference) carries the noise into the
    command; filtered, the effort on the first validation episode falls by more than a quarter and the
    reversal peak error does not grow."""
    ep = Episode("m220_reversal_tracking_hard", 500000, True)
    bumpless = {**PLAIN, "bumpless": True}
    bumpless, filtered = (
        run_episode(schedule(**{**bumpless, **extra}), ep).metrics
        for extra in ({}, {"high_velocity_filter_s": 0.01})
    )
    assert filtered["effort_rms"] < 0.75 * bumpless["effort_rms"]
    assert filtered["reversal_peak_error"] <= bumpless["reversal_peak_error"]


def test_the_filtered_schedule_filters_only_its_observer_and_names_bad_settings():
    from frictiongym.agents.classical import SpeedScheduledSettings
    from frictiongym.agents.registry import builtin

    c = _fresh(schedule(), "m220_reversal_tracking")
    tau = SpeedScheduledSettings.defaults().schedules["m220"].high_velocity_filter_s
    assert c.high.observer.velocity_filter_s == tau > 0
    assert builtin("LuGreObserver").observer.velocity_filter_s == 0.0  # the baseline keeps none
    assert (
        _fresh(
            schedule(high_velocity_filter_s=None), "m220_reversal_tracking"
        ).high.observer.velocity_filter_s
        == 0
    )
    with pytest.raises(ConfigError, match=r"speed_scheduled\.m220\.high: PID is not a LuGre observer"):
        schedule(high="PID").why_not(load_scenario("m220_regulation"))


def test_the_ff_schedule_runs_pid_ff_below_speed_low_on_tracking_and_pid_at_set_points():
    """low_tracking (controllers.yaml speed_scheduled.m220): on a tracking scenario the low loop is
    PID+FF, so at rest (w = 0) its commands are PID+FF's; at a set-point it is the schedule without it
    bit for bit (PID below speed_low). The feed-forward's Coulomb step at the 0.2 Hz reversals, where the
    low loop regains weight, lowers the filtered schedule's reversal peak (validation: 0.0055 against
    0.0085 rad over 30 episodes). A loop that is none is named."""
    from frictiongym.agents.classical import PIDCoulombViscousFF

    c = _fresh(schedule(), "m220_reversal_tracking")
    assert isinstance(c.low, PIDCoulombViscousFF) and c.high.observer.velocity_filter_s > 0
    ff = _fresh(PIDCoulombViscousFF(), "m220_reversal_tracking")
    ys = np.cumsum(np.random.default_rng(0).normal(0, 1e-3, 200))  # readings (rad), reference at rest
    assert [c.command(y, 0.3) for y in ys] == [ff.command(y, 0.3) for y in ys]
    ep = Episode("m220_regulation", 500000, True)
    mine, filtered = schedule(), schedule(low_tracking=None)
    np.testing.assert_equal(run_episode(mine, ep).metrics, run_episode(filtered, ep).metrics)
    peaks = [
        [
            run_episode(c, Episode("m220_reversal_tracking", s, True)).metrics["reversal_peak_error"]
            for s in (500000, 500001, 500002)
        ]
        for c in (mine, filtered)
    ]
    assert np.mean(peaks[0]) < 0.8 * np.mean(peaks[1])
    with pytest.raises(ConfigError, match=r"speed_scheduled\.m220\.low_tracking: Zero is not a loop"):
        schedule(low_tracking="Zero").why_not(load_scenario("m220_random"))


def test_speed_scheduled_settings_are_checked_by_name():
    with pytest.raises(ConfigError, match=r"speed_scheduled\.m220\.high: Zero is not a loop"):
        schedule(high="Zero", high_velocity_filter_s=None).why_not(load_scenario("m220_regulation"))
    with pytest.raises(ValueError, match="'PIDD' is not a built-in controller"):
        schedule(low="PIDD").why_not(load_scenario("m220_regulation"))


def test_the_task_schedule_runs_its_tasks_loop_alone_bit_for_bit():
    """TaskScheduled (controllers.yaml task_scheduled) on Kang's rotor: PID+FF's episode on a tracking
    scenario and PID's at a set-point, metrics equal to the last bit; PID+FF itself is refused at the
    set-point (tracking only), and a plant without a schedule is named."""
    from frictiongym.agents.classical import PIDCoulombViscousFF

    c = registry.make("TaskScheduled")
    assert "no schedule for plant 'emps'" in c.why_not(load_scenario("emps_random"))
    assert PIDCoulombViscousFF().why_not(load_scenario("kang_regulation")) is not None
    for scenario, alone in (("kang_random", PIDCoulombViscousFF()), ("kang_regulation", PID())):
        ep = Episode(scenario, 500000, True)
        assert c.why_not(load_scenario(scenario)) is None
        mine, theirs = run_episode(c, ep), run_episode(alone, ep)
        assert c.params()["loop"] == alone.name
        np.testing.assert_equal(mine.metrics, theirs.metrics)


def test_the_task_schedule_refuses_an_unknown_task_by_name(monkeypatch):
    from frictiongym.agents import settings
    from frictiongym.agents.classical import TaskScheduledSettings

    raw = settings._raw()
    bad = {**raw, "task_scheduled": {"kang_robot": {"tracking": "PID+FF", "setpoint": "PID"}}}
    monkeypatch.setattr(settings, "load_yaml", lambda *_a, **_k: bad)
    settings._raw.cache_clear()
    TaskScheduledSettings.defaults.cache_clear()
    try:
        with pytest.raises(ConfigError, match=r"task_scheduled\.kang_robot\.setpoint: not a task"):
            TaskScheduledSettings.defaults()
    finally:
        settings._raw.cache_clear()
        TaskScheduledSettings.defaults.cache_clear()
