"""Every command line the README and docs/ show (a line that starts with `frictiongym ...` or
`python scripts/<command>.py ...`, continuation lines joined) is accepted by its command's parser: the docs
cannot drift from the options. Lines with a usage placeholder (`[...]`) are synopses, not commands. The
parser runs to its end and stops there (nothing is executed)."""

from __future__ import annotations

import argparse
import re
import shlex
from pathlib import Path

import pytest

from frictiongym.scripts import cli

ROOT = Path(__file__).resolve().parents[1]
LINE = re.compile(r"^\s*(?:\$\s*)?((?:frictiongym|python scripts/\w+\.py)\s.*)$")
BY_MODULE = {module: command for command, module in cli.COMMANDS.items()}


def documented_commands() -> list[tuple[str, str]]:
    """(file:line, command line) of every command shown at the start of a line in README.md and docs/."""
    out = []
    for f in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        lines = f.read_text().splitlines()
        i = 0
        while i < len(lines):
            m = LINE.match(lines[i])
            start = i
            if m:
                cmd = m.group(1)
                while cmd.rstrip().endswith("\\") and i + 1 < len(lines):
                    i += 1
                    cmd = cmd.rstrip()[:-1] + " " + lines[i].strip()
                if "[" not in cmd:
                    out.append((f"{f.relative_to(ROOT)}:{start + 1}", cmd))
            i += 1
    return out


class Parsed(Exception):
    """Raised when the command's top-level parser has finished: the line parsed."""


COMMANDS = documented_commands()


def test_the_docs_show_commands() -> None:
    # the README's first run and the docs' commands are found: the collector is not vacuous
    assert any(where.startswith("README.md") for where, _ in COMMANDS)
    assert len(COMMANDS) >= 10


def parse(where: str, cmd: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """Run cmd through its command's parser up to its end: Parsed if it parses, SystemExit(2) if not."""
    argv = shlex.split(cmd, comments=True)
    argv = [BY_MODULE[Path(argv[1]).stem], *argv[2:]] if argv[0] == "python" else argv[1:]
    assert argv[0] in cli.COMMANDS, f"{where}: unknown command {argv[0]!r}"
    original = argparse.ArgumentParser.parse_known_args
    depth = 0

    def parse_only(self: argparse.ArgumentParser, args=None, namespace=None):
        nonlocal depth
        depth += 1
        try:
            out = original(self, args, namespace)
        finally:
            depth -= 1
        if depth == 0:  # the top-level parser is done (a sub-command's parser runs nested)
            if out[1]:
                self.error(f"unrecognized arguments: {' '.join(out[1])}")  # what parse_args would say
            raise Parsed(out)
        return out

    monkeypatch.setattr(argparse.ArgumentParser, "parse_known_args", parse_only)
    cli.main(argv)


@pytest.mark.parametrize("where,cmd", COMMANDS, ids=[w for w, _ in COMMANDS])
def test_documented_command_parses(where: str, cmd: str, monkeypatch: pytest.MonkeyPatch) -> None:
    with pytest.raises(Parsed):
        parse(where, cmd, monkeypatch)


@pytest.mark.parametrize(
    "cmd",
    [
        "frictiongym leaderboard --no-such-option",
        "frictiongym train --config residual_sac --seeds 0 1",  # the option is --seed
        "python scripts/identify.py check --bogus",  # inside a sub-command
        "frictiongym leaderboard --suite nonexistent",
    ],
)
def test_a_wrong_command_line_is_caught(cmd: str, monkeypatch: pytest.MonkeyPatch) -> None:
    with pytest.raises(SystemExit) as e:
        parse("here", cmd, monkeypatch)
    assert e.value.code == 2  # argparse's usage error


def test_the_readme_answer_tables_are_the_committed_test_runs():
    """The README's per-plant answer is generated: each plant's table of the `test` run's answer.md
    (docs/results/test/answer.md, written by the leaderboard) appears in the README as it is."""
    answer = (ROOT / "docs" / "results" / "test" / "answer.md").read_text()
    tables = re.findall(r"^## (\S+)\n\n((?:\|.*\n)+)", answer, re.M)
    readme = (ROOT / "README.md").read_text()
    assert [p for p, _ in tables] == ["kang_robot", "m220", "flexible_servo", "emps"]
    for plant, table in tables:
        assert table in readme, plant


@pytest.mark.slow  # a fresh interpreter
def test_the_readme_python_example_runs_and_prints_units(tmp_path):
    """The README's Python block runs as written and prints its numbers with their units."""
    import subprocess
    import sys

    [code] = re.findall(r"^```python\n(.*?)^```$", (ROOT / "README.md").read_text(), re.S | re.M)
    proc = subprocess.run(
        [sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = proc.stdout.strip().splitlines()
    assert len(lines) == 2 and all(" mrad, command " in x and x.endswith(" V rms") for x in lines), lines
