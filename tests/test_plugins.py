"""A user's controller (a plug-in, path.py:Class) is checked before the work starts: one control period on
each of its scenarios before any episode runs, and every mistake ends in one line naming what and where
(the controller, scenario, seed and step; the file's classes where the name is wrong or missing)."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from frictiongym.scripts import cli

PLUGIN = '''
from typing import ClassVar

from frictiongym.agents.base import PhysicalController


class Signature(PhysicalController):
    """A command without the reference argument."""

    name: ClassVar[str] = "Signature"

    def command(self, y):
        return 0.0


class NaNs(PhysicalController):
    """NaN from step STEP on."""

    name: ClassVar[str] = "NaNs"
    step = 0

    def start(self, ctx):
        self.k = 0

    def command(self, y, r):
        self.k += 1
        return float("nan") if self.k > self.step else 0.0
'''


@pytest.fixture
def plugin(tmp_path: Path) -> Path:
    path = tmp_path / "mine.py"
    path.write_text(textwrap.dedent(PLUGIN))
    return path


def leaderboard(capsys: pytest.CaptureFixture, out: Path, *controllers: str, workers: int = 1) -> str:
    """`frictiongym leaderboard` on two Kang scenarios with these controllers: its stderr, after checking
    it failed with exit code 2, ending in one line (no traceback)."""
    argv = ["leaderboard", "--scenarios", "kang_ramp", "kang_regulation", "--seeds", "5000-5001"]
    argv += [
        "--randomize",
        "--models",
        "--workers",
        str(workers),
        "--out",
        str(out),
        "--controllers",
        *controllers,
    ]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err.strip()  # the progress bar, then the error
    assert "Traceback" not in err and err.splitlines()[-1].startswith("error: "), err
    return err.splitlines()[-1]


def test_a_wrong_command_signature_is_named_before_any_episode(plugin, tmp_path, capsys):
    err = leaderboard(capsys, tmp_path / "run", "PID", f"{plugin}:Signature")
    assert "controller Signature on kang_ramp, seed 5000, step 0: TypeError" in err and "command()" in err
    assert not (tmp_path / "run" / "episodes.csv").exists()  # no reference episode ran


@pytest.mark.slow  # a process pool
def test_a_nan_command_is_named_with_its_step(plugin, tmp_path, capsys):
    err = leaderboard(capsys, tmp_path / "first", f"{plugin}:NaNs")
    assert "controller NaNs on kang_ramp, seed 5000, step 0: ValueError: actions must be finite" in err
    assert not (tmp_path / "first" / "episodes.csv").exists()
    # NaN later in the episode: the run stops at that step, on a worker of the pool, in one line
    later = plugin.with_name("later.py")
    later.write_text(plugin.read_text().replace("step = 0", "step = 7"))
    err = leaderboard(capsys, tmp_path / "later", f"{later}:NaNs", workers=2)
    assert "controller NaNs on kang_ramp, seeds 5000..5001, step 7: ValueError: actions must be finite" in err


def test_a_file_without_its_class_gets_the_form_and_the_classes_it_defines(plugin, tmp_path, capsys):
    err = leaderboard(capsys, tmp_path / "run", str(plugin))
    assert f"{plugin} is a file: name its class as {plugin}:ClassName (it defines Signature, NaNs)" in err


def test_a_wrong_class_name_lists_the_files_controllers(plugin, tmp_path, capsys):
    err = leaderboard(capsys, tmp_path / "run", f"{plugin}:Nope")
    assert "has no 'Nope'; its controllers: NaNs, Signature" in err


MARKER_PLUGIN = '''
from pathlib import Path
from typing import ClassVar

from frictiongym.agents.base import PhysicalController

Path(__file__).with_name("imported").write_text("the plug-in's code ran")


class Marker(PhysicalController):
    """Zero command; importing its file leaves a marker beside it."""

    name: ClassVar[str] = "Marker"

    def command(self, y, r):
        return 0.0
'''


@pytest.mark.slow  # four leaderboards
def test_a_results_folder_runs_no_code_it_names(tmp_path, capsys):
    """--report-from reads run.json as data: a plug-in it names is imported only when the command line
    names it too (--controllers), else the report is refused in one line naming the flag; the same for a
    model folder (--models)."""
    plugin = tmp_path / "code" / "marker.py"
    plugin.parent.mkdir()
    plugin.write_text(textwrap.dedent(MARKER_PLUGIN))
    run = tmp_path / "run"
    argv = ["leaderboard", "--scenarios", "kang_regulation", "--seeds", "5000", "--workers", "1", "--models"]
    assert cli.main([*argv, "--controllers", "PD", f"{plugin}:Marker", "--out", str(run)]) == 0
    (plugin.parent / "imported").unlink()  # the run itself imported it, as it should
    capsys.readouterr()
    assert (
        cli.main(["leaderboard", "--report-from", str(run), "--models", "--out", str(tmp_path / "r1")]) == 2
    )
    err = capsys.readouterr().err.strip()
    assert (
        f"names the plug-in '{plugin}:Marker', whose code would run: pass --controllers {plugin}:Marker"
        in err
    )
    assert not (plugin.parent / "imported").exists() and not (tmp_path / "r1" / "index.html").exists()
    # named on the command line: allowed, and its report written
    report = ["leaderboard", "--report-from", str(run), "--models", "--controllers", f"{plugin}:Marker"]
    assert cli.main([*report, "--out", str(tmp_path / "r2")]) == 0
    assert (tmp_path / "r2" / "index.html").is_file()
    # a model folder run.json names but the command line does not: refused by name
    folder = next(p for p in (Path(__file__).parents[1] / "agents/models/specialist").iterdir() if p.is_dir())
    assert (
        cli.main([*argv[:-1], "--models", str(folder), "--controllers", "PD", "--out", str(tmp_path / "m")])
        == 0
    )
    capsys.readouterr()
    assert (
        cli.main(
            ["leaderboard", "--report-from", str(tmp_path / "m"), "--models", "--out", str(tmp_path / "r3")]
        )
        == 2
    )
    assert f"names the model folder '{folder}': pass --models {folder}" in capsys.readouterr().err


def test_an_action_of_the_wrong_shape_is_named_like_a_nan(tmp_path, capsys):
    """Every refusal of the env's action check (envs.core.ActionError), not only a NaN, is the
    controller's mistake named with its scenario, seed and step."""
    shape = tmp_path / "shape.py"
    shape.write_text(
        "from frictiongym.agents.base import PhysicalController\n\n\n"
        "class Shape(PhysicalController):\n"
        "    name = 'Shape'\n\n"
        "    def act(self, obs):  # two actions where the env takes one\n"
        "        return [0.0, 0.0]\n\n"
        "    def command(self, y, r):\n"
        "        return 0.0\n"
    )
    err = leaderboard(capsys, tmp_path / "run", f"{shape}:Shape")
    assert "controller Shape on kang_ramp, seed 5000, step 0: ValueError: expected one action per env" in err
