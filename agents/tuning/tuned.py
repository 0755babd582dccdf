"""Tuned classical settings: configs/tuned.yaml (written by `frictiongym tune`, agents/tuning/search.py) read
into `<family>[tuned]` twins, each a classical baseline like its family, with the settings tuned on the
validation suite, defined on the plants it was tuned for."""

from __future__ import annotations

from collections.abc import Callable
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np

from frictiongym.agents.base import Controller, EpisodeContext
from frictiongym.envs.config import ConfigError, configs_dir, load_yaml
from frictiongym.envs.scenario import Scenario

TUNED_FILE = "tuned.yaml"
SUFFIX = "[tuned]"


def tuned_path() -> Path:
    """configs/tuned.yaml: the committed tuned settings."""
    return configs_dir() / TUNED_FILE


@cache
def tuned_entries(path: Path | None = None) -> dict[str, dict[str, dict[str, Any]]]:
    """{family: {plant: {"values": {...}, "manifest": {...}}}} of a tuned-settings file (none: {})."""
    path = path or tuned_path()
    if not path.is_file():
        return {}
    data = load_yaml(path) or {}
    if not isinstance(data, dict):
        raise ConfigError(str(path), "expected a mapping of family -> plant -> {values, manifest}")
    for family, plants in data.items():
        if not isinstance(plants, dict):
            raise ConfigError(f"{family}", f"expected a mapping of plant -> entry in {path}")
        for plant, rec in plants.items():
            if not isinstance(rec, dict) or not isinstance(rec.get("values"), dict):
                raise ConfigError(f"{family}.{plant}.values", f"missing or not a mapping in {path}")
    return data


def tunable(factory: Callable[[], Controller]) -> tuple[str, Any] | None:
    """(keyword, settings class) of a family that can be tuned, or None."""
    cls = factory.func if hasattr(factory, "func") else factory
    return getattr(cls, "tunes", None)


def build(cls: type, values: dict[str, dict[str, Any]]) -> Controller:
    """The family `cls` with its settings' plant entries replaced by `values` ({plant: {knob: value}})."""
    keyword, settings_cls = cls.tunes
    settings = settings_cls.defaults()
    for plant, v in values.items():
        settings = settings.replaced(plant, v)
    return cls(**{keyword: settings})


class Tuned(Controller):
    """A family with its tuned settings (configs/tuned.yaml), defined on the plants it was tuned for where
    the tuning changed the design's settings (where it kept them, the row would repeat the family's)."""

    def __init__(self, family: str, cls: type, entries: dict[str, dict[str, Any]]):
        self.name, self.family = family + SUFFIX, family
        self.plants = sorted(entries)
        self.kept = sorted(
            p for p, e in entries.items() if e["values"] == e.get("manifest", {}).get("design_values")
        )
        self.inner = build(cls, {p: e["values"] for p, e in entries.items()})
        self.sensor_kinds, self.tasks = self.inner.sensor_kinds, self.inner.tasks

    def why_not(self, scenario: Scenario) -> str | None:
        plant = scenario.spec.name
        if plant not in self.plants:
            return f"not tuned for plant {plant} (configs/{TUNED_FILE} has {self.plants})"
        if plant in self.kept:
            return f"its tuning on {plant} kept the design's settings: the row is {self.family}'s"
        return self.inner.why_not(scenario)

    def plant_overrides(self, scenario: Scenario) -> dict:
        return self.inner.plant_overrides(scenario)

    def reset(self, ctx: EpisodeContext) -> None:
        self.inner.reset(ctx)

    def act(self, obs: np.ndarray) -> np.ndarray:
        return self.inner.act(obs)

    def acting(self) -> Controller:
        return self.inner.acting()

    def params(self) -> dict[str, Any]:
        return self.inner.params()
