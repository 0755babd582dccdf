"""Identical-scenario suites (configs/suites.yaml): named, ordered lists of episodes (scenario, seed,
randomize). Every episode's parameters and initial state are drawn from its seed alone (numpy's
SeedSequence/PCG64, platform independent), so every controller sees the same episodes on every machine."""

from __future__ import annotations

from dataclasses import dataclass

from .config import ConfigError, Node, configs_dir, integer, load_yaml
from .scenario import scenario_names

FILE = "suites.yaml"


@dataclass(frozen=True)
class Episode:
    scenario: str
    seed: int
    randomize: bool


def suite_names() -> list[str]:
    return sorted(load_yaml(configs_dir() / FILE))


def load_suite(name: str) -> list[Episode]:
    """The suite's episodes, scenario-major, in the file's order; every key and value checked."""
    suites = Node(load_yaml(configs_dir() / FILE), FILE)
    if name not in suites:
        raise ConfigError("suite", f"unknown suite {name!r}; available: {sorted(suites.keys())}", FILE)
    s = suites.section(name)
    randomize = s.boolean("randomize")
    known = scenario_names()
    scenarios, seeds = s["scenarios"], s["seeds"]
    for key, value in (("scenarios", scenarios), ("seeds", seeds)):
        if not isinstance(value, list) or not value:
            raise s.error(key, f"expected a non-empty list, got {value!r}")
    for i, sc in enumerate(scenarios):
        if sc not in known:
            raise s.error(f"scenarios[{i}]", f"unknown scenario {sc!r}; available: {known}")
    seeds = [s.check(integer, x, s.field(f"seeds[{i}]"), 0) for i, x in enumerate(seeds)]
    s.done()
    return [Episode(sc, seed, randomize) for sc in scenarios for seed in seeds]
