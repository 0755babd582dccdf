"""Identify a plant's friction from data, and write the override the envs load.

    frictiongym identify step     (--csv LOG --step-v V | --simulate PLANT [--seed N] [--randomize]
                                         | --document) [--out DIR]
    frictiongym identify friction (--csv HOLDS [--min-speed RAD_S] | --simulate PLANT ... | --document)
    frictiongym identify lugre    (--csv HOLDS [--breakaway CSV THRESHOLD]
                                         [--presliding CSV AMPLITUDE HZ] | --simulate PLANT ...) [--out DIR]
    frictiongym identify recovery [--draws 20] [--out DIR]
    frictiongym identify idim     [--csv ESTIMATION [--validation LOG]] [--delays 0 1] [--out DIR]
    frictiongym identify check    [--csv LOG --plant PRESET] [--controller LabPD]
                                        [--scan sigma0_n_per_m|delay_s VALUE ...] [--out DIR]

idim: inverse-model identification (IDIM-LS, EMPS §3) of a drive from closed-loop logs: every friction
structure fitted on the estimation log, cross-tested on the validation log; writes DIR/report.md,
result.json and, for a linear drive, plant.yaml (a draft preset). check: the simulated drive (a plant
preset, default the EMPS) in closed loop under its lab controller against a measured log, and open loop
on its ν (--scan: the closed loop over values of one preset knob). Without --csv both use the EMPS logs
(configs/published/emps/). Drive logs: a .mat with the EMPS names, or a CSV with time_s,
position_m|_rad|_deg, reference_*, command_V[, disturbance_V] and '# drive_gain_n_per_v = ...'
(docs/emps.md).

CSV logs: '#' provenance lines, then columns time_s, command_V or command_Nm, position_rad|position_deg
and/or speed_rad_s|speed_deg_s, and for holds/ramps a segment column (one per hold or ramp) and optionally
speed_reference_rad_s (docs/identification.md). --simulate runs the same experiments on a plant of the
suite (randomised with --randomize) and saves their logs. --document uses the M220's own data (Iurian et al.
2005 §2.2-2.3). Writes DIR/report.md, result.json, fit plots and identified.yaml:
    gym.make("frictiongym/M220-<Scenario>-v1", overrides=yaml.safe_load(open("DIR/identified.yaml")))
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from frictiongym.envs.config import ConfigError, plant_names
from frictiongym.envs.records import atomic_text
from frictiongym.scripts.options import parser


def main(argv: list[str] | None = None) -> int:
    ap = parser(__doc__)
    ap.add_argument(
        "kind", choices=["step", "friction", "lugre", "recovery", "idim", "check"], help="what to identify"
    )
    src = ap.add_mutually_exclusive_group()
    src.add_argument("--csv", type=Path, help="a hardware (or any) log: a step, or speed holds")
    src.add_argument("--simulate", choices=plant_names(), help="run the experiments on this simulated plant")
    src.add_argument(
        "--document", action="store_true", help="the M220 data printed in Iurian et al. 2005 §2.2-2.3"
    )
    ap.add_argument("--seed", type=int, default=0, help="simulated plant's seed (with --randomize)")
    ap.add_argument("--randomize", action="store_true", help="draw the simulated plant from its ranges")
    ap.add_argument("--step-v", type=float, help="the step command of a --csv step log (V or N·m)")
    ap.add_argument(
        "--min-speed", type=float, default=0.0, help="friction: fit holds with |v| >= this (rad/s)"
    )
    ap.add_argument(
        "--breakaway", nargs=2, metavar=("CSV", "THRESHOLD"), help="ramps log, motion threshold (rad)"
    )
    ap.add_argument(
        "--presliding", nargs=3, metavar=("CSV", "AMPLITUDE", "HZ"), help="presliding log and its input"
    )
    ap.add_argument("--draws", type=int, default=20, help="recovery: randomised plants per plant")
    ap.add_argument("--validation", type=Path, help="idim: the cross-test log (a drive log)")
    ap.add_argument("--delays", type=int, nargs="+", default=[0, 1], help="idim: force shifts (samples)")
    ap.add_argument("--plant", help="check: the plant preset to simulate (configs/plants name)")
    ap.add_argument("--controller", default="LabPD", help="check: the controller of the closed loop")
    ap.add_argument(
        "--scan",
        nargs="+",
        metavar=("KNOB", "VALUE"),
        help="check: repeat over values of sigma0_n_per_m or delay_s (e.g. --scan delay_s 0 0.0005 0.001)",
    )
    ap.add_argument("--out", type=Path, default=Path("out/identify"), help="the results' folder")
    args = ap.parse_args(argv)
    # start-up cost: --help imports no MuJoCo
    from frictiongym.agents.lab.experiment_workflow import IdentifyOptions, recovery, run

    try:
        if args.kind == "recovery":
            table, _ = recovery(plant_names(), args.draws)
            args.out.mkdir(parents=True, exist_ok=True)
            atomic_text(args.out / "recovery.md", table)
            print(table)
            return 0
        if args.kind in ("idim", "check"):
            return _lab(args)
        if args.document and args.kind == "lugre":
            ap.error("--document holds a step and a Coulomb + viscous table: use step or friction")
        options = IdentifyOptions(
            args.kind,
            csv=args.csv,
            simulate=args.simulate,
            seed=args.seed,
            randomize=args.randomize,
            document=args.document,
            breakaway=(Path(args.breakaway[0]), float(args.breakaway[1])) if args.breakaway else None,
            presliding=(Path(args.presliding[0]), float(args.presliding[1]), float(args.presliding[2]))
            if args.presliding
            else None,
            step_v=args.step_v,
            min_speed=args.min_speed,
        )
        text = run(options, args.out)
    except (ConfigError, ValueError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(text)
    return 0


def _lab(args: argparse.Namespace) -> int:
    """The drive-log sub-commands (frictiongym.agents.lab.drive_workflow)."""
    from frictiongym.agents.lab import drive_workflow

    if args.kind == "idim":
        r = drive_workflow.identify(
            drive_workflow.IdentifyOptions(args.csv, args.validation, delays=tuple(args.delays))
        )
        for p in drive_workflow.write_identification(r, args.out):
            print(f"wrote {p}")
        return 0
    if args.scan:
        knob, values = args.scan[0], tuple(float(v) for v in args.scan[1:])
        text = drive_workflow.scan_markdown(knob, drive_workflow.scan(knob, values, args.csv, args.plant))
    else:
        text = drive_workflow.check_markdown(drive_workflow.check(args.csv, args.plant, args.controller))
    args.out.mkdir(parents=True, exist_ok=True)
    atomic_text(args.out / "check.md", text + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
