"""Metrics on signals whose values are known by construction."""

import numpy as np
import pytest

from frictiongym.envs import metrics


def test_integrals_of_a_constant_error():
    t = np.arange(0, 1.0, 0.01)
    m = metrics.integral_errors(t, np.full_like(t, 0.5))
    assert (
        m["iae"] == pytest.approx(0.5)
        and m["ise"] == pytest.approx(0.25)
        and m["rms_error"] == pytest.approx(0.5)
    )


def test_final_error_is_the_mean_absolute_error_of_the_last_tenth():
    e = np.concatenate([np.full(90, 5.0), np.array([1.0, -1.0] * 5)])
    assert metrics.final_error(e) == pytest.approx(1.0)


def test_settling_overshoot_on_a_damped_oscillation():
    t = np.arange(0, 10, 0.01)
    e = np.exp(-t) * np.cos(2 * np.pi * t)  # first undershoot near t = 0.5: e ≈ -exp(-0.5)
    # regulation: the move is the initial error e(0) = 1, the overshoot the largest excursion past 0
    r = np.zeros_like(t)
    assert metrics.overshoot_pct(r, e, 0.02) == pytest.approx(100 * np.exp(-0.5), rel=0.02)
    ts = metrics.settling_time(t, e, 0.02)
    assert np.all(np.abs(e[t >= ts]) <= 0.02) and abs(e[t < ts][-1]) > 0.02
    assert np.isnan(metrics.settling_time(t, np.ones_like(t), 0.02))


def test_overshoot_is_per_move_relative_to_the_move_size():
    """Tracking moves from a resting output: a 1-unit move overshot by 0.1 (10 %) and a 0.2-unit move
    back overshot by 0.05 (25 %) read 25 %, not a ratio to e(0) = 0; moves below min_move and a
    reference that never rests are not moves."""
    r = np.concatenate([np.zeros(10), np.linspace(0, 1, 6)[1:], np.ones(20), np.full(20, 0.8)])
    e = np.zeros_like(r)
    e[20] = 0.1  # past 1 in the move's (+) direction
    e[16] = -0.3  # behind the target: not an overshoot
    e[40] = -0.05  # past 0.8 in the (-) direction of the second move
    assert metrics.overshoot_pct(r, e, 1e-3) == pytest.approx(25.0)
    assert metrics.overshoot_pct(r, e, 0.5) == pytest.approx(10.0)  # the 0.2 move is below min_move
    t = np.linspace(0, 10, 1001)
    assert np.isnan(metrics.overshoot_pct(np.sin(t), 0.1 * np.cos(t), 1e-3))


def test_every_metric_of_an_episode_is_reported():
    t = np.arange(1, 101) * 0.01
    r, y = np.ones(100), np.ones(100)
    m = metrics.episode_metrics(t, r, y, np.zeros(100), np.zeros(100), settle_band=0.01, stick_velocity=0.1)
    assert set(m) == set(metrics.METRIC_NAMES)
    assert m["iae"] == 0.0 and m["settling_time"] == pytest.approx(0.01)
    assert np.isnan(m["overshoot_pct"])  # the output starts on the reference: no move to overshoot


def test_limit_cycle_amplitude_and_frequency():
    t = np.arange(0, 10, 0.001)
    y = 0.3 * np.sin(2 * np.pi * 2.5 * t)
    lc = metrics.limit_cycle(t, y)
    assert lc["limit_cycle_amp"] == pytest.approx(0.3, rel=1e-3)
    assert lc["limit_cycle_freq_hz"] == pytest.approx(2.5, rel=0.01)
    assert metrics.limit_cycle(t, 1e-6 * y, min_amp=1e-3)["limit_cycle_freq_hz"] == 0.0


def test_command_roughness_and_saturation_read_the_command_alone():
    """Chatter is the command's change per period: a command switching ±1 every period has roughness 2
    (|Δu| = 2 each period), a constant or slow one ~0; the saturated share counts periods at the limit."""
    switching = np.array([1.0, -1.0] * 50)
    assert metrics.command_roughness(switching) == pytest.approx(2.0)
    assert metrics.command_roughness(np.full(100, 0.7)) == 0.0
    assert metrics.command_roughness(np.linspace(0, 1, 101)) == pytest.approx(0.01)
    u = np.array([2.0, -2.0, 1.999, 0.0])
    assert metrics.saturated_share(u, 2.0) == pytest.approx(0.5)


def test_an_oscillation_at_rest_is_a_limit_cycle_and_an_offset_or_a_tracking_error_is_not():
    """Where the reference rests, the error's sustained oscillation over the second half of the rest
    counts (half its peak-to-peak); a constant offset (stuck short of the target) counts 0; a reference
    that never rests has no rest to judge (nan) however large its tracking error."""
    t = np.arange(2000) * 0.005
    r = np.where(t < 1.0, t, 1.0)  # a ramp, then a rest of 9 s
    hunting = np.where(t > 2.0, 0.01 * np.sin(2 * np.pi * 0.5 * t), 0.0)
    assert metrics.rest_oscillation(r, hunting, 1e-4) == pytest.approx(0.01, rel=1e-3)
    assert metrics.rest_oscillation(r, np.full_like(t, -0.02), 1e-4) == 0.0
    assert metrics.rest_oscillation(r, hunting, 0.02) == 0.0  # below the sensor's resolution
    assert np.isnan(metrics.rest_oscillation(np.sin(t), 0.3 * np.sin(40 * t), 1e-4))


def test_stick_slip_events_and_reversals():
    v = np.array([0, 0, 1, 1, 0, 0, 2, 0, -1, -1, 0])
    assert metrics.stick_slip_events(v, 0.5) == 3
    t = np.linspace(0, 10, 1001)
    r = np.sin(2 * np.pi * 0.2 * t)  # reversals at t = 1.25, 3.75, ...
    e = np.where(np.abs(t - 3.75) < 0.05, 0.1, 0.001)
    assert metrics.reversal_peak_error(t, r, e, 0.25) == pytest.approx(0.1)
    assert np.isnan(metrics.reversal_peak_error(t, np.zeros_like(t), e, 0.25))


def test_effort():
    m = metrics.effort(np.array([1.0, -1.0, 1.0]))
    assert m["effort_rms"] == pytest.approx(1.0) and m["effort_total_variation"] == pytest.approx(4.0)
