"""Friction and plant identification from measured data (Iurian et al. 2005 part 2, generalised), on hardware
logs or on the simulator: experiment logs and fits with 95 % confidence intervals, whose values fill the
plants' override (envs/plants/identified.py).

Units: time s, angle rad, speed rad/s, command in the plant's command unit (V or N·m, "cu"). Friction is
identified as the drive-referred steady-state command u_ss(v) that holds a speed v,

    u_ss(v) = sgn(v)·(Fc± + (Fs± - Fc±)·exp(-(v/vs)²)) + V·v    (LuGre's static map, Iurian et al. 2005 eq. 2)

per direction: Coulomb levels Fc± and static levels Fs± (cu, magnitudes), Stribeck velocity vs (rad/s),
lumped viscous slope V (cu·s/rad). σ0 (bristle stiffness) comes from presliding; σ1 from none of these
experiments (see IDENTIFIABLE).

Experiments (`simulate`): an open-loop step (§2.2); PI velocity holds at a list of speeds in both
directions (§2.3); slow command ramps to breakaway; small-amplitude presliding. Each returns a Log, the
same structure a hardware CSV log is read into (read_log / write_log).
"""

from __future__ import annotations

import csv
import io
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy import optimize, stats

from frictiongym.envs import measured
from frictiongym.envs.config import ConfigError
from frictiongym.envs.plants.identified import drive_friction
from frictiongym.envs.plants.spec import PlantSpec
from frictiongym.envs.records import atomic_text

# What each experiment can and cannot identify (the docs and the report print this table).
IDENTIFIABLE = {
    "step": "k = G/J and a = c/J of k/(s(s+a)) (drive-referred gain and damping over inertia); not friction",
    "friction": "Fc±, V from holds well above vs; Fs±, vs only where holds below ~2·vs are steady (sticking "
    "holds are dropped); not σ0, σ1",
    "breakaway": "Fs± (the command at which the drive breaks away on a slow ramp); not Fc, vs, σ0, σ1",
    "presliding": "σ0 (drive-referred) when the presliding displacement Fs/σ0 spans several sensor "
    "resolutions (encoder); not with a tachometer only, nor below the resolution; never σ1",
}
ALPHA = 0.05  # 95 % intervals


# ------------------------------------------------------------------------------------------- logs


@dataclass
class Log:
    """An experiment log in SI: t (s), u (command unit), position (rad) and/or speed (rad/s), segment (an
    experiment's part: a hold, a ramp direction; -1 if none), provenance lines, and optionally the speed
    set-point of each hold (rad/s)."""

    t: np.ndarray
    u: np.ndarray
    command_unit: str
    position: np.ndarray | None = None
    speed: np.ndarray | None = None
    segment: np.ndarray | None = None
    provenance: list[str] = field(default_factory=list)
    reference: np.ndarray | None = None  # speed set-point of a hold (rad/s), if the rig logs it

    def __post_init__(self) -> None:
        if self.position is None and self.speed is None:
            raise ConfigError("log", "needs a position or a speed column")
        if np.any(np.diff(self.t) <= 0):
            i = int(np.flatnonzero(np.diff(self.t) <= 0)[0]) + 1
            raise ConfigError("time_s", f"time must increase strictly; it does not at data row {i + 1}")


def read_log(path: str | Path) -> Log:
    """An experiment log of the one drive-log schema (envs/measured.py drive_columns: every row as long as
    the header, every value a finite number, time in seconds): time_s, command_V or command_Nm,
    position_<unit> and/or speed_<unit> (m, rad or deg; m/s, rad/s or deg/s), optionally segment and
    speed_reference_<unit> (a hold's set-point); a closed-loop log's other columns are not read here.
    Errors name the file, the column and the row."""
    c = measured.drive_columns(path)
    scalars = [f"{k} = {v!r}" for k, v in c.scalars.items()]
    return Log(
        t=c.t,
        u=c.command,
        command_unit=c.command_unit,
        position=c.position,
        speed=c.speed,
        segment=c.segment,
        provenance=[*c.provenance, *scalars],
        reference=c.speed_reference,
    )


def write_log(path: str | Path, log: Log) -> None:
    """Write a log as read_log reads it (SI columns, provenance as '#' lines)."""
    cols = {"time_s": log.t, f"command_{log.command_unit}": log.u}
    if log.position is not None:
        cols["position_rad"] = log.position
    if log.speed is not None:
        cols["speed_rad_s"] = log.speed
    if log.segment is not None:
        cols["segment"] = log.segment
    if log.reference is not None:
        cols["speed_reference_rad_s"] = log.reference
    buf = io.StringIO()
    for line in log.provenance:
        buf.write(f"# {line}\n")
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(cols)
    for row in zip(*cols.values(), strict=True):
        w.writerow([repr(int(x)) if isinstance(x, np.integer) else repr(float(x)) for x in row])
    atomic_text(Path(path), buf.getvalue())


# ------------------------------------------------------------------------------------------- fits
@dataclass(frozen=True)
class Estimate:
    """A fitted value and its 95 % confidence interval."""

    value: float
    low: float
    high: float

    def mean_with(self, other: Estimate) -> Estimate:
        """The mean of two directions' estimates (value and interval ends), for a parameter the simulator
        has once (one viscous slope, one Stribeck velocity)."""
        return Estimate(
            0.5 * (self.value + other.value), 0.5 * (self.low + other.low), 0.5 * (self.high + other.high)
        )

    def __format__(self, spec: str) -> str:
        return f"{self.value:{spec or '.6g'}} [{self.low:{spec or '.4g'}}, {self.high:{spec or '.4g'}}]"


def _estimates(names: Sequence[str], res: Any, n: int) -> dict[str, Estimate]:
    """Parameters of a scipy least_squares result with 95 % intervals from the Jacobian's covariance."""
    p = len(res.x)
    dof = max(n - p, 1)
    s2 = 2 * res.cost / dof
    try:
        cov = np.linalg.inv(res.jac.T @ res.jac) * s2
        se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    except np.linalg.LinAlgError:
        se = np.full(p, math.inf)
    q = stats.t.ppf(1 - ALPHA / 2, dof)
    return {
        k: Estimate(float(x), float(x - q * e), float(x + q * e))
        for k, x, e in zip(names, res.x, se, strict=True)
    }


def two_point_step_id(t: tuple[float, float], y: tuple[float, float], v: float) -> dict[str, float]:
    """Seed 000 §2.2: the line through two late step-response points gives θ ≈ α1·t + α2 with
    a = -α1/α2 and k = α1·a/v (it ignores the exponential term, ERRATA 000)."""
    alpha1 = (y[1] - y[0]) / (t[1] - t[0])
    alpha2 = y[0] - alpha1 * t[0]
    a = -alpha1 / alpha2
    return {"alpha1": alpha1, "alpha2": alpha2, "a": a, "k": alpha1 * a / v}


def step_response(t: np.ndarray, k: float, a: float, v: float) -> np.ndarray:
    """θ(t) of k/(s(s+a)) from rest for a step v at t = 0: α1·t + α2 + α3·e^(-a·t) (Iurian et al. 2005 §2.2).
    """
    return k * v / a * t - k * v / a**2 * (1.0 - np.exp(-a * t))


def step_through_points(t: tuple[float, float], y: tuple[float, float], v: float) -> dict[str, float]:
    """(k, a) of the full step response (with the exponential term) through the two points exactly: what
    the two-point method should give (ERRATA 000)."""
    start = two_point_step_id(t, y, v)
    res = optimize.least_squares(
        lambda p: (step_response(np.asarray(t), p[0], p[1], v) - np.asarray(y)) / np.asarray(y),
        [start["k"], start["a"]],
        bounds=([0, 1e-6], [np.inf, np.inf]),
        xtol=1e-15,
        ftol=1e-15,
    )
    return {"k": float(res.x[0]), "a": float(res.x[1])}


MIN_STEP_SAMPLES = 20  # a step response to fit k and a (two parameters) with an interval


def fit_step(t: np.ndarray, theta: np.ndarray, v: float) -> dict[str, Estimate]:
    """Least-squares fit of k, a of k/(s(s+a)) to a whole step response θ(t) from rest (t from the step).
    A response of fewer than MIN_STEP_SAMPLES samples, or one that does not determine k and a (an
    infinite or NaN interval), is refused."""
    t, theta = np.asarray(t, float), np.asarray(theta, float)
    if len(t) < MIN_STEP_SAMPLES:
        raise ConfigError("log", f"{len(t)} samples: a step fit needs at least {MIN_STEP_SAMPLES}")
    late = t > 0.5 * t[-1]
    start = two_point_step_id((t[late][0], t[-1]), (theta[late][0], theta[-1]), v)
    k0, a0 = (start["k"], start["a"]) if start["a"] > 0 and start["k"] > 0 else (theta[-1] / t[-1] ** 2, 1.0)
    scale = max(abs(theta).max(), 1e-12)
    res = optimize.least_squares(
        lambda p: (step_response(t, p[0] * k0, p[1] * a0, v) - theta) / scale,
        [1.0, 1.0],
        bounds=([1e-9, 1e-9], [np.inf, np.inf]),
    )
    est = _estimates(["k", "a"], res, len(t))
    for name, e in est.items():
        if not all(map(math.isfinite, (e.value, e.low, e.high))):
            raise ConfigError(
                "log", f"the step response does not determine {name} (interval {e.low}, {e.high})"
            )
    return {
        "k": Estimate(est["k"].value * k0, est["k"].low * k0, est["k"].high * k0),
        "a": Estimate(est["a"].value * a0, est["a"].low * a0, est["a"].high * a0),
    }


@dataclass(frozen=True)
class LineFit:
    """u = coulomb + viscous·v over one direction's points (signed, as the data)."""

    coulomb: Estimate
    viscous: Estimate
    points: int


def coulomb_viscous_fit(velocity: np.ndarray, control: np.ndarray, min_speed: float = 0.0) -> LineFit:
    """Seed 000 §2.3: least-squares line control = F_C + F_v·velocity over the points with |v| >= min_speed,
    with 95 % intervals (scipy.stats.linregress standard errors, Student t)."""
    velocity, control = np.asarray(velocity, float), np.asarray(control, float)
    sel = np.abs(velocity) >= min_speed
    n = int(sel.sum())
    if n < 3:
        raise ConfigError("points", f"{n} points with |v| >= {min_speed}: a line with intervals needs >= 3")
    r = stats.linregress(velocity[sel], control[sel])
    q = stats.t.ppf(1 - ALPHA / 2, n - 2)
    return LineFit(
        Estimate(r.intercept, r.intercept - q * r.intercept_stderr, r.intercept + q * r.intercept_stderr),
        Estimate(r.slope, r.slope - q * r.stderr, r.slope + q * r.stderr),
        n,
    )


def rows_reproducing(
    velocity: np.ndarray, control: np.ndarray, slope: str, intercept: str
) -> list[list[int]]:
    """Every subset of rows (1-based, >= 2 rows) whose least-squares line, rounded to the printed digits,
    gives the printed slope and intercept (strings as printed, e.g. "2.3517e-6", "0.114716")."""

    def printed(x: float, text: str) -> bool:
        mant = text.lower().split("e")[0]
        decimals = len(mant.split(".")[1]) if "." in mant else 0
        exp = int(text.lower().split("e")[1]) if "e" in text.lower() else 0
        return round(x / 10.0**exp, decimals) == round(float(text) / 10.0**exp, decimals)

    v, u = np.asarray(velocity, float), np.asarray(control, float)
    out = []
    for n in range(2, len(v) + 1):
        for rows in itertools.combinations(range(len(v)), n):
            m, b = np.polyfit(v[list(rows)], u[list(rows)], 1)
            if printed(m, slope) and printed(b, intercept):
                out.append([i + 1 for i in rows])
    return out


def static_friction_model(v: np.ndarray, fc: float, fs: float, vs: float, viscous: float) -> np.ndarray:
    """One direction's steady-state command magnitude |u_ss(v)| = Fc + (Fs - Fc)·exp(-(v/vs)²) + V·|v|."""
    v = np.abs(v)
    return fc + (fs - fc) * np.exp(-((v / vs) ** 2)) + viscous * v


def fit_static(
    speed: np.ndarray,
    command: np.ndarray,
    fs: float | None = None,
    vs_bounds: tuple[float, float] = (1e-4, 1e3),
) -> dict[str, Estimate]:
    """One direction's LuGre static map (magnitudes) from steady (speed, command) points: Fc, Fs, vs, V.
    With `fs` given (from breakaway), only Fc, vs and V are fitted and Fs is fixed."""
    v, u = np.abs(np.asarray(speed, float)), np.abs(np.asarray(command, float))
    if len(v) < (3 if fs is not None else 4):
        raise ConfigError("points", f"{len(v)} points in one direction: the static map needs at least 4")
    fast = v >= np.quantile(v, 2 / 3)
    line = coulomb_viscous_fit(v[fast], u[fast]) if fast.sum() >= 3 else None
    fc0 = line.coulomb.value if line else u.min()
    visc0 = max(line.viscous.value, 0.0) if line else 0.0
    fs0 = fs if fs is not None else max(u.max() - visc0 * v[np.argmax(u)], fc0)
    vmax, umax = float(v.max()), float(u.max())
    vs_hi = min(vs_bounds[1], vmax)  # a Stribeck velocity above the fastest hold is not in the data
    vs0 = float(np.clip(np.median(v) / 4, vs_bounds[0], vs_hi))
    if fs is None:
        names = ["fc", "fs", "vs", "viscous"]

        def model(p: np.ndarray) -> np.ndarray:
            return static_friction_model(v, p[0], p[1], p[2], p[3])

        p0, lo, hi = [fc0, fs0, vs0, visc0], [0, 0, vs_bounds[0], 0], [umax, 2 * umax, vs_hi, np.inf]
    else:
        names = ["fc", "vs", "viscous"]

        def model(p: np.ndarray) -> np.ndarray:
            return static_friction_model(v, p[0], fs, p[1], p[2])

        p0, lo, hi = [min(fc0, fs), vs0, visc0], [0, vs_bounds[0], 0], [fs, vs_hi, np.inf]
    p0 = np.clip(p0, np.array(lo) + 1e-12, np.array(hi) - 1e-12)
    scale = max(umax, 1e-12)
    res = optimize.least_squares(lambda p: (model(p) - u) / scale, p0, bounds=(lo, hi))
    est = _estimates(names, res, len(v))
    est = {k: Estimate(e.value, e.low, e.high) for k, e in est.items()}
    if fs is not None:
        est["fs"] = Estimate(fs, fs, fs)
    # residuals were scaled by `scale`; intervals from the Jacobian are already in parameter units
    return est


# ------------------------------------------------------------------------------------------- from logs
def resolution(log: Log) -> float:
    """The position (or speed) sensor's resolution as the log shows it: the smallest non-zero change."""
    y = log.position if log.position is not None else log.speed
    d = np.abs(np.diff(y))
    d = d[d > 1e-15]
    return float(d.min()) if len(d) else 0.0


def steady_points(log: Log, tolerance: float = 0.1) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """(speed, command) of each steady hold (segment): means over the segment's last half. A hold is
    steady when the speed of each quarter of that half is within `tolerance` of their mean and, if the log
    has the set-point, of the set-point (a hold that sticks or stick-slips is dropped: its mean command is
    not a point of the static map). Returns the points and the dropped segments."""
    if log.segment is None:
        raise ConfigError("segment", "a holds log needs a segment column (one segment per speed hold)")
    speeds, commands, dropped = [], [], []
    for seg in np.unique(log.segment):
        sel = np.flatnonzero(log.segment == seg)
        half = sel[len(sel) // 2 :]
        parts = np.array_split(half, 4)
        if min(len(p) for p in parts) < 2:
            raise ConfigError("segment", f"hold {seg} has {len(sel)} samples: too short to judge steadiness")
        if log.position is not None:
            v = [(log.position[p[-1]] - log.position[p[0]]) / (log.t[p[-1]] - log.t[p[0]]) for p in parts]
        else:
            v = [float(np.mean(log.speed[p])) for p in parts]
        mean = float(np.mean(v))
        target = float(np.mean(log.reference[half])) if log.reference is not None else mean
        if mean == 0 or max(abs(x - mean) for x in [*v, target]) > tolerance * abs(mean):
            dropped.append(int(seg))
            continue
        if log.position is not None:
            mean = (log.position[half[-1]] - log.position[half[0]]) / (log.t[half[-1]] - log.t[half[0]])
        speeds.append(mean)
        commands.append(float(np.mean(log.u[half])))
    return np.array(speeds), np.array(commands), dropped


def split_directions(
    speed: np.ndarray, command: np.ndarray, need: int
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """{'pos': ..., 'neg': ...} points by the sign of the speed; fewer than `need` in a direction is an
    error naming it."""
    out = {}
    for name, sel in (("pos", speed > 0), ("neg", speed < 0)):
        if sel.sum() < need:
            raise ConfigError(
                "points", f"{int(sel.sum())} steady points in the {name} direction; need {need}"
            )
        out[name] = (speed[sel], command[sel])
    return out


def breakaway_levels(log: Log, threshold: float) -> dict[str, float]:
    """Static levels (magnitudes, cu) from breakaway ramps: per segment, |u| at the first sample where the
    drive has moved `threshold` from its start (rad, or rad/s with a tachometer: above the presliding
    range, which is elastic and bounded); the direction from the sign of the command."""
    if log.segment is None:
        raise ConfigError("segment", "a breakaway log needs a segment column (one segment per ramp)")
    y = log.position if log.position is not None else log.speed
    thr = threshold
    out = {}
    for seg in np.unique(log.segment):
        sel = np.flatnonzero(log.segment == seg)
        moved = np.flatnonzero(np.abs(y[sel] - y[sel[0]]) >= thr)
        if not len(moved):
            raise ConfigError("breakaway", f"ramp {seg} never moved {thr:.3g} from its start")
        u = log.u[sel[moved[0]]]
        out["static_pos" if u > 0 else "static_neg"] = abs(float(u))
    if set(out) != {"static_pos", "static_neg"}:
        raise ConfigError("breakaway", f"needs a ramp in each direction; got {sorted(out)}")
    return out


def presliding_stiffness(log: Log, amplitude: float, frequency_hz: float) -> tuple[float | None, str]:
    """σ0 (cu/rad, drive-referred) from a sinusoidal presliding log: command amplitude / displacement
    amplitude over the last full period, linear trend removed (asymmetric friction makes the bristles
    creep a little each cycle). None, with the reason, when the displacement spans fewer than 5
    resolutions or there is no position sensor (not identifiable)."""
    if log.position is None:
        return None, "no position sensor: presliding displacement not measured (σ0 not identifiable)"
    last = log.t >= log.t[-1] - 1.0 / frequency_hz
    t, x = log.t[last], log.position[last]
    x = x - np.polyval(np.polyfit(t, x, 1), t)
    amp = 0.5 * float(x.max() - x.min())
    res = resolution(log)
    if amp == 0:
        return None, "the position did not move over the last period: σ0 not identifiable"
    if amp < 5 * res:
        return None, f"displacement {amp:.3g} rad < 5 resolutions ({res:.3g} rad): σ0 not identifiable"
    return amplitude / amp, f"displacement amplitude {amp:.3g} rad = {amp / res:.0f} resolutions"


@dataclass
class FrictionId:
    """Identified drive-referred friction: estimates with 95 % intervals, and what was not identified."""

    estimates: dict[str, Estimate]
    notes: list[str]
    points: dict[str, tuple[np.ndarray, np.ndarray]]
    unidentified: set[str] = field(default_factory=set)  # estimated but not to be trusted (see notes)

    def values(self) -> dict[str, float]:
        """The override values (IdentifiedFriction's fields; sigma0_per_rad if identified)."""
        e = self.estimates
        out = {
            "coulomb_pos": e["coulomb_pos"].value,
            "coulomb_neg": e["coulomb_neg"].value,
            "static_pos": e.get("static_pos", e["coulomb_pos"]).value,
            "static_neg": e.get("static_neg", e["coulomb_neg"]).value,
            "stribeck_velocity_rad_s": e["stribeck_velocity_rad_s"].value
            if "stribeck_velocity_rad_s" in e
            else 1.0,
            "viscous_per_rad_s": e["viscous_per_rad_s"].value,
        }
        if "sigma0_per_rad" in e:
            out["sigma0_per_rad"] = e["sigma0_per_rad"].value
        return out


def identify_coulomb_viscous(holds_log: Log, min_speed: float = 0.0) -> FrictionId:
    """Coulomb + viscous per direction (Iurian et al. 2005 §2.3) from the steady holds with |v| >= min_speed.
    """
    v, u, dropped = steady_points(holds_log)
    sel = np.abs(v) >= min_speed
    pts = split_directions(v[sel], u[sel], 3)
    est, notes = {}, [f"unsteady holds dropped: segments {dropped}"] if dropped else []
    fits = {d: coulomb_viscous_fit(*pts[d]) for d in pts}
    est["coulomb_pos"] = fits["pos"].coulomb
    c = fits["neg"].coulomb
    est["coulomb_neg"] = Estimate(-c.value, -c.high, -c.low)
    # one viscous slope for the plant (the simulator's LuGre has one σ2): the mean of the two
    est["viscous_per_rad_s"] = fits["pos"].viscous.mean_with(fits["neg"].viscous)
    est["viscous_pos_per_rad_s"], est["viscous_neg_per_rad_s"] = fits["pos"].viscous, fits["neg"].viscous
    return FrictionId(est, [*notes, "Stribeck part not fitted (Coulomb + viscous only)"], pts)


def identify_lugre(
    holds_log: Log,
    breakaway: tuple[Log, float] | None = None,
    presliding: tuple[Log, float, float] | None = None,
) -> FrictionId:
    """LuGre static part per direction (Fc, Fs, vs, V) from steady holds, with Fs from breakaway ramps
    (log, threshold) when given; σ0 from presliding (log, command amplitude, Hz) when identifiable; σ1 never
    (IDENTIFIABLE)."""
    v, u, dropped = steady_points(holds_log)
    pts = split_directions(v, u, 3 if breakaway is not None else 4)
    static = breakaway_levels(*breakaway) if breakaway is not None else {}
    est: dict[str, Estimate] = {}
    notes = [f"unsteady holds dropped (stick-slip): segments {dropped}"] if dropped else []
    fits = {}
    for d in ("pos", "neg"):
        fits[d] = fit_static(*pts[d], fs=static.get(f"static_{d}"))
        est[f"coulomb_{d}"], est[f"static_{d}"] = fits[d]["fc"], fits[d]["fs"]
    if static:
        notes.append("static levels from the breakaway ramps (intervals: not estimated, one ramp each)")
    for key, name in (("vs", "stribeck_velocity_rad_s"), ("viscous", "viscous_per_rad_s")):
        a, b = fits["pos"][key], fits["neg"][key]
        est[name] = a.mean_with(b)
    slowest = float(min(np.abs(v)))
    drop = min(
        (est[f"static_{d}"].value - est[f"coulomb_{d}"].value) / est[f"coulomb_{d}"].value
        for d in ("pos", "neg")
    )
    unidentified = set()
    if slowest > 2 * est["stribeck_velocity_rad_s"].value or drop < 0.1:
        unidentified.add("stribeck_velocity_rad_s")
        notes.append(
            f"vs = {est['stribeck_velocity_rad_s'].value:.3g} rad/s is not identified: the Stribeck drop is "
            f"{drop:.1%} of the Coulomb level and the slowest steady hold {slowest:.3g} rad/s (needs a drop "
            ">= 10 % and steady holds below 2·vs)"
        )
        if not static:  # nothing resolves a static level above the Coulomb one
            for d in ("pos", "neg"):
                est[f"static_{d}"] = est[f"coulomb_{d}"]
            notes.append("no breakaway data and no Stribeck drop resolved: static levels = Coulomb levels")
    if presliding is not None:
        s0, why = presliding_stiffness(*presliding)
        notes.append(f"presliding: {why}")
        if s0 is not None:
            est["sigma0_per_rad"] = Estimate(s0, math.nan, math.nan)  # one measurement: no interval
    notes.append(
        "σ1 (bristle damping) is not identifiable from these experiments: the preset's ratio is kept"
    )
    return FrictionId(est, notes, pts, unidentified)


def identify_simulated(logs: dict[str, Log], p: Any) -> FrictionId:
    """identify_lugre on a protocol's logs (experiments.run_all)."""
    return identify_lugre(
        logs["holds"],
        (logs["breakaway"], p.threshold) if "breakaway" in logs else None,
        (logs["presliding"], p.presliding_amplitude, p.presliding_hz) if "presliding" in logs else None,
    )


def truth_values(spec: PlantSpec) -> dict[str, float]:
    """The identified keys' true values of a simulated plant (drive_friction), for recovery checks."""
    t = drive_friction(spec)
    return {
        "coulomb_pos": t.coulomb_pos,
        "coulomb_neg": t.coulomb_neg,
        "static_pos": t.static_pos,
        "static_neg": t.static_neg,
        "stribeck_velocity_rad_s": t.stribeck_velocity,
        "viscous_per_rad_s": t.viscous,
        "sigma0_per_rad": t.sigma0,
    }
