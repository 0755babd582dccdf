"""A closed-loop drive log: what a lab records while its drive runs under its own controller (the EMPS
benchmark's data, or a user's drive). One reader for both the EMPS .mat files and a CSV of the documented
columns, on top of the world's one file loader (frictiongym.envs.measured).

CSV columns: time_s, position_m | position_rad | position_deg, reference_m | reference_rad | reference_deg
(the controller's set-point), command_V (the drive command as logged, including any injected disturbance),
optionally disturbance_V (the part of command_V that was injected, e.g. test pulses). Scalars as
'# name = value' lines: drive_gain_n_per_v (linear drive) or drive_gain_nm_per_v (rotary), optionally the
lab controller's kp_per_s and kv_v_per_unit_s (eq. 6 of the EMPS description).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from frictiongym.envs import measured
from frictiongym.envs.config import ConfigError
from frictiongym.envs.records import atomic_text
from frictiongym.envs.units import deg_to_rad

EMPS_DIR = "published/emps"  # under configs/
EMPS_SETS = {"estimation": "DATA_EMPS.mat", "validation": "DATA_EMPS_PULSES.mat"}
# EMPS .mat variable -> meaning (EMPS §2.2; units corrected in configs/published/emps/README.md)
EMPS_NAMES = {"t": "time", "qm": "position", "qg": "reference", "vir": "command", "pulses_N": "disturbance"}
POSITION_UNITS = {"m": 1.0, "rad": 1.0, "deg": deg_to_rad(1.0)}  # column suffix -> factor to SI
UNIT_OF = {"m": "m", "rad": "rad", "deg": "rad"}


@dataclass(frozen=True)
class DriveLog:
    """A closed-loop log in SI: t (s), position and reference (m or rad, `unit`), command (V, as logged,
    including the injected disturbance), disturbance (V, the injected part; zeros if none), drive gain
    (N/V or N·m/V), the lab controller's gains if logged (kp 1/s, kv V per unit/s), source, provenance."""

    t: np.ndarray
    position: np.ndarray
    reference: np.ndarray
    command: np.ndarray
    disturbance: np.ndarray
    drive_gain: float
    unit: str
    source: str
    kp: float | None = None
    kv: float | None = None
    provenance: tuple[str, ...] = ()
    columns: tuple[tuple[str, str], ...] = ()  # (role, name in the file): time, reference, disturbance

    def column(self, role: str) -> str | None:
        """The file's name of the signal with this role (None if the log has none)."""
        return dict(self.columns).get(role)

    def replay(self) -> dict:
        """Scenario overrides that replay this log: its reference and, if it has one, its injected
        disturbance as a force (drive gain x volts) on the load (envs/scenario.py, type recorded)."""
        t, ref = self.column("time"), self.column("reference") or ""
        scale = POSITION_UNITS[ref[10:]] if ref.startswith("reference_") else 1.0  # CSV unit -> SI
        out: dict = {
            "reference": {
                "type": "recorded",
                "file": self.source,
                "signal": ref,
                "time_signal": t,
                "scale": scale,
            }
        }
        if self.column("disturbance") is not None and np.any(self.disturbance):
            out["disturbance"] = {
                "type": "recorded",
                "file": self.source,
                "signal": self.column("disturbance"),
                "time_signal": t,
                "scale": self.drive_gain,
            }
        return out

    @property
    def period(self) -> float:
        """The mean sampling period (s)."""
        return float((self.t[-1] - self.t[0]) / (len(self.t) - 1))

    @property
    def force(self) -> np.ndarray:
        """The drive force (N; N·m for a rotary drive): gain times the logged command (EMPS eq. 7)."""
        return self.drive_gain * self.command


def emps_log(which: str) -> DriveLog:
    """The EMPS estimation ('estimation', DATA_EMPS.mat) or validation ('validation', with pulses) set."""
    if which not in EMPS_SETS:
        raise ConfigError("emps", f"unknown set {which!r}; available: {sorted(EMPS_SETS)}")
    return read_drive_log(f"{EMPS_DIR}/{EMPS_SETS[which]}")


def read_drive_log(path: str | Path) -> DriveLog:
    """A drive log: a .mat with the EMPS variable names (t, qm, qg, vir, gtau, kp, kv, optionally
    pulses_N), or a CSV of the columns in the module docstring. Errors name the file and the column."""
    rec = measured.load(path)
    if "qm" in rec.signals:
        measured.require(rec, ["t", "qm", "qg", "vir"])
        n = len(rec.signals["t"])
        return _checked(
            DriveLog(
                t=rec.time("t"),
                position=rec.signal("qm"),
                reference=rec.signal("qg"),
                command=rec.signal("vir"),
                disturbance=rec.signals.get("pulses_N", np.zeros(n)),
                drive_gain=rec.scalar("gtau"),
                unit="m",
                source=rec.source,
                kp=rec.scalars.get("kp"),
                kv=rec.scalars.get("kv"),
                provenance=rec.provenance,
                columns=(("time", "t"), ("reference", "qg"))
                + ((("disturbance", "pulses_N"),) if "pulses_N" in rec.signals else ()),
            )
        )
    pos = [c for c in rec.signals if c.startswith("position_") and c[9:] in POSITION_UNITS]
    ref = [c for c in rec.signals if c.startswith("reference_") and c[10:] in POSITION_UNITS]
    need = "time_s, position_m|_rad|_deg, reference_m|_rad|_deg, command_V"
    if len(pos) != 1 or len(ref) != 1 or "time_s" not in rec.signals or "command_V" not in rec.signals:
        raise ConfigError("header", f"need one each of {need}; got {sorted(rec.signals)}", rec.source)
    unit = UNIT_OF[pos[0][9:]]
    if UNIT_OF[ref[0][10:]] != unit:
        raise ConfigError(ref[0], f"the reference must be in the position's unit ({unit})", rec.source)
    gains = {"m": "drive_gain_n_per_v", "rad": "drive_gain_nm_per_v"}
    n = len(rec.signals["time_s"])
    return _checked(
        DriveLog(
            t=rec.time("time_s"),
            position=rec.signal(pos[0]) * POSITION_UNITS[pos[0][9:]],
            reference=rec.signal(ref[0]) * POSITION_UNITS[ref[0][10:]],
            command=rec.signal("command_V"),
            disturbance=rec.signals.get("disturbance_V", np.zeros(n)),
            drive_gain=rec.scalar(gains[unit]),
            unit=unit,
            source=rec.source,
            kp=rec.scalars.get("kp_per_s"),
            kv=rec.scalars.get("kv_v_per_unit_s"),
            provenance=rec.provenance,
            columns=(("time", "time_s"), ("reference", ref[0]))
            + ((("disturbance", "disturbance_V"),) if "disturbance_V" in rec.signals else ()),
        )
    )


def _checked(log: DriveLog) -> DriveLog:
    """Refuse logs the identification cannot use: too short, or not uniformly sampled (the filters and
    finite differences assume one period; 1 % of it is the tolerance)."""
    if len(log.t) < 200:
        raise ConfigError("log", f"{len(log.t)} samples: the identification needs at least 200", log.source)
    dt = np.diff(log.t)
    if np.ptp(dt) > 0.01 * dt.mean():
        raise ConfigError(
            "time", f"not uniformly sampled: periods from {dt.min():.6g} to {dt.max():.6g} s", log.source
        )
    if not 0.0 < log.drive_gain < 1e6:
        raise ConfigError("drive_gain", f"{log.drive_gain} must be positive and finite", log.source)
    for name, gain in (("kp", log.kp), ("kv", log.kv)):  # the lab controller's gains, if logged
        if gain is not None and not (math.isfinite(gain) and gain > 0):
            raise ConfigError(name, f"{gain} must be positive and finite", log.source)
    return log


def write_drive_log(path: str | Path, log: DriveLog) -> None:
    """Write a log as a CSV that read_drive_log reads back (SI columns, scalars and provenance as '#')."""

    gain = {"m": "drive_gain_n_per_v", "rad": "drive_gain_nm_per_v"}[log.unit]
    head = [f"# {line}" for line in log.provenance] + [f"# {gain} = {log.drive_gain!r}"]
    if log.kp is not None and log.kv is not None:
        head += [f"# kp_per_s = {log.kp!r}", f"# kv_v_per_unit_s = {log.kv!r}"]
    u = log.unit
    cols = ["time_s", f"position_{u}", f"reference_{u}", "command_V", "disturbance_V"]
    data = np.column_stack([log.t, log.position, log.reference, log.command, log.disturbance])
    body = [",".join(cols)] + [",".join(repr(float(x)) for x in r) for r in data]
    atomic_text(Path(path), "\n".join(head + body) + "\n")
