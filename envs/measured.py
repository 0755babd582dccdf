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
