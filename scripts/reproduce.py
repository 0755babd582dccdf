"""Reproduce the documents' numbers on the simulator: writes DIR/report.json, DIR/report.md and figures.

    frictiongym reproduce [--out out/reproduce] [--sections m220 kang ...]

Walks the sections of frictiongym.agents.reproduce (one module per document) in report order; exits 1 if
any row fails.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from tqdm import tqdm

from frictiongym.envs.records import atomic_text
from frictiongym.scripts.options import parser


def main(argv: list[str] | None = None) -> int:
    ap = parser(__doc__)
    ap.add_argument("--out", type=Path, default=Path("out/reproduce"), help="output folder")
    ap.add_argument("--sections", nargs="*", metavar="SECTION", help="a subset of sections (default: all)")
    args = ap.parse_args(argv)
    from frictiongym.agents import reproduce  # start-up cost: --help imports no MuJoCo

    if unknown := sorted(set(args.sections or ()) - set(reproduce.section_names())):
        ap.error(f"--sections: unknown {unknown}; choose from {reproduce.section_names()}")
    args.out.mkdir(parents=True, exist_ok=True)
    chosen = [s for s in reproduce.sections() if not args.sections or s.name in args.sections]
    results = [reproduce.run_section(s, args.out) for s in tqdm(chosen, desc="reproducing", unit="section")]
    rows = [r for res in results for r in res.rows]
    atomic_text(args.out / "report.json", json.dumps(rows, indent=1))
    atomic_text(args.out / "report.md", reproduce.markdown(results))
    failed = [r["id"] for r in rows if not r["pass"]]
    print(f"{len(rows) - len(failed)}/{len(rows)} rows pass; report in {args.out / 'report.md'}")
    for r in failed:
        print(f"FAIL {r}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
