"""The small protocol between a drive and the controller that runs it (frictiongym run-drive), over UDP:
one datagram a control period each way, little-endian, with sequence numbers and timestamps.

    readings  drive -> controller:  b"FGR1", seq (u32), t_drive (f64, s), n (u8), n readings (f64 each,
                                    the sensors' units: rad, m or V, in the plant preset's sensor order)
    command   controller -> drive:  b"FGC1", seq (u32: the readings' it answers), t_controller (f64, s),
                                    flags (u8: RUN, HOLD, STOP), command (f64, V or N·m)

A drive applies a RUN command; HOLD asks it to hold its safe command (zero) while the controller waits
(a watchdog); STOP ends the run. The virtual drive (envs/virtual_drive.py) and the controller's loop
(agents/deploy/drive_loop.py) both use these functions; loopback addresses only in the tests.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from typing import NamedTuple

READINGS_MAGIC, COMMAND_MAGIC = b"FGR1", b"FGC1"
RUN, HOLD, STOP = 0, 1, 2
_HEAD = struct.Struct("<4sIdB")
_COMMAND = struct.Struct("<4sIdBd")


class Readings(NamedTuple):
    seq: int
    t: float
    values: tuple[float, ...]


class Command(NamedTuple):
    seq: int
    t: float
    flags: int
    value: float


def pack_readings(seq: int, t: float, values: Sequence[float]) -> bytes:
    return _HEAD.pack(READINGS_MAGIC, seq, t, len(values)) + struct.pack(f"<{len(values)}d", *values)


def unpack_readings(data: bytes) -> Readings:
    """A readings datagram; a malformed one is a ValueError naming what is wrong."""
    if len(data) < _HEAD.size:
        raise ValueError(f"readings datagram of {len(data)} bytes, shorter than its header")
    magic, seq, t, n = _HEAD.unpack_from(data)
    if magic != READINGS_MAGIC or len(data) != _HEAD.size + 8 * n:
        raise ValueError(f"not a readings datagram (magic {magic!r}, {len(data)} bytes for {n} values)")
    return Readings(seq, t, struct.unpack_from(f"<{n}d", data, _HEAD.size))


def pack_command(seq: int, t: float, flags: int, value: float) -> bytes:
    return _COMMAND.pack(COMMAND_MAGIC, seq, t, flags, value)


def unpack_command(data: bytes) -> Command:
    """A command datagram; a malformed one is a ValueError naming what is wrong."""
    if len(data) != _COMMAND.size:
        raise ValueError(f"command datagram of {len(data)} bytes, expected {_COMMAND.size}")
    magic, seq, t, flags, value = _COMMAND.unpack(data)
    if magic != COMMAND_MAGIC or flags not in (RUN, HOLD, STOP):
        raise ValueError(f"not a command datagram (magic {magic!r}, flags {flags})")
    return Command(seq, t, flags, value)
