"""The small protocol between a drive and the controller that runs it (frictiongym run-drive), over UDP:
one datagram a control period each way, little-endian, with sequence numbers and timestamps.

    readings  drive -> controller:  b"FGR1", seq (u32), t_drive (f64, s), n (u8), n readings (f64 each,
                                    the sensors' units: rad, m or V, in the plant preset's sensor order)
    command   controller -> drive:  b"FGC1", seq (u32: the readings' it answers), t_controller (f64, s),
                                    flags (u8: RUN, HOLD, STOP), command (f64, V or N·m)

A drive applies a RUN command; HOLD asks it to hold its safe command (zero) while the controller waits
(a watchdog); STOP ends the run. The virtual drive (envs/virtual_drive.py) and the controller's loop
(agents/deploy/drive_loop.py) both use these functions; loopback addresses only in the tests.

With a shared key (both sides' --key-file) every datagram carries TAG_BYTES more: HMAC-SHA-256 of the
datagram's bytes, truncated to 128 bits (RFC 2104; the truncation of RFC 4868's HMAC-SHA-256-128), so a
sender without the key can neither forge nor alter one; replays are refused by the sequence numbers
(drive_loop.accept) and the drive's one-period window.
"""

from __future__ import annotations

import hashlib
import hmac
import os
import stat
import struct
from collections.abc import Sequence
from pathlib import Path
from typing import NamedTuple

TAG_BYTES = 16  # the truncated HMAC-SHA-256 a keyed datagram ends with
KEY_BYTES = (16, 1024)  # a key file's size: at least 128 bits

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


class Unauthenticated(ValueError):
    """A datagram without the tag the shared key gives it (forged, altered, or from a sender without it)."""


def read_key(path: Path) -> bytes:
    """A shared key from a file (KEY_BYTES long, its bytes as they are; `head -c 32 /dev/urandom > KEY`),
    readable by its owner only (a key others can read is no secret): a ValueError naming the file."""
    info = os.stat(path)
    if info.st_mode & (stat.S_IRWXG | stat.S_IRWXO):
        raise ValueError(
            f"{path}: the key file is open to others (mode {stat.filemode(info.st_mode)}): chmod 600"
        )
    if not KEY_BYTES[0] <= info.st_size <= KEY_BYTES[1]:
        raise ValueError(f"{path}: a key of {info.st_size} bytes; expected {KEY_BYTES[0]} to {KEY_BYTES[1]}")
    return Path(path).read_bytes()


def _signed(body: bytes, key: bytes | None) -> bytes:
    return body if key is None else body + hmac.new(key, body, hashlib.sha256).digest()[:TAG_BYTES]


def _verified(data: bytes, key: bytes | None) -> bytes:
    """The datagram's body after its tag was checked (constant time); the data itself without a key."""
    if key is None:
        return data
    body, tag = data[:-TAG_BYTES], data[-TAG_BYTES:]
    if len(data) < TAG_BYTES or not hmac.compare_digest(tag, _signed(body, key)[-TAG_BYTES:]):
        raise Unauthenticated(f"a datagram of {len(data)} bytes without the shared key's tag")
    return body


def pack_readings(seq: int, t: float, values: Sequence[float], key: bytes | None = None) -> bytes:
    body = _HEAD.pack(READINGS_MAGIC, seq, t, len(values)) + struct.pack(f"<{len(values)}d", *values)
    return _signed(body, key)


def unpack_readings(data: bytes, key: bytes | None = None) -> Readings:
    """A readings datagram; a malformed one is a ValueError naming what is wrong (Unauthenticated: its
    tag does not match the key)."""
    data = _verified(data, key)
    if len(data) < _HEAD.size:
        raise ValueError(f"readings datagram of {len(data)} bytes, shorter than its header")
    magic, seq, t, n = _HEAD.unpack_from(data)
    if magic != READINGS_MAGIC or len(data) != _HEAD.size + 8 * n:
        raise ValueError(f"not a readings datagram (magic {magic!r}, {len(data)} bytes for {n} values)")
    return Readings(seq, t, struct.unpack_from(f"<{n}d", data, _HEAD.size))


def pack_command(seq: int, t: float, flags: int, value: float, key: bytes | None = None) -> bytes:
    return _signed(_COMMAND.pack(COMMAND_MAGIC, seq, t, flags, value), key)


def unpack_command(data: bytes, key: bytes | None = None) -> Command:
    """A command datagram; a malformed one is a ValueError naming what is wrong (Unauthenticated: its
    tag does not match the key)."""
    data = _verified(data, key)
    if len(data) != _COMMAND.size:
        raise ValueError(f"command datagram of {len(data)} bytes, expected {_COMMAND.size}")
    magic, seq, t, flags, value = _COMMAND.unpack(data)
    if magic != COMMAND_MAGIC or flags not in (RUN, HOLD, STOP):
        raise ValueError(f"not a command datagram (magic {magic!r}, flags {flags})")
    return Command(seq, t, flags, value)
