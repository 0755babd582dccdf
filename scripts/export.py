"""Export a controller as an artefact a drive-side runtime steps (agents/deploy/runtime.py): a built-in
controller or residual base by name, or a saved model's folder, for a scenario (a model's own by default).

    frictiongym export agents/models/generalist/GenSAC-kang-ff-kang_random-s0 --out out/export/kang
    frictiongym export PID+FF --scenario m220_reversal_tracking --out out/export/pidff

The folder holds runtime.yaml (the scenario, its sampling, scaling and preview, the controller's designed
parameters, SHA-256 of every file), a saved model's manifest and weights (no pickle) and its network as
ONNX. Load it with frictiongym.agents.deploy.runtime.Runtime.load(DIR) and call step(readings, reference,
preview).
"""

from __future__ import annotations

import sys
from pathlib import Path

from frictiongym.envs.records import missing_extra
from frictiongym.scripts.options import parser


def main(argv: list[str] | None = None) -> int:
    ap = parser(__doc__)
    ap.add_argument("source", help="a controller's name (e.g. PID+FF) or a saved model's folder")
    ap.add_argument("--scenario", help="the scenario to run on (default: a saved model's own)")
    ap.add_argument("--out", type=Path, required=True, help="the artefact's folder (created)")
    args = ap.parse_args(argv)
    try:
        from frictiongym.agents.deploy.runtime import export  # onnx (the deploy extra) if learned

        print(export(args.source, args.out, args.scenario))
    except ModuleNotFoundError as e:
        print(missing_extra(e, "deploy", "frictiongym export"), file=sys.stderr)
        return 2
    except (ValueError, OSError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
