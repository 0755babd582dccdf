"""Sim-to-real friction study: controllers designed or trained on nominal (or randomised) plants, evaluated
on plants shifted one axis at a time (friction level, asymmetry, Stribeck velocity, σ0, viscous friction,
inertia, delay up to one control period), on other friction structures (Dahl, Maxwell-slip, Kang's
stick-slip model, Coulomb + viscous: the structural axis) and on joint shifts, in- and out-of-distribution.

    frictiongym sim2real [--scenario m220_reversal_tracking] [--models DIR ...] [--controllers ...]
                         [--seeds 10] [--points 5] [--joint 20] [--model-error 10] [--workers N]
                         [--structures lugre dahl maxwell_slip kang coulomb]
                         [--out out/sim2real]

Writes OUT/episodes.csv (resumable), sim2real.csv (controller, axis, shift, metric mean and 95 % CI),
sim2real.png (robustness curves), sim2real_structures.png (the main metric on each friction structure),
model_error.csv/.png (classical baselines designed on the identified model of randomised true plants vs on
the true parameters: the closing-the-loop study of identification) and sim2real.md (which controller keeps
its lead where, where each breaks, what model error costs).
Default models: the committed agents (agents/models/sim2real: trained without randomisation and with
wide ranges; agents/models/specialist and agents/models/generalist, the default leaderboard's: with the
nominal ranges); those that apply to the scenario run.
"""

from __future__ import annotations

import sys
from pathlib import Path

from frictiongym.envs.friction import STRUCTURES
from frictiongym.scripts.options import add_backend_arguments, backend_of, parser, scenario_name


def main(argv: list[str] | None = None) -> int:
    ap = parser(__doc__)
    ap.add_argument(
        "--scenario",
        default="m220_reversal_tracking",
        type=scenario_name,
        metavar="SCENARIO",
        help="the scenario",
    )
    ap.add_argument(
        "--models", nargs="*", type=Path, help="saved-model folders (default: the committed ones)"
    )
    ap.add_argument(
        "--controllers",
        nargs="+",
        help="default: every applicable controller and model (a residual base only when named)",
    )
    ap.add_argument("--seeds", type=int, default=10, help="episodes per shift value (default 10)")
    ap.add_argument("--points", type=int, default=5, help="shift values per axis (default 5)")
    ap.add_argument("--joint", type=int, default=20, help="joint-shift draws per set (default 20)")
    ap.add_argument(
        "--model-error", type=int, default=10, help="true plants of the identification closing-the-loop study"
    )
    ap.add_argument(
        "--structures",
        nargs="*",
        default=list(STRUCTURES),
        choices=STRUCTURES,
        help="friction structures of the structural axis (default: all; none: no structural axis)",
    )
    add_backend_arguments(ap)
    ap.add_argument("--out", type=Path, default=Path("out/sim2real"), help="the study's folder")
    args = ap.parse_args(argv)
    # start-up cost: --help imports none of these (MuJoCo, the controllers, the engine)
    from frictiongym.agents import sim2real
    from frictiongym.agents.evaluation.engine import one_line_errors, run_interruptibly
    from frictiongym.agents.registry import LEADERBOARD_GROUPS, committed_models

    ray = backend_of(args, ap)
    if min(args.seeds, args.points - 1, args.joint + 1, args.workers) < 1:
        ap.error("--seeds >= 1, --points >= 2, --joint >= 0, --workers >= 1")
    default = committed_models("sim2real", *LEADERBOARD_GROUPS)  # those that apply are run
    models = tuple(str(m) for m in (args.models if args.models is not None else default))

    def run() -> int:
        _, text = sim2real.run(
            args.scenario,
            args.controllers,
            models,
            args.out,
            args.seeds,
            args.points,
            args.joint,
            args.workers,
            model_error_draws=args.model_error,
            ray=ray,
            structures=tuple(args.structures),
        )
        print(text)
        return 0

    resume = f"the finished rows are in {args.out}/episodes.csv; rerun the same command to resume"
    return one_line_errors(lambda: run_interruptibly(run, resume), args.out)


if __name__ == "__main__":
    sys.exit(main())
