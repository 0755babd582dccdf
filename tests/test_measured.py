"""Recorded signals (envs/measured.py): the one loader of measured logs (.mat and CSV), its scalars and
its errors, which name the file and the variable or row."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from frictiongym.envs import measured
from frictiongym.envs.config import ConfigError, configs_dir

EMPS = configs_dir() / "published" / "emps"


@pytest.mark.parametrize(
    ("name", "md5"),
    [
        ("DATA_EMPS.mat", "a30f88237b73c4f5058d6b30c5cdc4e7"),
        ("DATA_EMPS_PULSES.mat", "0cf87b3b78b4519257b1fe2e75f28a81"),
    ],
)
def test_the_emps_data_in_the_project_are_the_benchmark_files_unchanged(name, md5):
    assert hashlib.md5((EMPS / name).read_bytes()).hexdigest() == md5
    assert md5 in (EMPS / "README.md").read_text()


def test_a_mat_log_gives_its_vectors_as_signals_and_its_1x1_variables_as_scalars():
    rec = measured.load("published/emps/DATA_EMPS.mat")  # relative to configs/
    assert set(rec.signals) == {"t", "qm", "qg", "vir"}
    assert {"gtau", "kp", "kv"} <= set(rec.scalars)
    assert rec.scalars["kp"] == 160.18 and rec.scalars["kv"] == 243.45  # EMPS eq. (6)
    assert len(rec.signal("t")) == 24841 and rec.time("t")[-1] == pytest.approx(24.84)  # §2.2
    with pytest.raises(ConfigError, match="qx: no such signal"):
        rec.signal("qx")


def test_a_csv_log_reads_columns_scalars_and_provenance(tmp_path):
    p = tmp_path / "log.csv"
    p.write_text("# rig A, 2026-11-30\n# drive_gain_n_per_v = 35.0\ntime_s,x\n0,1\n0.001,2\n0.002,3.5\n")
    rec = measured.load(p)
    assert rec.scalars == {"drive_gain_n_per_v": 35.0}
    assert rec.provenance == ("rig A, 2026-11-30",)
    np.testing.assert_array_equal(rec.signal("x"), [1.0, 2.0, 3.5])


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("time_s,x\n0,1\n0.001,a\n", "x: row 3: not a number"),
        ("time_s,x\n0,1\n0.001,nan\n", "x: row 3: nan is not finite"),
        ("time_s,x\n0,1\n0.001\n", "row 3: 1 values for 2 columns"),
        ("time_s,time_s\n0,1\n1,2\n", "repeated column names"),
        ("time_s,x\n0,1\n", "at least 2 data rows"),
    ],
)
def test_a_malformed_csv_log_is_refused_naming_the_column_and_row(tmp_path, text, match):
    p = tmp_path / "bad.csv"
    p.write_text(text)
    with pytest.raises(ConfigError, match=match) as e:
        measured.load(p)
    assert str(p) in str(e.value)


def test_a_missing_file_an_unknown_format_and_a_time_that_goes_back_are_refused(tmp_path):
    with pytest.raises(ConfigError, match="not found"):
        measured.load(tmp_path / "nope.mat")
    (tmp_path / "log.txt").write_text("1\n")
    with pytest.raises(ConfigError, match="unknown log format"):
        measured.load(tmp_path / "log.txt")
    (tmp_path / "bad.mat").write_bytes(b"not a mat file at all")
    with pytest.raises(ConfigError, match="not a readable MATLAB file"):
        measured.load(tmp_path / "bad.mat")
    p = tmp_path / "back.csv"
    p.write_text("time_s,x\n0,1\n0.002,2\n0.001,3\n")
    with pytest.raises(ConfigError, match="time_s: time must increase strictly; it does not at sample 2"):
        measured.load(p).time("time_s")


def test_loaded_signals_are_read_only_so_the_cache_cannot_be_corrupted():
    x = measured.load("published/emps/DATA_EMPS.mat").signal("qm")
    with pytest.raises(ValueError):
        x[0] = 1.0


def test_one_drive_log_schema_serves_the_experiment_fits_and_idim(tmp_path):
    """One CSV of the schema is read by the experiment reader (fits.read_log) and the closed-loop reader
    (drive_log.read_drive_log) through measured.drive_columns: the same time, command and position, in
    SI from degrees; and the schema's errors name the column: a role given twice, two kinds of unit."""

    from frictiongym.agents.lab.drive_log import read_drive_log
    from frictiongym.agents.lab.fits import read_log

    t = np.arange(300) * 1e-3
    deg = 10 * np.sin(2 * np.pi * t)
    body = "".join(f"{a},{b},{c},{d}\n" for a, b, c, d in zip(t, deg, deg, 0.1 * deg, strict=True))
    path = tmp_path / "drive.csv"
    path.write_text("# drive_gain_nm_per_v = 2.0\ntime_s,position_deg,reference_deg,command_V\n" + body)
    experiment, closed = read_log(path), read_drive_log(path)
    np.testing.assert_array_equal(experiment.t, closed.t)
    np.testing.assert_array_equal(experiment.u, closed.command)
    np.testing.assert_allclose(closed.position, np.deg2rad(deg), rtol=1e-15)
    np.testing.assert_array_equal(experiment.position, closed.position)
    assert closed.unit == "rad" and closed.drive_gain == 2.0 and experiment.command_unit == "V"
    two = tmp_path / "two.csv"
    two.write_text("time_s,position_rad,position_deg,command_V\n0,0,0,0\n0.001,0,0,0\n")
    with pytest.raises(ConfigError, match="a second position column") as e:
        measured.drive_columns(two)
    assert e.value.field == "position_deg"
    mixed = tmp_path / "mixed.csv"
    mixed.write_text("time_s,position_m,reference_rad,command_V\n0,0,0,0\n0.001,0,0,0\n")
    with pytest.raises(ConfigError, match="a drive is linear or rotary"):
        measured.drive_columns(mixed)
