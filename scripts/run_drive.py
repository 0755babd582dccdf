"""Run an exported controller (frictiongym export) on a drive over the drive protocol, with the safety
supervisor between them (agents/deploy/drive_loop.py), and log every sample in the drive-log schema.

    frictiongym run-drive ARTEFACT --drive HOST:PORT [--listen HOST:PORT] [--duration-s S]
                          [--log out/drive/log.csv] [--estop-file PATH] [--limit NAME=VALUE ...]
                          [--backend numpy|onnxruntime] [--network] [--key-file PATH]

Rehearse on the virtual drive first (frictiongym virtual-drive; docs/deploy.md). Ctrl-C stops cleanly
(STOP sent, the log written); creating --estop-file stops at once. --limit overrides a supervisor limit
(agents.deploy.drive_loop.Limits: command_limit, rate_limit, position_min, position_max, velocity_limit,
divergence_error, divergence_periods, watchdog_s, stop_after_s). Prints the run's figures as JSON; exit
code 0 when the run completed or was stopped by the operator, 3 when the supervisor stopped it. Both sides
bind loopback unless --network; off this machine give both --key-file (a shared key: every datagram is
tagged with an HMAC, and an untagged one is refused and logged; docs/deploy.md).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from frictiongym.scripts.options import add_address, add_network_option, address, loopback_only, parser


def limit(text: str) -> tuple[str, float]:
    name, _, value = text.partition("=")
    try:
        return name, float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}") from None


def main(argv: list[str] | None = None) -> int:
    ap = parser(__doc__)
    ap.add_argument("artefact", type=Path, help="a folder frictiongym export wrote")
    ap.add_argument("--drive", type=address, required=True, metavar="HOST:PORT", help="the drive's address")
    add_address(ap, "--listen", ("127.0.0.1", 47002), "this side's address")
    ap.add_argument("--duration-s", type=float, default=10.0, help="how long the loop runs (s)")
    ap.add_argument("--log", type=Path, default=Path("out/drive/log.csv"), help="the drive log (CSV)")
    ap.add_argument("--estop-file", type=Path, help="a file whose appearance stops the run at once")
    ap.add_argument("--limit", type=limit, nargs="*", default=[], help="supervisor limits, NAME=VALUE")
    ap.add_argument(
        "--backend", choices=("numpy", "onnxruntime"), default="numpy", help="how a network is evaluated"
    )
    add_network_option(ap)
    ap.add_argument(
        "--seed", type=int, default=0, help="the episode whose reference a random-reference scenario tracks"
    )
    args = ap.parse_args(argv)
    key = loopback_only(ap, args, drive=args.drive, listen=args.listen)
    from frictiongym.agents.deploy.drive_loop import Limits, run_drive  # the controllers: after --help
    from frictiongym.agents.deploy.runtime import Runtime  # the controllers: after --help

    known = set(Limits.__dataclass_fields__)
    if bad := [n for n, _ in args.limit if n not in known]:
        ap.error(f"--limit: unknown {bad}; one of {sorted(known)}")
    try:
        runtime = Runtime.load(args.artefact, args.backend)
        limits = {n: (int(v) if n == "divergence_periods" else v) for n, v in args.limit}
        out = run_drive(
            runtime, args.listen, args.drive, args.duration_s, args.log, limits, args.estop_file,
            seed=args.seed, key=key,
        )  # fmt: skip
    except (ValueError, OSError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(json.dumps(out, indent=1))
    return 3 if out["stop"] not in (None, "stop_interrupt", "stop_emergency") else 0


if __name__ == "__main__":
    sys.exit(main())
