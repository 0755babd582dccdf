"""The tutorials run as written: every `bash` and `python` block of docs/tutorials/*.md, in order, in a
folder that holds only the repository's committed models (agents/, as from the repository root): the
Python blocks share one interpreter, a bash block runs in a shell from Python at its place. A tutorial
that breaks fails here, and so in CI."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[1]
PAGES = sorted(p for p in (ROOT / "docs" / "tutorials").glob("*.md") if p.name != "index.md")
BLOCK = re.compile(r"^```(bash|python)\n(.*?)^```$", re.S | re.M)


FILE = "# file: "  # a python block that starts so is a file the reader saves at that path, not code to run


def script(page: Path) -> str:
    """The page as one Python script: its python blocks as they are (a block starting `# file: PATH`
    written to PATH instead), its bash blocks run by bash."""
    parts = ["import pathlib", "import subprocess"]
    for lang, code in BLOCK.findall(page.read_text()):
        if lang == "python" and code.startswith(FILE):
            path = code.splitlines()[0][len(FILE) :].strip()
            parts.append(f"pathlib.Path({path!r}).parent.mkdir(parents=True, exist_ok=True)")
            parts.append(f"pathlib.Path({path!r}).write_text({code!r})")
        elif lang == "python":
            parts.append(code)
        else:
            parts.append(f"subprocess.run(['bash', '-euo', 'pipefail', '-c', {code!r}], check=True)")
    return "\n".join(parts)


def test_tutorials_write_only_under_out():
    """What a tutorial saves goes under out/ (or a temporary folder), never into the repository's tree."""
    for page in PAGES:
        for lang, code in BLOCK.findall(page.read_text()):
            if lang == "python" and code.startswith(FILE):
                assert code.splitlines()[0][len(FILE) :].startswith("out/"), page.name
            for target in re.findall(r"open\(\s*[\"']([^\"']+)[\"']\s*,\s*[\"']w", code):
                assert target.startswith("out/"), f"{page.name} writes {target}"
            for target in re.findall(r"--out\s+(\S+)", code):
                assert target.startswith("out/"), f"{page.name} writes {target}"


def test_every_tutorial_is_listed_and_has_code():
    index = (ROOT / "docs" / "tutorials" / "index.md").read_text()
    assert PAGES and all(p.stem in index and BLOCK.search(p.read_text()) for p in PAGES)


@pytest.mark.slow
@pytest.mark.parametrize("page", PAGES, ids=[p.stem for p in PAGES])
def test_tutorial_runs_as_written(page, tmp_path):
    (tmp_path / "tutorial.py").write_text(script(page))
    (tmp_path / "agents").symlink_to(ROOT / "agents")
    proc = subprocess.run(
        [sys.executable, "tutorial.py"], cwd=tmp_path, capture_output=True, text=True, timeout=900
    )
    assert proc.returncode == 0, f"{page.name}:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
