"""A closed-loop drive log: what a lab records while its drive runs under its own controller (the EMPS
benchmark's data, or a user's drive), read by the one drive-log schema and reader
(frictiongym.envs.measured.drive_columns; docs/identification.md, "Drive logs"). A closed-loop log holds
at least time_s, position_<unit>, reference_<unit> (the controller's set-point), command_V (the drive
command as logged, including any injected disturbance) and the drive gain ('# drive_gain_n_per_v =' for
a linear drive, '# drive_gain_nm_per_v =' for a rotary one); optionally disturbance_V (the injected part
of command_V, e.g. test pulses) and the lab controller's kp_per_s and kv_v_per_unit_s (eq. 6 of the EMPS
description).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from frictiongym.envs import measured
from frictiongym.envs.config import ConfigError
from frictiongym.envs.records import atomic_text

EMPS_DIR = "published/emps"  # under configs/
EMPS_SETS = {"estimation": "DATA_EMPS.mat", "validation": "DATA_EMPS_PULSES.mat"}
# EMPS .mat variable -> meaning (EMPS §2.2; units corrected in configs/published/emps/README.md)
EMPS_NAMES = {"t": "time", "qm": "position", "qg": "reference", "vir": "command", "pulses_N": "disturbance"}


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
        scale = measured.UNIT_OF[ref[10:]][1] if ref.startswith("reference_") else 1.0  # CSV unit -> SI
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
    """A closed-loop drive log of the one schema (envs/measured.py drive_columns: a CSV of its columns or
    a .mat with the EMPS variable names), which must hold a position, a reference, a command in V and the
    drive gain. Errors name the file and the column."""
    c = measured.drive_columns(path)
    missing = [role for role in ("position", "reference") if getattr(c, role) is None]
    if missing or c.command_unit != "V":
        need = "position_<unit>, reference_<unit> and command_V (a closed-loop log)"
        raise ConfigError("header", f"needs {need}; the file lacks {missing or ['command_V']}", c.source)
    gain = {"m": "drive_gain_n_per_v", "rad": "drive_gain_nm_per_v"}[c.unit]
    if gain not in c.scalars:
        raise ConfigError(gain, f"no '# {gain} = value' line (the drive gain)", c.source)
    roles = ("time", "reference", "disturbance")
    return _checked(
        DriveLog(
            t=c.t,
            position=c.position,
            reference=c.reference,
            command=c.command,
            disturbance=c.disturbance if c.disturbance is not None else np.zeros(len(c.t)),
            drive_gain=c.scalars[gain],
            unit=c.unit,
            source=c.source,
            kp=c.scalars.get("kp_per_s"),
            kv=c.scalars.get("kv_v_per_unit_s"),
            provenance=c.provenance,
            columns=tuple((role, c.names[role]) for role in roles if role in c.names),
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
