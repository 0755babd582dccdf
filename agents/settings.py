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
