"""rl-baselines3-zoo with the frictiongym envs registered, and zoo agents judged on the validation suite.

    frictiongym zoo train --algo sac --env frictiongym/KangRobot-Regulation-v1 \
        --conf-file configs/zoo/sac.yml
    frictiongym zoo record_video --algo sac --env frictiongym/KangRobot-Regulation-v1 -f logs -n 500
    frictiongym zoo validate --algo sac --env frictiongym/KangRobot-Regulation-v1 -f logs --trust-pickle

train, enjoy and record_video are the zoo's own commands and take its options (record_video has no
--gym-packages, hence this front end; videos need the video extra and MUJOCO_GL=egl). validate runs
the latest zoo run of an id on the first validation-suite episodes of its scenario against the best
classical baseline, through the leaderboard's evaluation loop; the zoo saves its agents as pickles (an
SB3 zip, a VecNormalize), which run code when loaded: validate reads them only with --trust-pickle.
"""

from __future__ import annotations

import sys
from types import ModuleType

from frictiongym.envs.records import missing_extra
from frictiongym.scripts.options import Formatter, parser

ZOO_COMMANDS = ("train", "enjoy", "record_video")  # rl_zoo3's own commands, run with the ids registered


def _zoo_module() -> ModuleType | None:
    """frictiongym.agents.training.zoo (stable-baselines3, rl-zoo: the rl and zoo extras), or None after one
    line naming the missing extra and its install command."""
    try:
        from frictiongym.agents.training import zoo  # the rl and zoo extras: a missing one is named
    except ModuleNotFoundError as e:
        print(missing_extra(e, "rl,zoo", "frictiongym zoo"), file=sys.stderr)
        return None
    return zoo


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv and argv[0] in ZOO_COMMANDS:  # the zoo's own command: its options (and --help) are the zoo's
        zoo = _zoo_module()
        if zoo is None:
            return 2
        zoo.run_zoo_command(argv[0], argv[1:])
        return 0
    p = parser(__doc__)
    sub = p.add_subparsers(dest="command", required=True)
    for name in ZOO_COMMANDS:
        sub.add_parser(name, help=f"rl_zoo3.{name} with the frictiongym ids registered (zoo options)")
    what = "a zoo run against the best classical baseline (validation suite)"
    v = sub.add_parser("validate", help=what, description=what, formatter_class=Formatter)
    v.add_argument("--algo", required=True, help="the zoo's algorithm, e.g. sac")
    v.add_argument("--env", required=True, help="a frictiongym id, e.g. frictiongym/KangRobot-Regulation-v1")
    v.add_argument("-f", "--folder", default="logs", help="the zoo's log folder")
    v.add_argument("--exp-id", type=int, default=0, help="0: the latest run")
    v.add_argument("--episodes", type=int, default=10, help="first validation-suite episodes")
    v.add_argument(
        "--trust-pickle", action="store_true", help="load the run's SB3 zip and VecNormalize (pickles)"
    )
    args = p.parse_args(argv)
    zoo = _zoo_module()
    if zoo is None:
        return 2
    run = zoo.zoo_run(args.folder, args.algo, args.env, args.exp_id)
    try:
        out = zoo.validate(run, args.algo, args.env, args.episodes, trust_pickle=args.trust_pickle)
    except ValueError as e:  # e.g. the pickles, without --trust-pickle
        print(f"error: {e}", file=sys.stderr)
        return 2
    b, a = out["baseline"], out["agent"]
    from frictiongym.envs.scenario import load_scenario

    main = load_scenario(out["scenario"]).main_metric
    print(f"{run}: {out['scenario']}, first {args.episodes} validation episodes, {main} (lower is better)")
    print(f"  best classical {b.name}: {main} {b.main:.4g}, effort_rms {b.effort_rms:.4g}")
    print(f"  zoo agent: {main} {a[main]:.4g}, effort_rms {a['effort_rms']:.4g}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
