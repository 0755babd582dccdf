"""A virtual drive: a plant preset simulated in real time behind the drive protocol (envs/virtual_drive.py),
to rehearse frictiongym run-drive, faults included, before hardware. Loopback addresses only.

    frictiongym virtual-drive --scenario emps_tracking [--listen HOST:PORT] [--controller HOST:PORT]
                              [--duration-s S] [--loss P] [--late-s S] [--freeze-at-s S]
                              [--runaway-at-s S] [--seed N] [--poll-s S] [--network] [--key-file PATH]

Prints its figures as JSON (periods, commands missing and late, the datagrams it refused by why, the
ticks' lateness).
"""

from __future__ import annotations

import json
import sys

from frictiongym.scripts.options import add_address, add_network_option, loopback_only, parser, scenario_name


def main(argv: list[str] | None = None) -> int:
    ap = parser(__doc__)
    ap.add_argument(
        "--scenario", required=True, type=scenario_name, metavar="SCENARIO", help="the plant's scenario"
    )
    add_address(ap, "--listen", ("127.0.0.1", 47001), "this drive's address")
    add_address(ap, "--controller", ("127.0.0.1", 47002), "run-drive's address")
    ap.add_argument("--duration-s", type=float, default=10.0, help="how long it serves (s)")
    ap.add_argument("--loss", type=float, default=0.0, help="probability a readings datagram is lost")
    ap.add_argument("--late-s", type=float, default=0.0, help="readings sent this late in their period (s)")
    ap.add_argument("--freeze-at-s", type=float, help="the drive stops sending from this time (s)")
    ap.add_argument("--runaway-at-s", type=float, help="full positive command from this time (s)")
    ap.add_argument("--seed", type=int, default=0, help="the episode's seed (its plant and noise)")
    ap.add_argument(
        "--poll-s",
        type=float,
        help="how long it polls for each command before sleeping (s; default: half a period)",
    )
    add_network_option(ap)
    args = ap.parse_args(argv)
    key = loopback_only(ap, args, listen=args.listen, controller=args.controller)
    from frictiongym.envs.virtual_drive import Faults, serve  # start-up cost: --help imports no MuJoCo

    faults = Faults(args.loss, args.late_s, args.freeze_at_s, args.runaway_at_s)
    out = serve(
        args.scenario,
        args.listen,
        args.controller,
        args.duration_s,
        faults,
        args.seed,
        key=key,
        poll_s=args.poll_s,
    )
    out = {k: v for k, v in out.items() if k not in ("output", "command")}
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
