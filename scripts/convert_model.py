"""Convert a stable-baselines3 model folder (manifest.yaml naming model.zip and vecnormalize.pkl) into the
safe model format the leaderboard loads: policy.safetensors and a manifest with the network and SHA-256.

    frictiongym convert-model SRC_FOLDER [SRC_FOLDER ...] --trust-pickle --out DEST

An SB3 zip and a VecNormalize file are pickles: loading them runs any code they hold. --trust-pickle says
that you trust where they came from; it is required, and they are read by this command only. The new
folder (DEST/<name>/) holds no pickle and can be shared and loaded safely (docs/models.md).
"""

from __future__ import annotations

import sys
from pathlib import Path

from frictiongym.scripts.options import parser


def main(argv: list[str] | None = None) -> int:
    ap = parser(__doc__)
    ap.add_argument("src", nargs="+", type=Path, help="model folders of the SB3 form")
    ap.add_argument("--out", type=Path, required=True, help="folder to write the converted folders into")
    ap.add_argument(
        "--trust-pickle", action="store_true", help="load the SB3 zip and pickle (they can run code)"
    )
    args = ap.parse_args(argv)
    from frictiongym.agents.learned.convert import convert_folder  # start-up cost: after --help

    root = Path.cwd()
    for src in args.src:
        try:
            print(convert_folder(src, args.out, trust_pickle=args.trust_pickle, root=root))
        except (ValueError, OSError) as e:
            print(f"error: {src}: {e}", file=sys.stderr)
            return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
