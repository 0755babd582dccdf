"""The package's dependency rules, read from the installed package's source: imports point one way (the
simulated world `envs` imports nothing else of the project), no import circle anywhere (function-local
imports included: a circle hidden in a function is still one), and a function-local import says why."""

from __future__ import annotations

import ast
import graphlib
import importlib.util
import pkgutil
from pathlib import Path

import pytest

import frictiongym.agents
import frictiongym.envs
import frictiongym.scripts

PACKAGES = (frictiongym.envs, frictiongym.agents, frictiongym.scripts)
# Imports that may stay inside a function without a comment, for the reason named: optional extras
# (setup.cfg's rl, distributed, sbx, zoo, video) and matplotlib's start-up cost (plots only).
LOCAL_OK = {
    "torch": "rl extra",
    "stable_baselines3": "rl extra",
    "sb3_contrib": "rl extra",
    "ray": "distributed extra",
    "optuna": "distributed extra",
    "sbx": "sbx extra",
    "jax": "sbx extra",
    "flax": "sbx extra",
    "rl_zoo3": "zoo extra",
    "moviepy": "video extra",
    "matplotlib": "start-up cost; plots only",
}


def _modules() -> dict[str, tuple[Path, bool]]:
    """Every module of the installed package: name -> (source file, is a package)."""
    out = {}
    for pkg in PACKAGES:
        out[pkg.__name__] = (Path(pkg.__file__), True)
        for info in pkgutil.walk_packages(pkg.__path__, pkg.__name__ + "."):
            spec = importlib.util.find_spec(info.name)
            out[info.name] = (Path(spec.origin), info.ispkg)
    return out


MODULES = _modules()


def _imports(name: str, typing: bool = False) -> list[tuple[str, bool, int, str]]:
    """(imported project module, inside a function, line, source line) for each import in module `name`;
    `from pkg import x` is an import of pkg.x where that is a module, else of pkg. `typing`: the imports
    under `if TYPE_CHECKING:` too."""
    path, ispkg = MODULES[name]
    source = path.read_text()
    lines = source.splitlines()
    found = []

    def target(node: ast.ImportFrom) -> str:
        if node.level == 0:
            return node.module or ""
        parts = name.split(".") if ispkg else name.split(".")[:-1]
        parts = parts[: len(parts) - node.level + 1]
        return ".".join([*parts, *([node.module] if node.module else [])])

    def visit(node: ast.AST, local: bool) -> None:
        for child in ast.iter_child_nodes(node):
            type_only = isinstance(child, ast.If) and getattr(child.test, "id", None) == "TYPE_CHECKING"
            if type_only and not typing:
                continue
            inner = local or isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef)
            if isinstance(child, ast.Import):
                for a in child.names:
                    found.append((a.name, local, child.lineno, lines[child.lineno - 1]))
            elif isinstance(child, ast.ImportFrom):
                t = target(child)
                for a in child.names:
                    sub = f"{t}.{a.name}"
                    found.append((sub if sub in MODULES else t, local, child.lineno, lines[child.lineno - 1]))
            visit(child, inner)

    visit(ast.parse(source), False)
    return found


def test_the_walk_finds_every_room():
    """The checks below see the whole package (a walk that found nothing would pass them all)."""
    for name in (
        "frictiongym.envs.core",
        "frictiongym.envs.plants.sim",
        "frictiongym.agents.lab.radau",
        "frictiongym.agents.reproduce.kang1998",
        "frictiongym.agents.classical.pid",
        "frictiongym.agents.evaluation.leaderboard",
        "frictiongym.agents.learned.folder",
        "frictiongym.agents.deploy.runtime",
        "frictiongym.agents.tuning.search",
    ):
        assert name in MODULES
    assert len(MODULES) > 60


def test_the_simulated_world_imports_nothing_else_of_the_project():
    bad = [
        f"{name}:{line}: {text.strip()}"
        for name in MODULES
        if name.startswith("frictiongym.envs")
        for target, _, line, text in _imports(name)
        if target.startswith("frictiongym.") and not target.startswith("frictiongym.envs")
    ]
    assert not bad, bad


def _circle(names: list[str], typing: bool = False) -> list[str]:
    """An import circle among `names` (the imports a type checker follows too, with `typing`), or []."""
    graph = graphlib.TopologicalSorter()
    for name in names:
        graph.add(name)
        for target, _, _, _ in _imports(name, typing):
            if target in names and target != name:
                graph.add(name, target)
    try:
        graph.prepare()
    except graphlib.CycleError as e:
        return list(e.args[1])
    return []


def test_no_import_circle_anywhere():
    circle = _circle(list(MODULES))
    assert not circle, f"import circle: {' -> '.join(circle)}"


def test_no_circle_among_the_rooms_type_only_imports_included():
    """Within every room of agents/ (evaluation: the leaderboard's board, report, page and leaderboard
    among them), the imports a type checker follows form no circle either: a room reads one way."""
    agents = [n for n in MODULES if n.startswith("frictiongym.agents.") and n.count(".") > 2]
    rooms = {n.rsplit(".", 1)[0] + "." for n in agents}
    assert "frictiongym.agents.evaluation." in rooms and "frictiongym.agents.training." in rooms
    for room in sorted(rooms):
        circle = _circle([n for n in MODULES if n.startswith(room)], typing=True)
        assert not circle, f"import circle in {room}: {' -> '.join(circle)}"


def test_the_code_and_the_committed_models_have_different_names():
    """agents/models/ holds committed model folders (data); the code that reads them is agents/learned/."""
    assert not any(n.startswith("frictiongym.agents.models") for n in MODULES)
    assert "frictiongym.agents.learned.folder" in MODULES


def test_a_function_local_import_states_its_reason():
    """As stable-baselines3 does: an optional extra or a start-up cost (LOCAL_OK), or a comment saying
    why on the import's line. A front end (frictiongym.scripts) imports its work after its options are
    parsed, so that its --help answers at once (scripts/options.py; tests/test_cli.py)."""
    bad = [
        f"{name}:{line}: {text.strip()}"
        for name in MODULES
        if not name.startswith("frictiongym.scripts.")
        for target, local, line, text in _imports(name)
        if local and target.split(".")[0] not in LOCAL_OK and "#" not in text
    ]
    assert not bad, bad


def test_the_rules_catch_what_they_forbid(tmp_path, monkeypatch):
    """A module of envs importing agents, inside a function and without a comment, breaks two rules."""
    fake = tmp_path / "fake.py"
    fake.write_text("def f():\n    from frictiongym.agents import registry\n")
    monkeypatch.setitem(MODULES, "frictiongym.envs.fake", (fake, False))
    found = _imports("frictiongym.envs.fake")
    assert found == [("frictiongym.agents.registry", True, 2, "    from frictiongym.agents import registry")]
    with pytest.raises(AssertionError):
        test_the_simulated_world_imports_nothing_else_of_the_project()
    with pytest.raises(AssertionError):
        test_a_function_local_import_states_its_reason()


def test_a_circle_is_found(tmp_path, monkeypatch):
    for a, b in (("fa", "fb"), ("fb", "fa")):
        (tmp_path / f"{a}.py").write_text(f"from . import {b}\n")
        monkeypatch.setitem(MODULES, f"frictiongym.agents.{a}", (tmp_path / f"{a}.py", False))
    with pytest.raises(AssertionError, match="import circle"):
        test_no_import_circle_anywhere()
