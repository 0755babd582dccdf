"""What the front ends' parsers share, importing nothing heavy: `frictiongym COMMAND --help` answers at
once because a command's parser is built from this module, configs/ listings and argparse only; the
engine, MuJoCo, torch and Ray are imported after the options are parsed."""

from __future__ import annotations

import argparse
import os
from typing import Any


class Formatter(argparse.RawDescriptionHelpFormatter, argparse.ArgumentDefaultsHelpFormatter):
    """The module docstring as written, and every option's default after its help (unless the help
    already names its default, or there is none to name: None, False, or an empty list)."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if "default" in text or action.default in (None, False, [], argparse.SUPPRESS):
            return text
        return super()._get_help_string(action) or ""


def parser(doc: str | None) -> argparse.ArgumentParser:
    """A command's parser: its module docstring as the description, defaults shown."""
    return argparse.ArgumentParser(description=doc, formatter_class=Formatter)


def seed_range(text: str) -> list[int]:
    """'5000-5049' (inclusive) or '7' -> the seeds."""
    lo, _, hi = text.partition("-")
    try:
        seeds = list(range(int(lo), int(hi or lo) + 1))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected A-B or A (non-negative integers), got {text!r}") from None
    if not seeds or seeds[0] < 0:
        raise argparse.ArgumentTypeError(f"expected A <= B, both >= 0, got {text!r}")
    return seeds


def scenario_name(text: str) -> str:
    """A scenario of configs/scenarios/ (argparse type): an unknown name is an error pointing to the list,
    not a list of all 40 in every --help."""
    from frictiongym.envs.config import scenario_names

    if text not in scenario_names():
        raise argparse.ArgumentTypeError(f"unknown scenario {text!r}: `frictiongym list` prints them")
    return text


def add_backend_arguments(ap: argparse.ArgumentParser) -> None:
    """--workers, --backend and --address of the commands that run engine jobs."""
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="processes (default: all cores)")
    ap.add_argument("--backend", choices=["local", "ray"], default="local", help="process pool or Ray tasks")
    ap.add_argument("--address", help="Ray cluster to join (default: a local Ray on --workers CPUs)")


def backend_of(args: Any, ap: argparse.ArgumentParser) -> Any:
    """The engine's Ray backend the parsed arguments ask for (None: the local pool); bad combinations are
    errors."""
    if args.workers < 1:
        ap.error("--workers must be >= 1")
    if args.address and args.backend != "ray":
        ap.error("--address goes with --backend ray")
    if args.backend != "ray":
        return None
    from frictiongym.agents.evaluation.engine import Ray

    return Ray(args.address)
