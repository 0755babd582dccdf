"""What one env step computes (envs/step.py) and the sensors that read it (envs/sensors.py): the plain-float
and the array forms of every function give the same bits (the single env's fast path relies on it), the
encoder counts whole lines, every reward term is bounded and a diverged step scores below all of them,
and an observation is always finite float32."""

import numpy as np
import pytest

from frictiongym.envs.step import (
    ARRAY,
    FLOAT,
    OBS_CLIP,
    diverged_reward,
    encoder_reading,
    observation_layout,
    reward_terms,
    reward_total,
    sanitize_observation,
    tacho_reading,
)

RES = 2 * np.pi / 16000  # rad per line: the M220's encoders (Iurian et al. 2005's conversion table)
WEIGHTS = {"tracking": 1.0, "tracking_abs": 0.3, "effort": 0.001, "smoothness": 0.01}


def test_float_and_array_forms_give_the_same_bits():
    rng = np.random.default_rng(0)
    theta, omega, noise = rng.normal(0, 3, 200), rng.normal(0, 50, 200), rng.normal(0, 0.01, 200)
    e, a, a_prev = rng.normal(0, 2e3, 200), rng.uniform(-1, 1, 200), rng.uniform(-1, 1, 200)
    enc = encoder_reading(theta, RES, ARRAY)
    tacho = tacho_reading(omega, 0.0477, noise)
    terms = reward_terms(e, a, a_prev, WEIGHTS, ARRAY)
    total = reward_total(terms)
    for i in range(200):
        assert encoder_reading(float(theta[i]), RES, FLOAT) == enc[i]
        assert tacho_reading(float(omega[i]), 0.0477, float(noise[i])) == tacho[i]
        one = reward_terms(float(e[i]), float(a[i]), float(a_prev[i]), WEIGHTS, FLOAT)
        assert all(one[k] == terms[k][i] for k in one) and reward_total(one) == total[i]


def test_an_encoder_counts_whole_lines_passed():
    """floor(θ/res)·res: never above θ, less than one line below it, and half a line below zero reads
    minus one line (an incremental counter, not rounding)."""
    theta = np.linspace(-1.0, 1.0, 10001)
    reading = encoder_reading(theta, RES, ARRAY)
    assert np.all(reading <= theta + 1e-15) and np.all(theta - reading < RES * (1 + 1e-9))
    assert encoder_reading(-0.5 * RES, RES, FLOAT) == -RES
    assert encoder_reading(0.5 * RES, RES, FLOAT) == 0.0
    assert np.allclose(reading / RES, np.round(reading / RES))


def test_reward_terms_are_bounded_and_a_diverged_step_scores_below_any_other():
    weights = {"tracking": 2.0, "tracking_abs": 7.0, "effort": 0.5, "smoothness": 3.0}
    e = np.array([0.0, 1.0, -1e9, np.inf])  # an error far outside the output scale is capped at OBS_CLIP
    a, a_prev = np.array([0.0, 1.0, -1.0, 1.0]), np.array([0.0, -1.0, 1.0, -1.0])
    terms = reward_terms(e, a, a_prev, weights, ARRAY)
    assert terms["reward_tracking"][2] == terms["reward_tracking"][3] == -2.0 * OBS_CLIP
    assert terms["reward_tracking_abs"][2] == terms["reward_tracking_abs"][3] == -7.0 * OBS_CLIP
    assert terms["reward_tracking_abs"][1] == -7.0 and terms["reward_tracking_abs"][0] == 0.0
    for name, w in (("reward_effort", 0.5), ("reward_smoothness", 4 * 3.0)):
        assert np.all(terms[name] <= 0.0) and terms[name].min() == -w  # a², (a - a_prev)² at most 1, 4
    worst = reward_total(terms).min()
    assert diverged_reward(weights) == worst - 1.0


def test_the_absolute_term_prices_small_errors_as_iae_does():
    """At e/s = 0.01 (a set-point's last 3.5 mrad on Kang's 20 deg scale) the squared term is 1 % of the
    absolute one; at e/s = 1 they are equal: the absolute term shifts the reward's weight to small errors.
    Off (w_a = 0, every scenario's default) the total is the three-term reward to the last bit."""
    w = {"tracking": 1.0, "tracking_abs": 1.0, "effort": 0.0, "smoothness": 0.0}
    small, large = (reward_terms(x, 0.0, 0.0, w, FLOAT) for x in (0.01, 1.0))
    assert small["reward_tracking"] == pytest.approx(0.01 * small["reward_tracking_abs"])
    assert large["reward_tracking"] == large["reward_tracking_abs"] == -1.0
    off = {"tracking": 1.0, "tracking_abs": 0.0, "effort": 0.001, "smoothness": 0.01}
    rng = np.random.default_rng(0)
    e, a, ap = rng.normal(size=(3, 1000))
    t = reward_terms(e, a, ap, off, ARRAY)
    assert np.array_equal(reward_total(t), t["reward_tracking"] + t["reward_effort"] + t["reward_smoothness"])


def test_observations_are_finite_float32_whichever_form_comes_in():
    clean = [0.5, -2.0, 1e5]
    out = sanitize_observation(clean)
    assert out.dtype == np.float32 and np.array_equal(out, np.array(clean, np.float32))
    assert np.array_equal(sanitize_observation(np.array([clean])), out[None])
    for bad in ([np.nan, 1.0, 2.0], [1.0, np.nan, 2.0], [1.0, 2.0, np.inf], [-1e7, 0.0, 0.0]):
        fixed = sanitize_observation(bad)
        assert fixed.dtype == np.float32 and np.all(np.isfinite(fixed)) and np.abs(fixed).max() <= OBS_CLIP
        assert np.array_equal(fixed, sanitize_observation(np.array(bad)))
    assert sanitize_observation([np.nan, 1.0])[0] == 0.0
    assert sanitize_observation([-np.inf, 1.0])[0] == -OBS_CLIP


def test_observation_layout_slices_tile_the_vector_in_order():
    layout = observation_layout(2, 5, 3, True, 1)
    sizes = layout.structure()
    assert sizes == {
        "sensors": 2,
        "reference": 1,
        "preview": 5,
        "previous_action": 1,
        "history": 9,
        "privileged": 3,
    }
    stop = 0
    for name, n in sizes.items():
        s = layout.slice(name)
        assert (s.start, s.stop) == (stop, stop + n)
        stop += n
    assert stop == layout.size
    parts = {name: [float(i)] * n for i, (name, n) in enumerate(sizes.items())}
    packed = layout.pack(parts)
    assert packed == [float(i) for i, n in enumerate(sizes.values()) for _ in range(n)]
    rows = layout.pack({k: np.array([v, v]) for k, v in parts.items()})
    assert rows.shape == (2, layout.size) and rows[1].tolist() == packed
    assert observation_layout(1, 0, 0, False, 1).names == ("sensors", "reference", "previous_action")
    with pytest.raises(KeyError, match="no block 'torque'"):
        layout.slice("torque")
