"""Episode metrics, computed by this one module for every controller (plain functions over arrays).

Inputs: t (s), reference r, true tracked output y (same unit), command u (V or N·m), true velocity v of the
tracked joint (rad/s). Error e = y - r.
"""

from __future__ import annotations

import math

import numpy as np

METRIC_NAMES = (
    "iae",
    "ise",
    "rms_error",
    "final_error",
    "settling_time",
    "overshoot_pct",
    "limit_cycle_amp",
    "limit_cycle_freq_hz",
    "stick_slip_events",
    "reversal_peak_error",
    "effort_rms",
    "effort_total_variation",
    "command_roughness",
    "saturated_share",
    "rest_oscillation",
)


def metric_unit(name: str, output_unit: str, command_unit: str) -> str:
    """A metric's unit for a plant whose tracked output is in `output_unit` (rad, m or V) and whose command
    is in `command_unit` (V or N·m): what a table's header shows beside the metric's name."""
    return {
        "iae": f"{output_unit}·s",
        "ise": f"{output_unit}²·s",
        "rms_error": output_unit,
        "final_error": output_unit,
        "settling_time": "s",
        "overshoot_pct": "%",
        "limit_cycle_amp": output_unit,
        "limit_cycle_freq_hz": "Hz",
        "stick_slip_events": "count",
        "reversal_peak_error": output_unit,
        "effort_rms": f"{command_unit} rms",
        "effort_total_variation": command_unit,
        "command_roughness": f"{command_unit} rms",
        "saturated_share": "fraction",
        "rest_oscillation": output_unit,
    }[name]


def integral_errors(t: np.ndarray, e: np.ndarray) -> dict[str, float]:
    """IAE = Σ|e|·dt, ISE = Σe²·dt (rectangle rule on the sampling grid), RMS error."""
    dt = float(np.mean(np.diff(t))) if len(t) > 1 else 0.0
    return {
        "iae": float(np.sum(np.abs(e)) * dt),
        "ise": float(np.sum(e**2) * dt),
        "rms_error": float(np.sqrt(np.mean(e**2))),
    }


FINAL_FRACTION = 0.1  # the share of an episode final_error averages over


def final_error(e: np.ndarray, fraction: float = FINAL_FRACTION) -> float:
    """Steady-state error: mean |e| over the last `fraction` of the episode."""
    n = max(1, round(len(e) * fraction))
    return float(np.mean(np.abs(e[-n:])))


def settling_time(t: np.ndarray, e: np.ndarray, band: float) -> float:
    """Time after which |e| stays within band (s from the start); nan if it never settles."""
    outside = np.flatnonzero(np.abs(e) > band)
    if len(outside) == 0:
        return float(t[0])
    if outside[-1] == len(e) - 1:
        return float("nan")
    return float(t[outside[-1] + 1])


def holds(r: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) index ranges where the reference is at rest: maximal runs of at least two equal
    consecutive samples."""
    still = np.flatnonzero(np.diff(r) == 0)  # r[i + 1] == r[i]
    if len(still) == 0:
        return []
    breaks = np.flatnonzero(np.diff(still) > 1)
    starts = np.concatenate([[still[0]], still[breaks + 1]])
    ends = np.concatenate([still[breaks], [still[-1]]]) + 2
    return list(zip(starts.tolist(), ends.tolist(), strict=True))


def overshoot_pct(r: np.ndarray, e: np.ndarray, min_move: float) -> float:
    """Largest overshoot of the episode's moves, each in % of its own size. A move ends where the reference
    comes to rest (a hold, `holds`); its size is the distance from the previous hold's value (for the first
    hold: from the initial output y(0) = r(0) + e(0), regulation from an initial error), its overshoot
    the largest excursion of the output past the held value in the move's direction, during the hold.
    Moves smaller than min_move (the settling band) are not moves; nan if there is none (a reference that
    never rests, e.g. a sine). The same unit for r, e and min_move."""
    worst, previous = math.nan, float(r[0] + e[0])
    for i, j in holds(r):
        target = float(r[i])
        size = target - previous
        previous = target
        if abs(size) < min_move:
            continue
        past = max(0.0, float(np.max(np.sign(size) * e[i:j])))
        worst = max(past / abs(size) * 100.0, 0.0 if math.isnan(worst) else worst)
    return worst


def limit_cycle(t: np.ndarray, y: np.ndarray, window: float = 0.4, min_amp: float = 0.0) -> dict[str, float]:
    """Amplitude (half peak-to-peak) and frequency (from mean-crossings) of y over the last `window`
    fraction of the episode (or the last `window` seconds if window > 1). Frequency is 0 below min_amp."""
    sel = t >= (t[-1] - window if window > 1 else t[0] + (1 - window) * (t[-1] - t[0]))
    yw, tw = y[sel], t[sel]
    amp = 0.5 * float(np.max(yw) - np.min(yw)) if len(yw) else float("nan")
    if not len(yw) or amp <= min_amp:
        return {"limit_cycle_amp": amp, "limit_cycle_freq_hz": 0.0}
    s = np.signbit(yw - np.mean(yw))
    crossings = np.flatnonzero(s[1:] != s[:-1])
    if len(crossings) < 3:
        return {"limit_cycle_amp": amp, "limit_cycle_freq_hz": 0.0}
    tc = tw[crossings]
    return {"limit_cycle_amp": amp, "limit_cycle_freq_hz": float((len(tc) - 1) / 2.0 / (tc[-1] - tc[0]))}


def stick_slip_events(v: np.ndarray, threshold: float) -> int:
    """Number of stuck -> moving transitions of the velocity (|v| crosses threshold upwards after a stick)."""
    moving = np.abs(v) >= threshold
    return int(np.count_nonzero(moving[1:] & ~moving[:-1]))


def reversal_half_window(control_period: float) -> float:
    """The half width (s) of the window around a reversal reversal_peak_error reads: 0.25 s, at least five
    control periods."""
    return max(0.25, 5 * control_period)


def reversal_windows(t: np.ndarray, r: np.ndarray, half_window: float) -> np.ndarray:
    """The samples within ±half_window (s) of a reference velocity reversal (bool mask; none if r never
    reverses)."""
    sign = np.sign(np.diff(r))
    nz = np.flatnonzero(sign != 0)
    rev = nz[1:][sign[nz[1:]] != sign[nz[:-1]]]
    near = np.zeros(len(t), dtype=bool)
    for i in rev:
        near |= (t >= t[i] - half_window) & (t <= t[i] + half_window)
    return near


def reversal_peak_error(t: np.ndarray, r: np.ndarray, e: np.ndarray, half_window: float) -> float:
    """Largest |e| within ±half_window (s) of each reference velocity reversal; nan if r never reverses."""
    near = reversal_windows(t, r, half_window)
    return float(np.max(np.abs(e[near]))) if near.any() else float("nan")


def effort(u: np.ndarray) -> dict[str, float]:
    """Control effort RMS and total variation Σ|Δu|."""
    return {
        "effort_rms": float(np.sqrt(np.mean(u**2))),
        "effort_total_variation": float(np.sum(np.abs(np.diff(u)))),
    }


def command_roughness(u: np.ndarray) -> float:
    """Chatter as the command's high-frequency activity: the rms of its change from one control period to
    the next (command units); 0 for a constant command."""
    return float(np.sqrt(np.mean(np.diff(u) ** 2))) if len(u) > 1 else 0.0


def saturated_share(u: np.ndarray, limit: float) -> float:
    """The share of control periods whose command is at the actuator's limit (|u| within 1e-9 of it)."""
    return float(np.mean(np.abs(u) >= limit * (1 - 1e-9))) if len(u) else float("nan")


REST_MIN_SAMPLES = 20  # a rest's second half must hold at least this many samples to be judged


def rest_oscillation(r: np.ndarray, e: np.ndarray, min_amp: float) -> float:
    """A limit cycle measured as a sustained oscillation where the reference rests: over the second half
    of each rest (`holds`, after the move's transient), the error's half peak-to-peak when it crosses its
    own mean at least three times (one and a half periods) and exceeds min_amp (the sensor's resolution),
    else 0; the largest over the rests. A constant offset (a drive stuck short of its target) is not an
    oscillation and counts 0. nan where the reference never rests long enough (a tracking task: its
    error's size is the main metric's business, not a limit cycle's). The unit of e and min_amp."""
    worst = math.nan
    for i, j in holds(r):
        w = e[(i + j) // 2 : j]
        if len(w) < REST_MIN_SAMPLES:
            continue
        amp = 0.5 * float(np.max(w) - np.min(w))
        s = np.signbit(w - np.mean(w))
        cycling = amp > min_amp and np.count_nonzero(s[1:] != s[:-1]) >= 3
        worst = max(amp if cycling else 0.0, 0.0 if math.isnan(worst) else worst)
    return worst


def from_first_period(log: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The samples of an episode log the metrics use: from the first control period on (the log's first
    sample is the reset state, before any command was applied)."""
    return {k: v[1:] for k, v in log.items()}


def defined_metrics(metrics: dict[str, float]) -> dict[str, float]:
    """The metrics that are defined for an episode (not nan: e.g. settling_time when the output never
    settles, reversal_peak_error without a reversal), as the envs put them in info: a dict with nan
    never compares equal to itself. Results files keep every metric and write the undefined ones as n/a."""
    return {k: v for k, v in metrics.items() if v == v}


def episode_metrics(
    t: np.ndarray,
    r: np.ndarray,
    y: np.ndarray,
    u: np.ndarray,
    v: np.ndarray,
    *,
    settle_band: float,
    stick_velocity: float,
    command_limit: float = math.inf,
    lc_min_amp: float = 0.0,
    reversal_half_window: float = 0.25,
) -> dict[str, float]:
    """All metrics of one episode (see METRIC_NAMES); command_limit is the actuator's |u| limit."""
    e = y - r
    out = integral_errors(t, e)
    out["final_error"] = final_error(e)
    out["settling_time"] = settling_time(t, e, settle_band)
    out["overshoot_pct"] = overshoot_pct(r, e, settle_band)
    out.update(limit_cycle(t, y - r, min_amp=lc_min_amp))
    out["stick_slip_events"] = float(stick_slip_events(v, stick_velocity))
    out["reversal_peak_error"] = reversal_peak_error(t, r, e, reversal_half_window)
    out.update(effort(u))
    out["command_roughness"] = command_roughness(u)
    out["saturated_share"] = saturated_share(u, command_limit)
    out["rest_oscillation"] = rest_oscillation(r, e, lc_min_amp)
    return out
