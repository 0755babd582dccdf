"""Controller settings: configs/controllers.yaml read once, checked key by key (unknown and missing keys
are errors naming the file), into one typed, frozen settings object per controller family.

A controller takes its settings as constructor arguments (`PID(integrator_pole_ratio=0.3)`, or a whole
settings object); the YAML only supplies the defaults, so nothing is re-read at reset and a sweep can set
any field.
"""

from __future__ import annotations

import dataclasses
from functools import cache
from typing import Any, TypeVar

from frictiongym.envs.config import ConfigError, Node, configs_dir, load_yaml

FILE = "controllers.yaml"
T = TypeVar("T")


@cache
def _raw() -> dict[str, Any]:
    return load_yaml(configs_dir() / FILE)


def section(name: str) -> Node:
    """A fresh checked view of one top-level section of controllers.yaml."""
    root = Node(_raw(), FILE)
    return root.section(name)


def with_overrides(settings: T, overrides: dict[str, Any]) -> T:
    """settings with fields replaced; an unknown field is an error naming it and the allowed ones."""
    fields = {f.name for f in dataclasses.fields(settings)}
    unknown = sorted(set(overrides) - fields)
    if unknown:
        raise ConfigError(type(settings).__name__, f"unknown setting(s) {unknown}; allowed: {sorted(fields)}")
    return dataclasses.replace(settings, **overrides)


def check_file() -> None:
    """Read every family's defaults and reject any top-level section nobody reads."""
    from . import classical

    root = Node(_raw(), FILE)
    for family in classical.SETTINGS:
        root.section(family.SECTION)
        family.defaults()
    root.section("knowledge")
    knowledge_defaults()
    root.done()


@cache
def knowledge_defaults() -> dict[str, float]:
    """What friction compensators believe about the plant, relative to the nominal preset (knowledge:)."""
    k = section("knowledge")
    out = {"static_friction_scale": k.positive("static_friction_scale", 10.0)}
    k.done()
    return out
