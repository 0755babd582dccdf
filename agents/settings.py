"""Controller settings: configs/controllers.yaml read once, checked key by key (unknown and missing keys
are errors naming the file), into one typed, frozen settings object per controller family.

A controller takes its settings as constructor arguments (`PID(integrator_pole_ratio=0.3)`, or a whole
settings object); the YAML only supplies the defaults, so nothing is re-read at reset and a sweep can set
any field.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from functools import cache
from typing import Any, ClassVar, TypeVar

from frictiongym.envs.config import ConfigError, Node, configs_dir, load_yaml

FILE = "controllers.yaml"
T = TypeVar("T")


KNOWLEDGE = "knowledge"


class FamilySettings:
    """Base of a controller family's settings object: declares the family's section of controllers.yaml
    (SECTION). Every family module is imported with the classical package, so when any family reads its
    section, all sections are declared."""

    SECTION: ClassVar[str]
    sections: ClassVar[set[str]] = set()

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if "SECTION" in vars(cls):  # an abstract base (PerPlantSettings) declares none
            FamilySettings.sections.add(cls.SECTION)


@cache
def _raw() -> dict[str, Any]:
    """controllers.yaml, loaded once."""
    return load_yaml(configs_dir() / FILE)


def read(name: str, build: Callable[[Node], T]) -> T:
    """build(section) for one top-level section of controllers.yaml; keys it did not read are errors, and
    so is (at a family's read) a top-level section no family declares."""
    if name != KNOWLEDGE:
        known = FamilySettings.sections | {KNOWLEDGE}
        for key in _raw():
            if key not in known:
                raise ConfigError(key, f"unknown section; allowed: {sorted(known)}", FILE)
    node = Node(_raw(), FILE).section(name)
    out = build(node)
    node.done()
    return out


def with_overrides(settings: T, overrides: dict[str, Any]) -> T:
    """settings with fields replaced; an unknown field is an error naming it and the allowed ones."""
    fields = {f.name for f in dataclasses.fields(settings)}
    unknown = sorted(set(overrides) - fields)
    if unknown:
        raise ConfigError(type(settings).__name__, f"unknown setting(s) {unknown}; allowed: {sorted(fields)}")
    return dataclasses.replace(settings, **overrides)


@cache
def knowledge_defaults() -> dict[str, float]:
    """What friction compensators believe about the plant, relative to the nominal preset (knowledge:)."""
    return read(KNOWLEDGE, lambda k: {"static_friction_scale": k.positive("static_friction_scale", 10.0)})


@dataclasses.dataclass(frozen=True)
class Knob:
    """A tunable design choice of a per-plant settings entry: its range (in the field's unit), whether it
    is searched on a log scale, and whether it is a whole number. Reading a YAML value checks the range,
    and `frictiongym tune` searches it."""

    low: float
    high: float
    log: bool = False
    whole: bool = False

    def check(self, node: Node, key: str) -> float | int:
        """The value of `key` in `node`, within [low, high] (an error naming the key otherwise)."""
        if self.whole:
            return node.integer(key, self.low, self.high)
        return node.number(key, self.low, self.high)


P = TypeVar("P")


class PerPlantSettings(FamilySettings):
    """A family whose design choices are one entry per plant preset (controllers.yaml `<SECTION>.<plant>`),
    each a frozen dataclass (ENTRY) whose fields are all Knobs (KNOBS: field -> Knob, units in the field's
    docstring). Tuning replaces a plant's entry (`replaced`); a family reads its plant's entry at reset."""

    ENTRY: ClassVar[type]
    KNOBS: ClassVar[dict[str, Knob]]
    plants: dict[str, Any]

    @classmethod
    def read_section(cls, s: Node) -> dict[str, Any]:
        """Every plant's entry of a section, each field checked against its knob."""
        out = {}
        for plant in list(s.keys()):
            p = s.section(plant)
            out[plant] = cls.ENTRY(**{k: knob.check(p, k) for k, knob in cls.KNOBS.items()})
            p.done()
        return out

    def of(self, plant: str) -> Any:
        """The entry of a plant preset (an error naming the section and the plants it has)."""
        if plant not in self.plants:
            raise ConfigError(
                f"{self.SECTION}.{plant}", f"no settings for this plant; {FILE} has {sorted(self.plants)}"
            )
        return self.plants[plant]

    def replaced(self, plant: str, values: dict[str, Any]) -> Any:
        """These settings with a plant's entry's fields replaced (tuned values), each within its knob."""
        for key, v in values.items():
            knob = self.KNOBS.get(key)
            if knob is None:
                raise ConfigError(key, f"not a setting of {self.SECTION}; allowed: {sorted(self.KNOBS)}")
            if not (knob.low <= v <= knob.high) or (knob.whole and v != int(v)):
                raise ConfigError(f"{self.SECTION}.{plant}.{key}", f"{v!r} outside [{knob.low}, {knob.high}]")
        entry = dataclasses.replace(self.of(plant), **values)
        return dataclasses.replace(self, plants={**self.plants, plant: entry})
