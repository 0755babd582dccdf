"""The real-time loop between an exported controller (agents/deploy/runtime.py) and a drive, over the drive
protocol (envs/drive_protocol.py), with a safety supervisor between them (frictiongym run-drive).

The drive paces the loop: it starts its clock when the controller's first datagram (a HOLD, sent every
HELLO_S until readings come) arrives, and each readings datagram is answered at once with a command. The
controller's side generates the reference (the scenario's, repeated over its episode length) and its
preview. The supervisor sees every reading and every command before it leaves, and acts in this order:

- emergency stop (Supervisor.emergency_stop(): a signal, a file appearing) and a clean stop (Ctrl-C):
  STOP sent, the log closed;
- watchdog: no readings for `watchdog_s`: HOLD sent (the drive holds zero) every period; none for
  `stop_after_s` (or no first readings within STARTUP_S): STOP;
- any sensor's reading not finite, or outside the reading window (the position window widened by its
  own width on each side: an untracked encoder or tachometer reads in the tracked one's unit): STOP
  (`stop_reading`);
- position outside [position_min, position_max] or the speed (the position's difference per period)
  above `velocity_limit`: STOP;
- divergence: |reference - position| above `divergence_error` for `divergence_periods` periods: STOP;
- the command clipped to ±command_limit and its change per period to `rate_limit` (counted as actions,
  not stops).

Every sample is logged in the drive-log schema (docs/identification.md: time_s, the sample's nominal
instant k·h, position_<unit>, reference_<unit>, command_V, the drive gain), plus `supervisor` (the
action's code, SUPERVISOR_CODES), `compute_s` (the time from a datagram's arrival to its answer) and
`drive_time_s` (the drive's own timestamp), so a run on a drive feeds the identification directly (a
lost datagram leaves its sample out).
"""

from __future__ import annotations

import math
import select
import signal
import socket
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from frictiongym.agents.deploy.runtime import Runtime
from frictiongym.envs.drive_protocol import (
    HOLD,
    RUN,
    STOP,
    Readings,
    Unauthenticated,
    pack_command,
    unpack_readings,
)
from frictiongym.envs.scenario import Scenario

STARTUP_S = 10.0  # s: the drive's first readings must come within this, or the run stops (watchdog)
HELLO_S = 0.01  # s: until then a HOLD is sent this often (the drive starts its clock on the first)
# the supervisor's action on a sample, as logged
SUPERVISOR_CODES = {
    "ok": 0,
    "clipped": 1,
    "rate_limited": 2,
    "hold": 3,
    "stop_watchdog": 4,
    "stop_position": 5,
    "stop_velocity": 6,
    "stop_divergence": 7,
    "stop_emergency": 8,
    "stop_interrupt": 9,
    "stop_log": 10,
    "stop_reading": 11,
}
# Datagrams the loop refuses, counted in the run's figures (`rejected`) and each written to the log's
# sidecar (<log>.rejected.csv): from another peer than the drive it was given, without the shared key's
# tag (with --key-file), malformed (length, magic, sensor count), a replay (a sequence number not above
# the last accepted) or a jump (more periods ahead than the watchdog lets pass). None of them feeds the
# watchdog or steps the controller.
REJECTIONS = ("peer", "unauthenticated", "malformed", "replay", "jump")


@dataclass(frozen=True)
class Limits:
    """The supervisor's limits, in the plant's units (tracked output: m or rad; command: V or N·m; s)."""

    command_limit: float
    rate_limit: float  # largest change of the command per period
    position_min: float
    position_max: float
    velocity_limit: float
    divergence_error: float
    divergence_periods: int
    watchdog_s: float
    stop_after_s: float

    @classmethod
    def of(cls, sc: Scenario, reference: np.ndarray, **overrides: Any) -> Limits:
        """Defaults from the scenario, so that its nominal episodes run through under its loops
        (tests/test_drive.py checks all of them offline): the command range and half the full range's
        change per period; a window of the reference's span and every reading the scenario may start
        from (its initial-state range), widened by its reach (the output scale plus the way three times
        the reference's fastest speed goes in 0.1 s); three times that speed plus the start's distance to
        the reference and the output scale covered in 0.1 s, for a position sensor (a tachometer's
        reading is a speed: its window is its limit); an error above the reach held for 0.1 s without
        closing by a tenth; a watchdog of 5 periods and a stop after 0.1 s without readings; keyword
        arguments override them."""
        h, s = sc.control_period, sc.output_scale
        speed = float(np.max(np.abs(np.diff(reference)))) / h if len(reference) > 1 else 0.0
        lo, hi = start_readings(sc)
        offset = max(abs(lo - reference[0]), abs(hi - reference[0])) if len(reference) else 0.0
        position = sc.spec.sensors[sc.tracked_sensor].kind == "encoder"
        reach = s + 0.1 * 3 * speed  # the output scale and the way 3x the reference speed goes in 0.1 s
        out = {
            "command_limit": sc.action_scale,
            "rate_limit": sc.action_scale,
            "position_min": min(float(reference.min()), lo) - reach,
            "position_max": max(float(reference.max()), hi) + reach,
            "velocity_limit": 3 * speed + (offset + s) / 0.1 if position else math.inf,
            "divergence_error": reach,
            "divergence_periods": max(1, round(0.1 / h)),
            "watchdog_s": 5 * h,
            "stop_after_s": max(0.1, 10 * h),
        }
        return cls(**{**out, **overrides})


def start_readings(sc: Scenario) -> tuple[float, float]:
    """The lowest and highest tracked reading the scenario's episodes may start from (its initial-state
    range of the tracked joint; a tachometer reads its speed times its gain; mirrored where the start's
    sign is drawn)."""
    sensor = sc.spec.sensors[sc.tracked_sensor]
    j = min(sc.spec.joint_index(sensor.joint), len(sc.qpos_range) - 1)  # one row for belted joints
    lo, hi = (sc.qpos_range[j] if sensor.kind == "encoder" else sc.qvel_range[j] * sensor.gain).tolist()
    if sc.random_sign:
        lo, hi = min(lo, -hi), max(hi, -lo)
    return float(lo), float(hi)


@dataclass
class Supervisor:
    """The checks of the module docstring, one reading and one command at a time (no clock of its own:
    the loop tells it the time)."""

    limits: Limits
    last_position: float | None = None
    last_command: float = 0.0
    diverging: int = 0  # periods the error has been above divergence_error
    streak_error: float = 0.0  # the error when it went above
    emergency: bool = False
    events: dict[str, int] = field(default_factory=lambda: dict.fromkeys(SUPERVISOR_CODES, 0))

    def emergency_stop(self) -> None:
        self.emergency = True

    def readings_ok(self, values: tuple[float, ...]) -> bool:
        """Every sensor's reading finite and inside the reading window (the module docstring): a drive
        whose sensors read nonsense is stopped before any reading reaches the controller."""
        lim = self.limits
        span = lim.position_max - lim.position_min
        lo, hi = lim.position_min - span, lim.position_max + span
        return all(lo <= v <= hi for v in values)  # NaN compares false

    def check(self, position: float, reference: float, period: float) -> str:
        """ "ok", or the stop a reading calls for."""
        lim = self.limits
        if self.emergency:
            return "stop_emergency"
        if not (lim.position_min <= position <= lim.position_max) or not math.isfinite(position):
            return "stop_position"
        if (
            self.last_position is not None
            and abs(position - self.last_position) > lim.velocity_limit * period
        ):
            return "stop_velocity"
        self.last_position = position
        error = abs(reference - position)
        if error <= lim.divergence_error:
            self.diverging = 0
        else:
            if self.diverging == 0:
                self.streak_error = error
            self.diverging += 1
            if self.diverging >= lim.divergence_periods:
                if error > 0.9 * self.streak_error:  # held, not closing: a drive that does not follow
                    return "stop_divergence"
                self.diverging = 0  # closing (a loop catching up after a jump of the reference): go on
        return "ok"

    def limit(self, command: float) -> tuple[float, str]:
        """The command clipped to the command limit, then its change to the rate limit."""
        lim, why = self.limits, "ok"
        u = command if math.isfinite(command) else 0.0
        if abs(u) > lim.command_limit:
            u, why = math.copysign(lim.command_limit, u), "clipped"
        step = u - self.last_command
        if abs(step) > lim.rate_limit:
            u, why = self.last_command + math.copysign(lim.rate_limit, step), "rate_limited"
        self.last_command = u
        return u, why

    def record(self, what: str) -> str:
        self.events[what] += 1
        return what


def reference_of(sc: Scenario, steps: int, seed: int = 0) -> np.ndarray:
    """The scenario's reference r(t_k) for k < steps, its episode repeated (the controller side's); a
    reference drawn per episode (type random) is episode `seed`'s, as the env draws it."""
    n = sc.episode_steps + sc.preview_steps + 1
    t = np.arange(n) * sc.control_period
    drawn = sc.reference.episode(seed, t)[0] if sc.reference.per_episode else sc.reference(t)
    one = np.asarray(drawn, dtype=float)
    reps = math.ceil((steps + sc.preview_steps + 1) / sc.episode_steps) + 1
    return np.tile(one[: sc.episode_steps], reps)


def run_drive(
    runtime: Runtime,
    address: tuple[str, int],
    drive: tuple[str, int],
    duration_s: float,
    log: Path,
    limits: dict[str, Any] | None = None,
    estop_file: Path | None = None,
    ready: Any = None,
    seed: int = 0,
    key: bytes | None = None,
) -> dict[str, Any]:
    """Close the loop for duration_s (drive periods) or until the supervisor stops it; writes the log (the
    drive-log schema) and returns the run's figures: periods, the supervisor's events, the stop and why,
    per-period times (median, 99th percentile, max): compute (a datagram's arrival to its answer sent),
    split into the controller's step, the send call (the kernel's delivery; on loopback it wakes the
    drive's process) and the loop's own overhead (the rest); deadline misses (answers sent later than
    half a period after their readings arrived). Ctrl-C (SIGINT) stops it cleanly: STOP sent, the log written.
    `ready`, if given, is set once the socket is bound. `seed`: the episode whose reference a scenario
    that draws one per episode tracks (reference_of). `key`: the shared key (drive_protocol.read_key)
    every datagram is tagged with and checked by, or None."""
    sc = runtime.scenario
    h = sc.control_period
    steps = round(duration_s / h)
    drive = (socket.gethostbyname(drive[0]), drive[1])  # compared with each datagram's sender
    ref = reference_of(sc, steps, seed)
    sup = Supervisor(Limits.of(sc, ref[: sc.episode_steps], **(limits or {})))
    stream = open_log(log, sc)  # before the first period: an unwritable --log fails here, in one line
    interrupted = []
    previous = signal.signal(signal.SIGINT, lambda *_: interrupted.append(True)) if _main_thread() else None
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sock.bind(address)
    except OSError:
        sock.close()
        stream.close()
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
        raise
    if ready is not None:
        ready.set()
    periods = 0  # the periods run (each a row of the log, written as it is run)
    # per period (s): arrival to answer sent, the controller's step, the send call (the kernel's delivery)
    answer, step_s, send_s = np.zeros(steps + 1), np.full(steps + 1, np.nan), np.full(steps + 1, np.nan)
    stop, last_seen, last_k = None, time.perf_counter(), None
    log_error: OSError | None = None
    started, rejected = time.perf_counter(), dict.fromkeys(REJECTIONS, 0)
    gap = math.ceil(sup.limits.stop_after_s / h) + 1  # periods a lost stretch may skip before the watchdog
    rejects = RejectLog(log.with_suffix(".rejected.csv"))
    runtime.reset()
    try:
        while stop is None:
            if interrupted:
                stop = sup.record("stop_interrupt")
                break
            if estop_file is not None and estop_file.exists():
                sup.emergency_stop()
            wait = sup.limits.watchdog_s if periods else HELLO_S
            if not select.select([sock], [], [], wait)[0]:
                silent = time.perf_counter() - last_seen
                if silent >= (sup.limits.stop_after_s if periods else STARTUP_S):
                    stop = sup.record("stop_watchdog")
                else:  # HOLD: the drive holds zero (and, before its first readings, learns we are here)
                    sock.sendto(pack_command(0, time.perf_counter(), HOLD, 0.0, key), drive)
                    if periods:
                        sup.record("hold")
                continue
            data, sender = sock.recvfrom(2048)
            arrived = time.perf_counter()
            r, why = accept(data, sender, drive, len(sc.spec.sensors), last_k, gap, steps, key)
            if why is not None:
                rejected[why] += 1
                rejects.write(f"{arrived - started!r},{sender[0]}:{sender[1]},{why},{len(data)}\n")
                continue
            last_seen = arrived  # only a valid reading from the drive feeds the watchdog
            k = r.seq
            if not sup.readings_ok(r.values):  # any sensor: a drive that reads nonsense
                stop = sup.record("stop_reading")
                break
            position = r.values[sc.tracked_sensor]
            reference = float(ref[k])
            what = sup.check(position, reference, (k - last_k) * h if last_k is not None else h)
            last_k = k
            if what != "ok":
                stop = sup.record(what)
                u = 0.0
            else:
                preview = ref[k + 1 : k + 1 + sc.preview_steps].tolist()
                t_step = time.perf_counter()
                command = runtime.step(r.values, reference, preview)
                t_send = time.perf_counter()
                step_s[periods] = t_send - t_step
                u, what = sup.limit(command)
                sup.record(what)
                datagram = pack_command(k, time.perf_counter(), RUN, u, key)
                t_send = time.perf_counter()
                sock.sendto(datagram, sender)
                send_s[periods] = time.perf_counter() - t_send
            spent = time.perf_counter() - arrived
            answer[periods] = spent
            periods += 1
            try:  # each row on disk as it is run: a crash or a full disk keeps what ran
                stream.write(log_row((k * h, position, reference, u, SUPERVISOR_CODES[what], spent, r.t)))
            except OSError as e:
                stop = sup.record("stop_log")
                log_error = e
                break
            if k == steps - 1:  # the run's last period: done
                break
    finally:
        sock.sendto(pack_command(0, time.perf_counter(), STOP, 0.0, key), drive)
        sock.close()
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
        try:
            stream.close()
        except OSError as e:  # the last rows could not be flushed
            log_error = e
        rejects.close()
    c = answer[: max(periods, 1)]
    stepped = ~np.isnan(step_s[: len(c)])
    parts = {"step_s": step_s[: len(c)][stepped], "send_s": send_s[: len(c)][stepped]}
    parts["overhead_s"] = c[stepped] - parts["step_s"] - parts["send_s"]  # the loop's own work
    return {
        "periods": periods,
        "stop": stop,
        "events": {k: v for k, v in sup.events.items() if v},
        "compute_s": _spread(c),
        **{name: _spread(x) for name, x in parts.items()},
        "deadline_misses": int(np.sum(c > 0.5 * h)),
        "log": str(log),
        "log_error": None if log_error is None else f"{log_error.strerror or log_error}: {log}",
        "rejected": {k: v for k, v in rejected.items() if v},
    }


def _spread(x: np.ndarray) -> dict[str, float]:
    """Median, 99th percentile and maximum of per-period times (s); zeros for none."""
    x = x if len(x) else np.zeros(1)
    return {"median": float(np.median(x)), "p99": float(np.percentile(x, 99)), "max": float(x.max())}


def accept(
    data: bytes,
    sender: tuple,
    drive: tuple,
    sensors: int,
    last: int | None,
    gap: int,
    steps: int,
    key: bytes | None = None,
) -> tuple[Readings | None, str | None]:
    """(the readings, None) for a datagram the loop takes, else (None, why: one of REJECTIONS): from the
    drive's address and port, tagged with the shared key if there is one, well formed with one value per
    sensor, and its sequence number strictly
    above the last accepted one and at most `gap` periods ahead (the first: within the first `gap`), and
    inside the run (below `steps`)."""
    if sender[:2] != drive[:2]:
        return None, "peer"
    try:
        r = unpack_readings(data, key)
    except Unauthenticated:
        return None, "unauthenticated"
    except ValueError:
        return None, "malformed"
    if len(r.values) != sensors or not math.isfinite(r.t):
        return None, "malformed"
    floor = -1 if last is None else last
    if r.seq <= floor:
        return None, "replay"
    if r.seq > floor + gap or r.seq >= steps:
        return None, "jump"
    return r, None


class RejectLog:
    """The sidecar of refused datagrams (time since the start in s, the sender, why, its size in bytes),
    created at the first one and flushed line by line."""

    def __init__(self, path: Path):
        self.path, self.stream = path, None

    def write(self, line: str) -> None:
        if self.stream is None:
            self.stream = open(self.path, "w", buffering=1)  # noqa: SIM115  (closed by close())
            self.stream.write("time_s,sender,why,bytes\n")
        self.stream.write(line)

    def close(self) -> None:
        if self.stream is not None:
            self.stream.close()


def _main_thread() -> bool:
    import threading  # signal handlers can be set from the main thread only

    return threading.current_thread() is threading.main_thread()


def open_log(path: Path, sc: Scenario) -> TextIO:
    """The run's drive log (the schema: an encoder's position in m or rad; a tachometer's reading is
    logged as the position column's signal in V, for the record), opened and its header written before
    the first period; rows follow one whole line at a time, each flushed as it is written (line
    buffering). An OSError here is the caller's one line: nothing has been commanded yet."""
    sensor = sc.spec.sensors[sc.tracked_sensor]
    unit = sc.spec.joint_unit(sensor.joint)  # the tracked joint's position unit
    gain = {"m": "drive_gain_n_per_v", "rad": "drive_gain_nm_per_v"}[unit]
    head = [
        f"# frictiongym run-drive: {sc.name}, control period {sc.control_period} s, tracked {sensor.kind}",
        f"# supervisor codes: {SUPERVISOR_CODES}",
        f"# {gain} = {sc.spec.actuator_gain!r}",
        f"time_s,position_{unit},reference_{unit},command_V,supervisor,compute_s,drive_time_s",
    ]
    path.parent.mkdir(parents=True, exist_ok=True)
    stream = open(path, "w", buffering=1)  # noqa: SIM115  (closed by run_drive's finally)
    stream.write("\n".join(head) + "\n")
    return stream


def log_row(row: tuple) -> str:
    """One logged period as its CSV line (floats as repr: read back exactly)."""
    return ",".join(repr(float(x)) if i != 4 else str(x) for i, x in enumerate(row)) + "\n"
