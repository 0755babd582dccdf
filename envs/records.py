"""Writing results: files replaced atomically (a reader, or an interrupted run, never sees a half-written
file) and the provenance every result carries (package version, git commit, the exact command)."""

from __future__ import annotations

import csv
import io
import json
import os
import shlex
import subprocess
import sys
import uuid
from collections.abc import Callable
from importlib.metadata import PackageNotFoundError, distribution, version
from pathlib import Path
from typing import Any
from urllib.parse import unquote, urlparse


def atomic_write(path: Path, write: Callable[[Path], None]) -> None:
    """write(tmp) into a temporary file of its own beside path (a unique name with path's suffix: some
    writers append their own; two runs writing the same path never share one), flush it to disk, then
    rename it over path. On any failure the temporary file is removed and path is left as it was."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}-{uuid.uuid4().hex[:12]}.tmp{path.suffix}")
    try:
        write(tmp)
        with open(tmp, "rb+") as f:
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def atomic_text(path: Path, text: str) -> None:
    """A whole text file, atomically."""
    atomic_write(path, lambda p: p.write_text(text))


def pyplot() -> Any:
    """matplotlib.pyplot on the file backend (Agg): the one place the package selects a backend, for the
    figures it writes as files (agents/figures.py saves them). Imported when a figure is drawn."""
    import matplotlib  # start-up cost: imported where a figure is drawn

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def csv_text(rows: list[dict[str, Any]], fields: list[str] | None = None) -> str:
    """Rows as CSV text with a header: `fields` (default: the first row's keys); missing values empty."""
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=fields or list(rows[0]), restval="", lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    return buf.getvalue()


def package_version() -> str:
    """The installed frictiongym version ("unknown" when running from an uninstalled tree)."""
    try:
        return version("frictiongym")
    except PackageNotFoundError:
        return "unknown"


def install_command(extra: str) -> str:
    """The pip command that adds an extra to this installation as it was made: editable from its folder,
    from its folder, or by name."""
    try:
        dist = distribution("frictiongym")
    except PackageNotFoundError:
        return f"pip install 'frictiongym[{extra}]'"
    text = dist.read_text("direct_url.json")
    info = json.loads(text) if text else {}
    base = Path(str(dist.locate_file("")))
    if not info and (base / "setup.cfg").is_file():  # a checkout's own metadata (setup.py develop)
        return f"pip install -e '{base}[{extra}]'"
    url = info.get("url", "")
    if url.startswith("file://"):
        path = unquote(urlparse(url).path)
        editable = info.get("dir_info", {}).get("editable", False)
        return f"pip install {'-e ' if editable else ''}'{path}[{extra}]'"
    return f"pip install 'frictiongym[{extra}]'"


def missing_extra(e: ModuleNotFoundError, extra: str, what: str) -> str:
    """One line for a command that needs an optional extra which is not installed."""
    return f"error: {what} needs the {extra} extra ({e.name} is not installed): {install_command(extra)}"


def git_commit() -> str:
    """The commit of the code's git checkout ("" outside one)."""
    try:
        return subprocess.run(
            ["git", "rev-parse", "HEAD"],
            cwd=Path(__file__).parent,
            capture_output=True,
            text=True,
            timeout=10,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""


def command_line() -> str:
    """The exact command this process runs, shell-quoted, as typed from the repository: `frictiongym
    COMMAND ...` when the frictiongym command dispatched it (its argv[0] is "frictiongym COMMAND"), else
    python and the script, relative to the working directory when it lies below it."""
    argv0, rest = sys.argv[0], sys.argv[1:]
    if argv0.startswith("frictiongym "):
        return shlex.join([*argv0.split(" ", 1), *rest])
    path = Path(argv0)
    if path.is_absolute() and path.is_relative_to(Path.cwd()):
        argv0 = str(path.relative_to(Path.cwd()))
    return shlex.join([Path(sys.executable).name, argv0, *rest])
