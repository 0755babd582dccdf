"""Bringing a drive into the suite (agents/lab/drive_workflow.py, scripts/identify.py idim|check): a lab's
CSV logs give the same identification as the EMPS .mat files, a draft preset the suite loads and
simulates, and the check of that preset against the measurement."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from frictiongym.agents.lab import drive_workflow
from frictiongym.agents.lab.drive_log import emps_log, write_drive_log
from frictiongym.envs.config import ConfigError
from frictiongym.envs.plants import plant_spec
from frictiongym.envs.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]


def test_the_encoder_grid_of_a_log_is_found_or_reported_absent():
    q = np.array([0.0, 5e-8, 1.5e-7, 1.5e-7, 2.0e-7])
    assert drive_workflow.resolution(q) == pytest.approx(5e-8)
    assert drive_workflow.resolution(np.array([0.0, 5e-8, 1.23e-7])) is None
    assert drive_workflow.resolution(emps_log("estimation").position) == pytest.approx(5e-8)
    assert drive_workflow.resolution(emps_log("validation").position) is None  # processed (README)


def test_a_scenario_takes_a_preset_file_and_names_a_bad_plant(tmp_path):
    p = tmp_path / "drive.yaml"
    p.write_text((ROOT / "configs/plants/emps.yaml").read_text())
    assert load_scenario("emps_tracking", overrides={"plant": str(p)}).spec.name == "emps"
    with pytest.raises(ConfigError, match="plant: 'nope' is neither a preset"):
        load_scenario("emps_tracking", overrides={"plant": "nope"})


@pytest.mark.slow
def test_a_lab_takes_its_csv_logs_from_identification_to_a_checked_preset(tmp_path):
    # the documented path (docs/emps.md) on the EMPS logs written as CSV: idim -> plant.yaml -> check
    est, val = tmp_path / "est.csv", tmp_path / "val.csv"
    write_drive_log(est, emps_log("estimation"))
    write_drive_log(val, emps_log("validation"))
    out = tmp_path / "id"
    run = [sys.executable, str(ROOT / "scripts/identify.py")]
    proc = subprocess.run(
        [*run, "idim", "--csv", str(est), "--validation", str(val), "--delays", "0", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    assert "| coulomb_viscous | 0 | 4.083 | 5.982 |" in (out / "report.md").read_text()  # §3.4's numbers
    preset = yaml.safe_load((out / "plant.yaml").read_text())
    assert preset["carriage"]["mass_kg"] == pytest.approx(95.1089, abs=1e-4)
    assert preset["sensors"]["encoder"]["resolution_m"] == pytest.approx(5e-8)
    spec = plant_spec(out / "plant.yaml", check_ranges=True)  # a valid preset, randomisable
    assert spec.drive_friction.bias == pytest.approx(3.1648, abs=1e-4)
    proc = subprocess.run(
        [*run, "check", "--csv", str(val), "--plant", str(out / "plant.yaml"), "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    closed = next(ln for ln in (out / "check.md").read_text().splitlines() if "| closed |" in ln)
    force = float(closed.split("|")[6])
    assert force < 10.0  # %, the simulated force against the measured one (§3.5's own model: 8.94 %)


def test_a_rotary_log_gets_no_linear_draft_preset(tmp_path):
    log = emps_log("estimation")
    p = tmp_path / "rot.csv"
    text = ["# drive_gain_nm_per_v = 0.5", "time_s,position_rad,reference_rad,command_V"]
    text += [
        f"{t},{q * 40},{r * 40},{u}"
        for t, q, r, u in zip(log.t, log.position, log.reference, log.command, strict=True)
    ]
    p.write_text("\n".join(text) + "\n")
    r = drive_workflow.identify(
        drive_workflow.IdentifyOptions(p, structures=("coulomb_viscous",), delays=(0,))
    )
    with pytest.raises(ConfigError, match="the draft preset is a linear drive"):
        drive_workflow.draft_preset(r)
    assert [x.name for x in drive_workflow.write_identification(r, tmp_path / "out")] == [
        "report.md",
        "result.json",
    ]


@pytest.mark.slow  # an identification study
def test_the_measurement_chooses_no_actuation_delay_and_stiff_bristles():
    # the preset's two choices made on the estimation log (configs/plants/emps.yaml): the simulated
    # force is closest to the measured one with no delay beyond the hold, and with the preset's σ0
    delay = drive_workflow.scan("delay_s", (0.0, 0.001))
    assert delay[0][1].relative_error_pct["force"] < delay[1][1].relative_error_pct["force"] - 1.0
    sigma = drive_workflow.scan("sigma0_n_per_m", (2.6e5, 2.6e7))
    assert sigma[1][1].relative_error_pct["force"] < 0.6 * sigma[0][1].relative_error_pct["force"]
    with pytest.raises(ConfigError, match="'mass' not in"):
        drive_workflow.scan("mass", (1.0,))
