"""Identical-scenario suites (configs/suites.yaml): named, ordered lists of episodes (scenario, seed,
randomize). Every episode's parameters and initial state are drawn from its seed alone (numpy's
SeedSequence/PCG64, platform independent), so every controller sees the same episodes on every machine."""

from __future__ import annotations

from dataclasses import dataclass

from .config import ConfigError, Node, boolean, configs_dir, integer, load_yaml
from .scenario import scenario_config, scenario_names

FILE = "suites.yaml"


@dataclass(frozen=True)
class Episode:
    """One episode: (scenario, seed, randomize), and optionally pinned parameters (randomization keys and
    values, sorted) that replace the drawn ones (reset(options={"params": ...}): sim-to-real shifts). The
    pinned key `friction_model` (a name, not a number) is structural: the env is built with that friction
    structure (the scenario key of the same name), the sim-to-real study's structural axis."""

    scenario: str
    seed: int
    randomize: bool
    params: tuple[tuple[str, float | str], ...] = ()

    def options(self) -> dict | None:
        """The reset options of the episode (the pinned values, without the structural key)."""
        pinned = {k: v for k, v in self.params if k not in STRUCTURAL}
        return {"params": pinned} if pinned else None

    def overrides(self) -> dict | None:
        """The scenario overrides the episode's structural keys make (None: the scenario as it is)."""
        return {k: v for k, v in self.params if k in STRUCTURAL} or None


STRUCTURAL = ("friction_model",)  # pinned keys that change how the env is built, not a drawn value


def suite_names() -> list[str]:
    return sorted(load_yaml(configs_dir() / FILE))


def _suite(name: str) -> Node:
    suites = Node(load_yaml(configs_dir() / FILE), FILE)
    if name not in suites:
        raise ConfigError("suite", f"unknown suite {name!r}; available: {sorted(suites.keys())}", FILE)
    return suites.section(name)


def suite_held_out(name: str) -> bool:
    """Whether a suite is held out (`held_out: true`, the generalisation suite): its scenarios are never
    trained or selected on."""
    return _suite(name).boolean("held_out", default=False)


def load_suite(name: str) -> list[Episode]:
    """The suite's episodes, scenario-major, in the file's order; every key and value checked. A held-out
    suite holds held-out scenarios only, and no other suite holds one."""
    s = _suite(name)
    randomize = s.boolean("randomize")
    held_out = s.boolean("held_out", default=False)
    known = scenario_names()
    scenarios = s["scenarios"]
    if not isinstance(scenarios, list) or not scenarios:
        raise s.error("scenarios", f"expected a non-empty list, got {scenarios!r}")
    for i, sc in enumerate(scenarios):
        if sc not in known:
            raise s.error(f"scenarios[{i}]", f"unknown scenario {sc!r}; available: {known}")
        if boolean(scenario_config(sc).get("held_out", False), f"{sc}: held_out") != held_out:
            why = "is not held out" if held_out else "is held out (the generalisation suite's)"
            raise s.error(f"scenarios[{i}]", f"{sc} {why}; a suite is held out whole or not at all")
    if isinstance(s["seeds"], dict):  # {start, count}
        r = s.section("seeds")
        start, count = r.integer("start", 0), r.integer("count", 1, 100_000)
        seeds = list(range(start, start + count))
    elif isinstance(s["seeds"], list) and s["seeds"]:
        seeds = [s.check(integer, x, s.field(f"seeds[{i}]"), 0) for i, x in enumerate(s["seeds"])]
    else:
        raise s.error("seeds", f"expected a non-empty list or {{start, count}}, got {s['seeds']!r}")
    s.done()
    return [Episode(sc, seed, randomize) for sc in scenarios for seed in seeds]
