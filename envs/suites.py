"""Identical-scenario suites (configs/suites.yaml): named, ordered lists of episodes (scenario, seed,
randomize). Every episode's parameters and initial state are drawn from its seed alone (numpy's
SeedSequence/PCG64, platform independent), so every controller sees the same episodes on every machine."""

from __future__ import annotations

from dataclasses import dataclass

from .config import ConfigError, configs_dir, load_yaml
from .scenario import scenario_names


@dataclass(frozen=True)
class Episode:
    scenario: str
    seed: int
    randomize: bool


def suite_names() -> list[str]:
    return sorted(load_yaml(configs_dir() / "suites.yaml"))


def load_suite(name: str) -> list[Episode]:
    """The suite's episodes, scenario-major, in the file's order."""
    suites = load_yaml(configs_dir() / "suites.yaml")
    if name not in suites:
        raise ConfigError("suite", f"unknown suite {name!r}; available: {sorted(suites)}")
    s = suites[name]
    known = scenario_names()
    for sc in s["scenarios"]:
        if sc not in known:
            raise ConfigError(f"suites.{name}.scenarios", f"unknown scenario {sc!r}; available: {known}")
    if not isinstance(s.get("randomize"), bool):
        raise ConfigError(f"suites.{name}.randomize", "expected true or false")
    return [Episode(sc, int(seed), s["randomize"]) for sc in s["scenarios"] for seed in s["seeds"]]
