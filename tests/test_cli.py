"""The `frictiongym` command answers --help at once: the top level and every command's help import none
of the heavy modules (MuJoCo, torch, stable-baselines3, Ray, JAX, onnxruntime: seconds of start-up), every
option says what it is, the top-level list gives each command's whole summary, and each command's help
spells it one way (`frictiongym COMMAND`). The times themselves: `frictiongym bench-cli`."""

from __future__ import annotations

import argparse

import pytest

from frictiongym.scripts import cli
from frictiongym.scripts.bench_cli import heavy_imports


@pytest.mark.slow  # fresh interpreters
@pytest.mark.parametrize("argv", [["--help"], *([c, "--help"] for c in cli.COMMANDS)], ids=lambda a: a[0])
def test_help_imports_no_heavy_module(argv: list[str]) -> None:
    assert heavy_imports(argv) == [], f"frictiongym {' '.join(argv)} imports them"


def test_the_probe_sees_a_heavy_import() -> None:
    # the check above is not vacuous: running a command (not its help) imports MuJoCo
    assert "mujoco" in heavy_imports(["list"])


class Built(Exception):
    """Raised when a command's parser starts parsing: it carries the parser."""


def command_parser(command: str, monkeypatch: pytest.MonkeyPatch) -> argparse.ArgumentParser:
    """The command's top-level parser, as its main builds it (nothing runs)."""

    def capture(self: argparse.ArgumentParser, args=None, namespace=None):
        raise Built(self)

    monkeypatch.setattr(argparse.ArgumentParser, "parse_known_args", capture)
    with pytest.raises(Built) as e:
        cli.main([command])
    return e.value.args[0]


def parsers(ap: argparse.ArgumentParser) -> list[argparse.ArgumentParser]:
    """The parser and its sub-commands' parsers."""
    out = [ap]
    for a in ap._actions:
        if isinstance(a, argparse._SubParsersAction):
            for sub in a.choices.values():
                out += parsers(sub)
    return out


# the zoo's own commands pass their options to rl_zoo3, which documents them
@pytest.mark.parametrize("command", [c for c in cli.COMMANDS if c != "zoo"] + ["zoo validate"])
def test_every_option_has_help(command: str, monkeypatch: pytest.MonkeyPatch) -> None:
    name, *sub = command.split()
    ap = command_parser(name, monkeypatch)
    if sub:
        ap = next(p for p in parsers(ap) if p.prog.endswith(sub[0]))
    missing = [
        a.dest
        for a in ap._actions
        if not isinstance(a, argparse._HelpAction | argparse._SubParsersAction) and not (a.help or "").strip()
    ]
    assert not missing, f"{command}: options without help {missing}"
    text = ap.format_help()
    assert "python scripts/" not in text, f"{command}'s help spells the command two ways"
    assert ap.description, f"{command} has no description"


def test_help_shows_defaults() -> None:
    ap = cli.importlib.import_module("frictiongym.scripts.options").parser("doc")
    ap.add_argument("--seconds", type=float, default=4.0, help="measuring time")
    ap.add_argument("--seed", type=int, default=0, help="the seed")
    ap.add_argument("--out", default="out/x", help="the folder (default: out/x)")
    text = " ".join(ap.format_help().split())
    assert "measuring time (default: 4.0)" in text
    assert "the seed (default: 0)" in text  # a zero is a default to show (0 == False, but not False)
    assert "(default: out/x) (default" not in text  # a help that names its default is not repeated


def test_the_list_gives_whole_summaries() -> None:
    text = cli.usage()
    assert "…" not in text
    for command in cli.COMMANDS:
        assert " ".join(cli.summary(command).split()) in " ".join(text.split())
