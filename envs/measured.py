"""Recorded signals: the one loader of a measured log (a MATLAB .mat file, read with scipy.io.loadmat, or a
CSV file), used by scenarios that replay a measured reference or disturbance and by the lab's
identification on real data (frictiongym.agents.lab).

A CSV log: '#' lines are provenance, except '# name = number' lines, which give scalars (a drive gain, a
controller gain); then a header row and one row per sample. A .mat log: 1-D variables (column or row
vectors) are signals, 1x1 variables scalars. Values are as stored: units are the caller's (the column
names of a CSV carry them, e.g. position_m, command_V).
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

import numpy as np

from .config import ConfigError, configs_dir
from .units import deg_to_rad

SAMPLING_PERIOD_S = (1e-6, 0.5)  # a drive's log: from 1 MHz to 2 Hz sampling (s)


@dataclass(frozen=True)
class Recording:
    """Signals (name -> 1-D float array, all of one length), scalars (name -> float) and provenance lines
    of one file."""

    source: str
    signals: dict[str, np.ndarray]
    scalars: dict[str, float] = field(default_factory=dict)
    provenance: tuple[str, ...] = ()

    def signal(self, name: str) -> np.ndarray:
        """The signal called name (an error naming the file and the signals it has)."""
        if name not in self.signals:
            raise ConfigError(name, f"no such signal; the file has {sorted(self.signals)}", self.source)
        return self.signals[name]

    def scalar(self, name: str) -> float:
        """The scalar called name (an error naming the file and the scalars it has)."""
        if name not in self.scalars:
            raise ConfigError(name, f"no such scalar; the file has {sorted(self.scalars)}", self.source)
        return self.scalars[name]

    def time(self, name: str) -> np.ndarray:
        """The signal called name, checked as a sample time: strictly increasing, and its median sampling
        period within SAMPLING_PERIOD_S (a drive's log; a time in milliseconds under a name in seconds
        would make every identified rate 1000 times off)."""
        t = self.signal(name)
        bad = np.flatnonzero(np.diff(t) <= 0)
        if bad.size:
            raise ConfigError(
                name, f"time must increase strictly; it does not at sample {bad[0] + 1}", self.source
            )
        period = float(np.median(np.diff(t)))
        low, high = SAMPLING_PERIOD_S
        if not low <= period <= high:
            raise ConfigError(
                name,
                f"median sampling period {period:.6g} s is outside [{low:g}, {high:g}] s for a drive's log: "
                "is the time in another unit (ms: divide by 1000)?",
                self.source,
            )
        return t


def resolve(path: str | Path) -> Path:
    """A log path as written in a config: absolute, or relative to the working directory, or to the
    project's configs/ folder (e.g. published/emps/DATA_EMPS.mat)."""
    p = Path(path)
    if p.is_absolute() or p.exists():
        return p
    return configs_dir() / p


def load(path: str | Path) -> Recording:
    """Read a .mat or .csv log (cached per path). Errors name the file and the variable or row: a missing
    file, an unreadable one, signals of different lengths, non-numbers and values that are not finite."""
    return _load(str(resolve(path)))


@cache
def _load(path: str) -> Recording:
    p = Path(path)
    if not p.is_file():
        raise ConfigError("file", "not found", path)
    suffix = p.suffix.lower()
    if suffix == ".mat":
        rec = _read_mat(p)
    elif suffix == ".csv":
        rec = _read_csv(p)
    else:
        raise ConfigError("file", f"unknown log format {p.suffix!r}: expected .mat or .csv", path)
    lengths = {k: len(v) for k, v in rec.signals.items()}
    if len(set(lengths.values())) > 1:
        raise ConfigError("signals", f"signals of different lengths: {lengths}", path)
    for name, x in rec.signals.items():
        bad = np.flatnonzero(~np.isfinite(x))
        if bad.size:
            raise ConfigError(name, f"sample {bad[0]}: {x[bad[0]]} is not finite", path)
        x.setflags(write=False)
    return rec


def _read_mat(p: Path) -> Recording:
    from scipy import io  # scipy.io loads only for .mat logs

    try:
        raw = io.loadmat(p)
    except (ValueError, TypeError, OSError, IndexError, NotImplementedError) as e:
        raise ConfigError("file", f"not a readable MATLAB file ({e})", str(p)) from None
    signals, scalars = {}, {}
    for name, v in raw.items():
        if name.startswith("__") or not isinstance(v, np.ndarray) or v.dtype.kind not in "biuf":
            continue
        if v.size == 1:
            scalars[name] = float(v.item())
        elif v.ndim == 2 and 1 in v.shape:
            signals[name] = v.ravel().astype(float)
    prov = (f"{p.name}: {raw['__header__'].decode(errors='replace')}",) if "__header__" in raw else ()
    return Recording(str(p), signals, scalars, prov)


def _read_csv(p: Path) -> Recording:
    lines = p.read_text().splitlines()
    prov, scalars = [], {}
    for line in lines:
        if not line.startswith("#"):
            continue
        text = line[1:].strip()
        key, eq, value = text.partition("=")
        if eq and key.strip().isidentifier():
            try:
                scalars[key.strip()] = float(value)
                continue
            except ValueError:
                pass
        prov.append(text)
    rows = list(csv.reader(line for line in lines if line.strip() and not line.startswith("#")))
    if len(rows) < 3:
        raise ConfigError("log", "needs a header row and at least 2 data rows", str(p))
    header = [h.strip() for h in rows[0]]
    if len(set(header)) != len(header):
        raise ConfigError("header", f"repeated column names: {header}", str(p))
    data = np.empty((len(rows) - 1, len(header)))
    for r, row in enumerate(rows[1:]):
        if len(row) != len(header):
            raise ConfigError("log", f"row {r + 2}: {len(row)} values for {len(header)} columns", str(p))
        for c, text in enumerate(row):
            try:
                data[r, c] = float(text)
            except ValueError:
                raise ConfigError(header[c], f"row {r + 2}: not a number: {text!r}", str(p)) from None
            if not math.isfinite(data[r, c]):
                raise ConfigError(header[c], f"row {r + 2}: {text} is not finite", str(p))
    return Recording(str(p), {h: data[:, c] for c, h in enumerate(header)}, scalars, tuple(prov))


def require(rec: Recording, names: Sequence[str]) -> None:
    """Fail, naming the file and every missing signal, unless rec has all of names."""
    missing = [n for n in names if n not in rec.signals]
    if missing:
        raise ConfigError("signals", f"missing {missing}; the file has {sorted(rec.signals)}", rec.source)


# ------------------------------------------------------------------------------------------- drive logs
# The one drive-log schema (docs/identification.md, "Drive logs"): a CSV's columns by role, each name
# carrying its unit, converted to SI here; a column of another name is kept in the recording, unread.
UNIT_OF = {"m": ("m", 1.0), "rad": ("rad", 1.0), "deg": ("rad", deg_to_rad(1.0))}  # suffix: (SI unit, factor)
SPEED_UNIT_OF = {"m_s": ("m", 1.0), "rad_s": ("rad", 1.0), "deg_s": ("rad", deg_to_rad(1.0))}
COMMAND_UNITS = ("V", "Nm")
# The EMPS benchmark's .mat variables (Janot et al. 2019, §2.2) as the schema's columns and scalars
EMPS_MAT = {"t": "time_s", "qm": "position_m", "qg": "reference_m", "vir": "command_V"}
EMPS_MAT_SCALARS = {"gtau": "drive_gain_n_per_v", "kp": "kp_per_s", "kv": "kv_v_per_unit_s"}


@dataclass(frozen=True)
class DriveColumns:
    """A drive log in the one schema, in SI: time (s), the command as logged (command_unit: V or N·m),
    position, speed and reference in `unit` (m or rad; m/s or rad/s), a hold's speed set-point, the
    injected part of the command (disturbance, V or the .mat's N), segment labels, scalars (drive gain,
    controller gains) and the file's own name of each role's column (for replaying it)."""

    source: str
    t: np.ndarray
    command: np.ndarray
    command_unit: str
    unit: str | None
    position: np.ndarray | None = None
    speed: np.ndarray | None = None
    reference: np.ndarray | None = None
    speed_reference: np.ndarray | None = None
    disturbance: np.ndarray | None = None
    segment: np.ndarray | None = None
    scalars: dict[str, float] = field(default_factory=dict)
    provenance: tuple[str, ...] = ()
    names: dict[str, str] = field(default_factory=dict)  # role -> the file's column name


def drive_columns(path: str | Path) -> DriveColumns:
    """A drive log read by the one schema: a CSV of its columns, or a .mat with the EMPS variable names.

    Columns (units in the name): time_s; command_V or command_Nm; position_m|_rad|_deg and/or
    speed_m_s|_rad_s|_deg_s; optionally reference_<unit> (the controller's set-point), disturbance_V (the
    injected part of the command), segment (an experiment's part: an integer label),
    speed_reference_<unit> (a hold's speed set-point). Scalars as '# name = value' lines:
    drive_gain_n_per_v or drive_gain_nm_per_v, kp_per_s, kv_v_per_unit_s. Errors name the file and the
    column: a role given twice, units of two kinds (m and rad), no command, no position or speed."""
    rec = load(path)
    src, signals, scalars = rec.source, dict(rec.signals), dict(rec.scalars)
    own = {k: k for k in signals}  # the schema's name of each signal -> the file's
    if "qm" in signals:  # the EMPS .mat names
        require(rec, list(EMPS_MAT))
        own = {EMPS_MAT.get(k, k): k for k in signals}
        signals = {EMPS_MAT.get(k, k): v for k, v in signals.items()}
        scalars = {EMPS_MAT_SCALARS.get(k, k): v for k, v in scalars.items()}
    if "time_s" not in signals:
        raise ConfigError("header", f"no time_s column; the file has {sorted(signals)}", src)

    names = {"time": own["time_s"]}

    def one(role: str, prefix: str, units: dict[str, tuple[str, float]]) -> tuple[np.ndarray, str] | None:
        found = [c for c in signals if c.startswith(prefix) and c[len(prefix) :] in units]
        if len(found) > 1:
            raise ConfigError(found[1], f"a second {role} column beside {found[0]}", src)
        if not found:
            return None
        unit, factor = units[found[0][len(prefix) :]]
        names[role] = own[found[0]]
        return signals[found[0]] * factor, unit  # a copy, in SI

    commands = [c for c in signals if c.startswith("command_") and c[8:] in COMMAND_UNITS]
    if len(commands) != 1:
        raise ConfigError("header", f"one command column (command_V or command_Nm); got {commands}", src)
    columns = {
        role: one(role, prefix, units)
        for role, prefix, units in (
            ("position", "position_", UNIT_OF),
            ("speed", "speed_", SPEED_UNIT_OF),
            ("reference", "reference_", UNIT_OF),
            ("speed_reference", "speed_reference_", SPEED_UNIT_OF),
        )
    }
    if columns["position"] is None and columns["speed"] is None:
        raise ConfigError("header", f"no position_<unit> or speed_<unit> column; got {sorted(signals)}", src)
    units = {c[1] for c in columns.values() if c is not None}
    if len(units) > 1:
        raise ConfigError(
            "header", f"columns in two kinds of unit {sorted(units)}: a drive is linear or rotary", src
        )
    disturbance = next((c for c in ("disturbance_V", "pulses_N") if c in signals), None)
    if disturbance is not None:
        names["disturbance"] = disturbance
    segment = signals.get("segment")
    if segment is not None and not np.array_equal(segment, np.round(segment)):
        raise ConfigError("segment", "labels must be whole numbers", src)
    return DriveColumns(
        source=src,
        t=Recording(src, {names["time"]: signals["time_s"]}).time(names["time"]),
        command=signals[commands[0]],
        command_unit=commands[0][8:],
        unit=units.pop() if units else None,
        position=columns["position"][0] if columns["position"] else None,
        speed=columns["speed"][0] if columns["speed"] else None,
        reference=columns["reference"][0] if columns["reference"] else None,
        speed_reference=columns["speed_reference"][0] if columns["speed_reference"] else None,
        disturbance=signals[disturbance] if disturbance else None,
        segment=segment.astype(int) if segment is not None else None,
        scalars=scalars,
        provenance=rec.provenance,
        names=names,
    )
