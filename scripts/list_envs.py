"""List the Gymnasium ids this package registers: one per plant (scenario= chooses the scenario) and one
per scenario, with each scenario's plant, task, length and main metric.

    frictiongym list [--markdown]

--markdown prints the table docs/envs.md holds (a test keeps the two equal).
"""

from __future__ import annotations

from frictiongym.envs import ENV_IDS, SCENARIO_IDS, _env_class
from frictiongym.scripts.options import parser

HEADER = ("id", "scenario", "plant", "task", "episode (s)", "steps", "main metric")


def rows() -> list[tuple[str, ...]]:
    """One row per registered id: the plants' (their default scenario), then every scenario's."""
    from frictiongym.envs.scenario import load_scenario  # start-up cost: --help imports no MuJoCo

    out = []
    for id_, (entry, _) in ENV_IDS.items():
        sc = load_scenario(_env_class(entry).default_scenario)
        out.append((id_, f"any (default {sc.name})", sc.spec.name, "", "", "", ""))
    for id_, name in sorted(SCENARIO_IDS.items()):
        sc = load_scenario(name)
        length = f"{sc.episode_steps * sc.control_period:g}"
        out.append((id_, name, sc.spec.name, sc.task, length, str(sc.episode_steps), sc.main_metric))
    return out


def markdown() -> str:
    """The table as Markdown."""
    lines = ["| " + " | ".join(HEADER) + " |", "|" + "---|" * len(HEADER)]
    lines += [
        "| " + " | ".join(f"`{c}`" if i < 2 and c and " " not in c else c for i, c in enumerate(r)) + " |"
        for r in rows()
    ]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = parser(__doc__)
    ap.add_argument("--markdown", action="store_true", help="the table as Markdown (docs/envs.md)")
    args = ap.parse_args(argv)
    if args.markdown:
        print(markdown(), end="")
        return 0
    table = [HEADER, *rows()]
    widths = [max(len(r[i]) for r in table) for i in range(len(HEADER))]
    for r in table:
        print("  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
