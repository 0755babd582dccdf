"""What the front ends' parsers share, importing nothing heavy: `frictiongym COMMAND --help` answers at
once because a command's parser is built from this module, configs/ listings and argparse only; the
engine, MuJoCo, torch and Ray are imported after the options are parsed."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Any


class Formatter(argparse.RawDescriptionHelpFormatter, argparse.ArgumentDefaultsHelpFormatter):
    """The module docstring as written, and every option's default after its help (unless the help
    already names its default, or there is none to name: None, False, or an empty list)."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        none = action.default is None or action.default is False or action.default == []
        if "default" in text or none or action.default is argparse.SUPPRESS:
            return text
        return super()._get_help_string(action) or ""


def parser(doc: str | None) -> argparse.ArgumentParser:
    """A command's parser: its module docstring as the description, defaults shown."""
    return argparse.ArgumentParser(description=doc, formatter_class=Formatter)


def seed_range(text: str) -> list[int]:
    """'5000-5049' (inclusive) or '7' -> the seeds."""
    lo, _, hi = text.partition("-")
    try:
        seeds = list(range(int(lo), int(hi or lo) + 1))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected A-B or A (non-negative integers), got {text!r}") from None
    if not seeds or seeds[0] < 0:
        raise argparse.ArgumentTypeError(f"expected A <= B, both >= 0, got {text!r}")
    return seeds


def scenario_name(text: str) -> str:
    """A scenario of configs/scenarios/ (argparse type): an unknown name is an error pointing to the list,
    not a list of all 40 in every --help."""
    from frictiongym.envs.config import scenario_names

    if text not in scenario_names():
        raise argparse.ArgumentTypeError(f"unknown scenario {text!r}: `frictiongym list` prints them")
    return text


def add_backend_arguments(ap: argparse.ArgumentParser) -> None:
    """--workers, --backend and --address of the commands that run engine jobs."""
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="processes (default: all cores)")
    ap.add_argument("--backend", choices=["local", "ray"], default="local", help="process pool or Ray tasks")
    ap.add_argument("--address", help="Ray cluster to join (default: a local Ray on --workers CPUs)")


def address(text: str) -> tuple[str, int]:
    """'HOST:PORT' (argparse type; HOST defaults to the loopback) -> (host, port)."""
    host, _, port = text.rpartition(":")
    try:
        return host or "127.0.0.1", int(port)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected HOST:PORT, got {text!r}") from None


def add_address(ap: argparse.ArgumentParser, flag: str, default: tuple[str, int], what: str) -> None:
    """A HOST:PORT option of the drive commands, its default shown as it is typed."""
    ap.add_argument(
        flag,
        type=address,
        default=default,
        metavar="HOST:PORT",
        help=f"{what} (default: {default[0]}:{default[1]})",
    )


def add_network_option(ap: argparse.ArgumentParser) -> None:
    """--network and --key-file, which loopback_only reads."""
    ap.add_argument("--network", action="store_true", help="allow addresses off this machine")
    ap.add_argument(
        "--key-file",
        type=Path,
        metavar="PATH",
        help="a shared key (16-1024 bytes, mode 600; both sides): every datagram is tagged (HMAC-SHA-256)",
    )


def loopback_only(
    ap: argparse.ArgumentParser, args: argparse.Namespace, **addresses: tuple[str, int]
) -> bytes | None:
    """The shared key of --key-file (None without one), after refusing (one line naming the option) an
    address off this machine unless --network says so; on a network without a key, a one-line warning:
    anyone on the segment could then command the drive (docs/deploy.md)."""
    import ipaddress
    import socket

    for option, (host, _) in addresses.items():
        try:
            ip = ipaddress.ip_address(socket.gethostbyname(host))
        except (OSError, ValueError):
            ap.error(f"--{option}: cannot resolve {host!r}")
        if not ip.is_loopback and not args.network:
            ap.error(f"--{option} {host} is not this machine's loopback: pass --network to allow it")
    if args.key_file is None:
        if args.network:
            print("warning: --network without --key-file: datagrams are not authenticated", file=sys.stderr)
        return None
    from frictiongym.envs.drive_protocol import read_key  # the standard library's hmac only

    try:
        return read_key(args.key_file)
    except (OSError, ValueError) as e:
        ap.error(f"--key-file: {e}")


def backend_of(args: Any, ap: argparse.ArgumentParser) -> Any:
    """The engine's Ray backend the parsed arguments ask for (None: the local pool); bad combinations are
    errors."""
    if args.workers < 1:
        ap.error("--workers must be >= 1")
    if args.address and args.backend != "ray":
        ap.error("--address goes with --backend ray")
    if args.backend != "ray":
        return None
    from frictiongym.agents.evaluation.engine import Ray

    return Ray(args.address)
