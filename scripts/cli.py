"""The `frictiongym` command (setup.cfg's console_scripts): `frictiongym COMMAND [options]` runs the front
end scripts/<command>.py with the same options, e.g.

    frictiongym leaderboard --suite default
    frictiongym train --config residual_sac --scenario kang_regulation --seed 0 1 2 --steps 3000
    frictiongym reproduce --sections m220
    frictiongym COMMAND --help
"""

from __future__ import annotations

import ast
import importlib
import importlib.util
import sys
import textwrap
from pathlib import Path

from frictiongym.envs.records import package_version

COMMANDS = {  # subcommand -> module of frictiongym.scripts
    "list": "list_envs",
    "leaderboard": "leaderboard",
    "train": "train",
    "tune": "tune",
    "sim2real": "sim2real",
    "windows": "windows",
    "identify": "identify",
    "reproduce": "reproduce",
    "render": "render",
    "docs": "docs",
    "zoo": "zoo",
    "convert-model": "convert_model",
    "export": "export",
    "run-drive": "run_drive",
    "virtual-drive": "virtual_drive",
    "rehearse": "rehearse",
    "check-draws": "check_draws",
    "bench-envs": "bench_envs",
    "bench-physics": "bench_physics",
    "bench-leaderboard": "bench_leaderboard",
    "bench-versions": "bench_versions",
    "bench-training": "bench_training",
    "bench-runtime": "bench_runtime",
    "bench-cli": "bench_cli",
}


def summary(command: str) -> str:
    """The first sentence of the command's module docstring, whole, read without importing the module
    (train imports torch)."""
    spec = importlib.util.find_spec(f"{__package__}.{COMMANDS[command]}")
    doc = ast.get_docstring(ast.parse(Path(spec.origin).read_text())) or ""
    first = " ".join(doc.split("\n\n")[0].split())  # the first paragraph, on one line
    return first.split(". ")[0].split(": ")[0].rstrip(".:")


def usage() -> str:
    """The top-level help: every command with its whole summary, wrapped under its name."""
    width = max(map(len, COMMANDS))
    lines = [
        textwrap.fill(
            summary(c), 100, initial_indent=f"  {c:<{width}}  ", subsequent_indent=" " * (width + 4)
        )
        for c in COMMANDS
    ]
    head = "usage: frictiongym COMMAND [options]  (frictiongym COMMAND --help)\n\ncommands:\n"
    return head + "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Dispatch to scripts/<command>.py's main with the remaining arguments; its exit code is ours."""
    argv = sys.argv[1:] if argv is None else argv
    if not argv or argv[0] in ("-h", "--help"):
        print(usage())
        return 0 if argv else 2
    if argv[0] == "--version":
        print(f"frictiongym {package_version()}")
        return 0
    command, rest = argv[0], argv[1:]
    if command not in COMMANDS:
        print(f"frictiongym: unknown command {command!r}\n\n{usage()}", file=sys.stderr)
        return 2
    module = importlib.import_module(f"{__package__}.{COMMANDS[command]}")
    saved = sys.argv
    # the front ends parse sys.argv; argparse's usage then names the command
    sys.argv = [f"frictiongym {command}", *rest]
    try:
        return module.main() or 0
    finally:
        sys.argv = saved


if __name__ == "__main__":
    sys.exit(main())
