"""Rehearse an exported controller on the virtual drive several times in a row (loopback, the drive in a
process of its own) and print each rehearsal's figures: deadline misses, compute per period split into
the controller's step, the send call and the loop's own overhead, commands missing at the drive, the
tracking error (the tracked output's unit).

    frictiongym rehearse ARTEFACT [--runs 10] [--duration-s 6] [--seed N] [--backend numpy|onnxruntime]
                         [--out out/rehearse] [--loss P] [--late-s S] [--poll-s S]

Run it above the machine's other work, as a drive's loop runs: `nice -n -10 frictiongym rehearse ...`
(docs/deploy.md). Exit code 0 when every rehearsal completed, 3 when the supervisor stopped one.
"""

from __future__ import annotations

import sys
from pathlib import Path

from frictiongym.scripts.options import parser


def main(argv: list[str] | None = None) -> int:
    ap = parser(__doc__)
    ap.add_argument("artefact", type=Path, help="a folder frictiongym export wrote")
    ap.add_argument("--runs", type=int, default=10, help="rehearsals, one after another")
    ap.add_argument("--duration-s", type=float, default=6.0, help="each rehearsal's length (s)")
    ap.add_argument("--seed", type=int, default=0, help="the drive's episode (its plant and noise)")
    ap.add_argument(
        "--backend", choices=("numpy", "onnxruntime"), default="numpy", help="how a network is evaluated"
    )
    ap.add_argument("--out", type=Path, default=Path("out/rehearse"), help="the logs' folder (run<i>.csv)")
    ap.add_argument("--loss", type=float, default=0.0, help="probability a readings datagram is lost")
    ap.add_argument("--late-s", type=float, default=0.0, help="readings sent this late in their period (s)")
    ap.add_argument(
        "--poll-s",
        type=float,
        help="how long the drive polls for each command before it sleeps (s; default: half a period)",
    )
    args = ap.parse_args(argv)
    if args.runs < 1 or args.duration_s <= 0:
        ap.error("--runs must be >= 1 and --duration-s > 0")
    from frictiongym.agents.deploy.rehearsal import rehearse  # the controllers: after --help
    from frictiongym.envs.virtual_drive import Faults

    print("run  periods  stop             misses  compute med/p99 (ms)  step  send  own  (ms, med)  missing  "
          "mean/max |e|")  # fmt: skip
    stopped = False
    try:
        for r in rehearse(
            args.artefact, args.out, args.runs, args.duration_s, Faults(args.loss, args.late_s), args.seed,
            args.backend, poll_s=args.poll_s,
        ):  # fmt: skip
            stopped |= r["stop"] is not None
            ms = {k: 1e3 * v for k, v in r.items() if k.endswith("_s")}
            print(
                f"{r['run']:>3}  {r['periods']:>7}  {r['stop'] or 'completed':<15}  "
                f"{r['deadline_misses']:>6}  {ms['compute_median_s']:>8.3f} / {ms['compute_p99_s']:<8.3f}  "
                f"{ms['step_median_s']:.3f} {ms['send_median_s']:.3f} {ms['overhead_median_s']:.3f}"
                f"{'':>11}{r['missing_at_drive']:>7}  {r['mean_abs_error']:.3g} / {r['max_abs_error']:.3g}",
                flush=True,
            )
    except (ValueError, OSError, RuntimeError) as e:  # a refused artefact, a port, a drive that failed
        print(f"error: {e}", file=sys.stderr)
        return 2
    return 3 if stopped else 0


if __name__ == "__main__":
    sys.exit(main())
