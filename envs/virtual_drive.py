"""A virtual drive: a plant preset simulated in real time behind the drive protocol (envs/drive_protocol.py),
so that a controller's loop (frictiongym run-drive) can be rehearsed, faults included, before it meets
hardware. Loopback addresses only in the tests.

The drive's clock starts when the controller's first datagram arrives. Every control period h, at the
tick t_k = t_0 + k·h, the drive sends its sensors' readings (decoded from
the env's observation: float32 resolution) as datagram k, waits until t_k + h for the command answering
it, then simulates one period with the command it has (so a command acts one period after the readings it
answers, as on a drive that applies it at its next sample): a RUN command's value, zero for HOLD, the
last command held when none came in time (counted as missing; one answering an earlier datagram is
counted late and not applied). The plant runs the scenario's nominal preset (randomize false) with the
reference left out (the controller's side generates it).

Faults to rehearse (Faults): datagrams lost with a probability, readings sent late within their period,
a drive that freezes (sends nothing from a time on) and one that runs away (applies its full positive
command from a time on, whatever it is told).
"""

from __future__ import annotations

import math
import select
import socket
import time
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from .drive_protocol import HOLD, STOP, Command, Unauthenticated, pack_readings, unpack_command
from .servo_env import ServoEnv, decode_observation

STARTUP_S = 30.0  # s: the controller's first datagram must come within this
# the datagrams the drive refuses, by why: from another sender than its controller, without the shared
# key's tag, not a well-formed command, a non-finite command
REFUSALS = ("peer", "unauthenticated", "malformed", "nonfinite")


def take_command(
    data: bytes, sender: tuple, controller: tuple, key: bytes | None
) -> tuple[Command | None, str | None]:
    """(the command, None) for a datagram the drive takes, else (None, why: one of REFUSALS); each datagram
    is unpacked (and its tag checked) once."""
    if sender != controller:
        return None, "peer"
    try:
        cmd = unpack_command(data, key)
    except Unauthenticated:
        return None, "unauthenticated"
    except ValueError:
        return None, "malformed"
    return (cmd, None) if math.isfinite(cmd.value) else (None, "nonfinite")


@dataclass(frozen=True)
class Faults:
    """What goes wrong on the virtual drive: loss, the probability each readings datagram is dropped;
    late_s, how late in its period each is sent (s); freeze_at_s, when the drive stops sending (s);
    runaway_at_s, when it starts applying its full positive command whatever it is told (s)."""

    loss: float = 0.0
    late_s: float = 0.0
    freeze_at_s: float | None = None
    runaway_at_s: float | None = None


def serve(
    scenario: str,
    address: tuple[str, int],
    controller: tuple[str, int],
    duration_s: float,
    faults: Faults = Faults(),
    seed: int = 0,
    ready: Any = None,
    key: bytes | None = None,
    poll_s: float | None = 0.0,
) -> dict[str, Any]:
    """Run the drive for duration_s (or until a STOP command), sending readings to `controller` from
    `address`; returns its figures: periods run, commands missing and late, the datagrams it refused by
    why (REFUSALS), the ticks' lateness (s: median, 99th percentile, max) and the log of the true output
    and applied command. `ready`, if given, is set (a threading or multiprocessing Event) once the socket
    is bound. `key`: the shared key every datagram is tagged with and checked by (drive_protocol), or
    None. `poll_s`: how long after sending its readings the drive polls for the command before it sleeps
    until the period's end (None: half the period), as a drive's receive path polls: the controller's
    send then delivers without waking a process (on loopback the wake-up is the sender's cost; 0 in a
    thread beside the loop, which polling would starve of the interpreter lock)."""
    env = ServoEnv(
        scenario,
        randomize=False,
        overrides={"reference": {"type": "constant", "value": 0.0}},
        episode_s=duration_s + 1.0,
    )
    sc = env.scenario
    h, scale, sensors = sc.control_period, sc.action_scale, [s.name for s in sc.spec.sensors]
    rng = np.random.default_rng(seed)
    obs, _ = env.reset(seed=seed)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(address)
    if ready is not None:
        ready.set()
    steps = round(duration_s / h)
    poll_s = 0.5 * h if poll_s is None else poll_s
    u, missing, late, stopped, rejected = 0.0, 0, 0, False, dict.fromkeys(REFUSALS, 0)
    lateness, output, applied = np.zeros(steps), np.zeros(steps), np.zeros(steps)
    k = 0
    try:
        deadline = time.perf_counter() + STARTUP_S
        while True:  # the controller's first datagram starts the clock; another sender's is ignored
            left = deadline - time.perf_counter()
            if left <= 0 or not select.select([sock], [], [], left)[0]:
                raise TimeoutError(f"no controller datagram within {STARTUP_S} s on {address}")
            data, sender = sock.recvfrom(64)
            _, why = take_command(data, sender, controller, key)
            if why is None:
                break
            rejected[why] += 1
        t0 = time.perf_counter()
        for k in range(steps):
            tick = t0 + k * h
            t_send = tick + faults.late_s
            while (now := time.perf_counter()) < t_send:
                time.sleep(min(t_send - now, 2e-4) if t_send - now > 3e-4 else 0)
            lateness[k] = now - t_send
            frozen = faults.freeze_at_s is not None and k * h >= faults.freeze_at_s
            if not frozen and not rng.random() < faults.loss:
                d = decode_observation(sc, obs)
                values = [float(d["sensors"][name]) for name in sensors]
                sock.sendto(pack_readings(k, now - t0, values, key), controller)
            answer = None
            poll_until = time.perf_counter() + poll_s
            while answer is None and (left := tick + h - time.perf_counter()) > 0:
                if time.perf_counter() < poll_until:  # polling: the command's arrival wakes no process
                    if not select.select([sock], [], [], 0)[0]:
                        continue
                elif not select.select([sock], [], [], left)[0]:
                    break
                data, sender = sock.recvfrom(64)
                # only the controller it was given commands it, with a well-formed, finite command
                cmd, why = take_command(data, sender, controller, key)
                if cmd is None:
                    rejected[why] += 1
                    continue
                if cmd.flags == STOP:
                    stopped = True
                    break
                if cmd.seq == k:
                    answer = cmd
                else:
                    late += 1
            if stopped:
                break
            if answer is None:
                missing += not frozen  # a frozen drive expects none
            else:
                u = 0.0 if answer.flags == HOLD else answer.value
            if faults.runaway_at_s is not None and k * h >= faults.runaway_at_s:
                u = scale
            a = min(max(u / scale, -1.0), 1.0)  # the amplifier's range: any finite command is applied clipped
            obs, _, term, trunc, info = env.step(np.array([a], np.float32))
            output[k], applied[k] = info["output"], a * scale
            if term or trunc:
                break
    finally:
        sock.close()
    run = lateness[: k + 1]
    return {
        "scenario": scenario,
        "periods": k + 1,
        "stopped_by_controller": stopped,
        "missing_commands": missing,
        "late_commands": late,
        "rejected_datagrams": {k: v for k, v in rejected.items() if v},
        "tick_lateness_s": {
            "median": float(np.median(run)),
            "p99": float(np.percentile(run, 99)),
            "max": float(run.max()),
        },
        "faults": asdict(faults),
        "output": output[: k + 1],
        "command": applied[: k + 1],
    }
