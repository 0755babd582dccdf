"""Reproduce the documents' numbers on the simulator: writes DIR/report.json, DIR/report.md and figures.

python scripts/reproduce.py [--out out/reproduce] [--sections m220 kang ...]

Walks the sections of frictiongym.agents.reproduce (one module per document) in report order; exits 1 if
any row fails.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from tqdm import tqdm

from frictiongym.agents import reproduce
from frictiongym.envs.records import atomic_text


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=Path("out/reproduce"), help="output folder")
    ap.add_argument("--sections", nargs="*", choices=reproduce.section_names(), help="subset of sections")
    args = ap.parse_args(argv)
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
