"""The lab's inverse-model identification (agents/lab/drive_log.py, idim.py) on the EMPS measurements: the
published IDIM-LS numbers recomputed from the data, what the data say beyond the description, the CSV
path a lab takes with its own drive, and the friction-structure table's contract."""

from __future__ import annotations

import numpy as np
import pytest

from frictiongym.agents.lab import idim
from frictiongym.agents.lab.drive_log import emps_log, read_drive_log, write_drive_log
from frictiongym.agents.reproduce import janot2019
from frictiongym.agents.reproduce.report import published_node
from frictiongym.envs.config import ConfigError


@pytest.fixture(scope="module")
def estimation():
    return emps_log("estimation")


@pytest.fixture(scope="module")
def validation():
    return emps_log("validation")


def test_the_emps_logs_are_read_in_si_with_the_description_gains(estimation, validation):
    for log in (estimation, validation):
        assert log.unit == "m" and log.period == pytest.approx(1e-3, rel=1e-4)  # 1 kHz, §2.2
        assert log.drive_gain == pytest.approx(35.15, abs=0.005)  # gτ, eq. (7)
        assert (log.kp, log.kv) == (160.18, 243.45)  # eq. (6)
    assert not estimation.disturbance.any() and set(np.unique(validation.disturbance)) == {0.0, 5.0}


def test_the_estimation_positions_are_on_the_encoder_grid_of_50_nm(estimation):
    # 50,000 counts/rev (§2.2) through a 2.5 mm/rev screw: every step of qm is a multiple of 5e-8 m
    counts = np.diff(estimation.position) / 5e-8
    assert np.abs(counts - np.round(counts)).max() < 1e-6
    assert np.abs(np.round(counts)).min() == 0  # and it does rest on one count


def test_the_position_noise_above_the_grid_is_a_fraction_of_a_count(estimation):
    """The measured noise floor behind emps.yaml's noise_std_m = 0: what a 7-point cubic Savitzky-Golay
    fit leaves of qm (its high-frequency part; the motion itself is smooth at 1 kHz) is 1.7e-8 m rms,
    about the 5e-8 m grid's own rounding (q/sqrt(12) = 1.44e-8 m): the noise beyond quantisation is at
    most sqrt(1.72² - 1.44²) ≈ 0.9e-8 m, a fifth of a count."""
    from scipy.signal import savgol_filter

    q = estimation.position
    rest = (q - savgol_filter(q, 7, 3))[50:-50]
    rounding = 5e-8 / np.sqrt(12)
    assert rounding < rest.std() < 1.25 * rounding
    assert np.sqrt(rest.std() ** 2 - rounding**2) < 0.2 * 5e-8


def test_the_logged_command_is_eq6_plus_the_pulses_in_volts(estimation, validation):
    # ν = kp·kv·(qg - qm) - kv·q̇m with the 2-tap FIR velocity (§2.2); the pulses jump the logged ν by 5
    for log, tol in ((estimation, 0.02), (validation, 0.15)):  # V; the validation qm is processed (README)
        q = log.position
        qf = 0.5 * q + 0.5 * np.concatenate([[q[0]], q[:-1]])
        dq = np.concatenate([[0.0], np.diff(qf)]) / 1e-3
        nu = log.kp * log.kv * (log.reference - q) - log.kv * dq
        assert np.abs(log.command - log.disturbance - nu)[10:].max() < tol  # V (the command spans ±4..9 V)
    edges = np.flatnonzero(np.diff(validation.disturbance) > 0)
    assert len(edges) == 25
    assert np.diff(validation.command)[edges] == pytest.approx(5.0, abs=0.3)


@pytest.mark.parametrize("delay", [0, 1])
def test_a_csv_of_the_documented_columns_gives_the_same_identification_as_the_mat(
    estimation, tmp_path, delay
):
    p = tmp_path / "drive.csv"
    write_drive_log(p, estimation)
    log = read_drive_log(p)
    np.testing.assert_array_equal(log.position, estimation.position)
    assert (log.drive_gain, log.kp, log.kv) == (estimation.drive_gain, estimation.kp, estimation.kv)
    cfg = idim.IdimSettings(delay_samples=delay)
    a = idim.fit("coulomb_viscous", idim.states(estimation, cfg), cfg)
    b = idim.fit("coulomb_viscous", idim.states(log, cfg), cfg)
    np.testing.assert_array_equal(a.theta, b.theta)


def test_a_csv_without_the_needed_columns_is_refused_naming_them(tmp_path):
    p = tmp_path / "drive.csv"
    p.write_text("# drive_gain_n_per_v = 35\ntime_s,position_m,command_V\n0,0,0\n0.001,0,0\n")
    with pytest.raises(
        ConfigError, match=r"needs position_<unit>, reference_<unit> and command_V .* \['reference'\]"
    ):
        read_drive_log(p)


@pytest.mark.slow  # reproduces a paper's estimates
def test_idim_ls_reproduces_the_published_estimates_their_std_and_the_cross_test():
    rows = list(janot2019.idim_rows(idim.emps_table()))
    assert len(rows) == 27
    failed = [r for r in rows if not r["pass"]]
    assert not failed, failed
    m = next(r for r in rows if r["id"] == "emps.idim.mass_kg")
    assert m["simulated"] == pytest.approx(95.1089, abs=1e-4)


def test_scipy_default_padding_would_not_reproduce_them(estimation):
    # the reason for matlab_filtfilt: scipy's padlen 3·n moves the Coulomb estimate by 0.04 N (§3.4: 20.3935)
    from scipy import signal

    b, a = signal.butter(4, 0.2)
    q = signal.filtfilt(b, a, estimation.position)
    assert np.abs(q - idim.matlab_filtfilt(b, a, estimation.position))[:20].max() > 1e-9


@pytest.mark.slow  # the EMPS's whole model table: every structure and delay fitted (12 s)
def test_the_offset_and_asymmetric_coulomb_levels_are_not_identifiable_together():
    row = next(r for r in idim.emps_table() if r.fit.structure == "coulomb_viscous_asym_offset")
    assert row.fit.condition_number > idim.CONDITION_LIMIT and not row.fit.identifiable


def test_every_fit_sees_only_the_estimation_set(estimation, validation):
    # changing the validation log changes the cross-test, never the parameters
    cfg = idim.IdimSettings()
    rows = idim.model_table(estimation, validation, ("coulomb_viscous",), (0,), cfg)
    doubled = idim.model_table(estimation, estimation, ("coulomb_viscous",), (0,), cfg)
    np.testing.assert_array_equal(rows[0].fit.theta, doubled[0].fit.theta)
    assert rows[0].validation.relative_error_pct != doubled[0].validation.relative_error_pct
    assert doubled[0].validation.relative_error_pct == pytest.approx(rows[0].fit.relative_error_pct)


@pytest.mark.slow  # the EMPS's whole model table: every structure and delay fitted (12 s)
def test_a_structure_of_the_suite_beats_both_published_models_on_the_validation_set():
    table = idim.emps_table()
    best = janot2019.best(table)
    pub = published_node("emps2019").section("idim_ls").section("cross_test").number("relative_error_pct")
    asym = next(r for r in table if r.fit.structure == "coulomb_viscous_asym" and r.delay_samples == 0)
    assert best.fit.identifiable
    assert best.validation.relative_error_pct < min(pub, asym.validation.relative_error_pct)


@pytest.mark.slow  # the EMPS's whole model table: every structure and delay fitted (12 s)
def test_the_profile_interval_of_a_nonlinear_parameter_brackets_its_estimate():
    for r in idim.emps_table():
        if r.fit.nonlinear is not None:
            iv = r.fit.nonlinear[1]
            assert iv.low < iv.value < iv.high
            lo, hi = idim.STRUCTURES[r.fit.structure].search
            assert lo <= iv.value <= hi


def test_the_bristle_state_turns_over_about_its_presliding_length():
    # from s = -1, moving at v for a travel x: s = 1 - 2·exp(-x/L); at x = L·ln 2, s = 0
    h, v, length = 1e-3, 1e-3, 1e-5
    s = idim.bristle_state(np.concatenate([[-v] * 200, [v] * 200]), length, h)
    k = int(np.argmax(s[200:] >= 0))
    assert (k + 1) * v * h == pytest.approx(length * np.log(2), abs=v * h)


def test_the_maxwell_slip_state_is_the_simulators_elements_from_rest():
    """From rest at constant speed each element is a bristle state 1 - exp(-x/L_k), L_k = r_k·c·L
    (envs/friction.py's shares and lengths); their sum starts with the slope 1/L of one bristle of length
    L, the simulator's property that the small-motion stiffness is LuGre's."""
    from frictiongym.envs.friction import MAXWELL_SLIP_LENGTHS, MAXWELL_SLIP_SHARES

    h, v, length = 1e-3, 1e-4, 1e-4  # 0.001 L per sample
    x = v * h * np.arange(1, 401)
    c = sum(a / r for a, r in zip(MAXWELL_SLIP_SHARES, MAXWELL_SLIP_LENGTHS, strict=True))
    expect = sum(
        a * (1 - np.exp(-x / (r * c * length)))
        for a, r in zip(MAXWELL_SLIP_SHARES, MAXWELL_SLIP_LENGTHS, strict=True)
    )
    states = idim.States(np.zeros(400), np.full(400, v), np.zeros(400), np.zeros(400), h, "")
    cols = idim.STRUCTURES["maxwell_slip_asym"].columns(states, length)
    np.testing.assert_allclose(cols[2], expect, rtol=1e-12)  # the positive-side state column
    assert expect[0] / x[0] == pytest.approx(1 / length, rel=0.01)


@pytest.mark.slow  # the EMPS's whole model table: every structure and delay fitted (12 s)
def test_kangs_static_excess_acts_only_inside_the_stick_band_and_the_emps_data_do_not_support_it():
    from frictiongym.envs.friction import KANG_STICK_BAND
    from frictiongym.envs.plants import plant_spec

    band = KANG_STICK_BAND * plant_spec("emps").drive_friction.vs
    dq = np.array([0.1 * band, band, 5 * band, -0.1 * band])
    states = idim.States(np.zeros(4), dq, np.zeros(4), np.zeros(4), 1e-3, "")
    excess = idim.STRUCTURES["kang_asym"].columns(states, float("nan"))[-2:]
    assert excess[0][0] > 0.99 and excess[0][2] < 1e-10 and excess[1][3] < -0.99
    row = next(r for r in idim.emps_table() if r.fit.structure == "kang_asym" and r.delay_samples == 0)
    for name in ("stick_excess_pos_n", "stick_excess_neg_n"):  # no stiction peak resolved on the drive
        iv = row.fit.intervals[row.fit.names.index(name)]
        assert iv.low < 0 < iv.high
