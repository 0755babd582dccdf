"""Loading plant YAML files from configs/ and checking values, with errors that name the field."""

from __future__ import annotations

import copy
import math
import re
from collections.abc import Mapping
from importlib import resources
from pathlib import Path
from typing import Any

import yaml


class _Loader(yaml.SafeLoader):
    """SafeLoader that also reads 1e5 / 1.0e5 as floats (YAML 1.2; PyYAML's 1.1 rules need 1.0e+5)."""


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
    list("-+0123456789"),
)


class ConfigError(ValueError):
    """A configuration or parameter value is invalid; the message names the field and the allowed range."""

    def __init__(self, field: str, message: str):
        self.field = field
        super().__init__(f"{field}: {message}")


def configs_dir() -> Path:
    """The installed configs/ folder (frictiongym.configs)."""
    return Path(str(resources.files("frictiongym.configs")))


def plant_names() -> list[str]:
    """Names of the plant presets under configs/plants/."""
    return sorted(p.stem for p in (configs_dir() / "plants").glob("*.yaml"))


def load_yaml(name_or_path: str | Path, kind: str = "plants") -> dict[str, Any]:
    """Load a preset by name (configs/<kind>/<name>.yaml) or by path."""
    path = Path(name_or_path)
    if path.suffix not in (".yaml", ".yml"):
        path = configs_dir() / kind / f"{name_or_path}.yaml"
        if not path.exists():
            raise ConfigError(kind, f"unknown preset {name_or_path!r}; available: {plant_names()}")
    with open(path) as f:
        data = yaml.load(f, Loader=_Loader)
    if not isinstance(data, dict):
        raise ConfigError(str(path), "a preset must be a YAML mapping")
    return data


def merge(base: Mapping[str, Any], overrides: Mapping[str, Any] | None, prefix: str = "") -> dict[str, Any]:
    """Deep-merge overrides into a copy of base. Keys must exist in base (typos are errors)."""
    out = copy.deepcopy(dict(base))
    for key, value in (overrides or {}).items():
        field = f"{prefix}{key}"
        if key not in out:
            raise ConfigError(field, f"unknown key; allowed: {sorted(out)}")
        if isinstance(out[key], dict) and isinstance(value, Mapping):
            out[key] = merge(out[key], value, prefix=f"{field}.")
        else:
            out[key] = copy.deepcopy(value)
    return out


def number(
    value: Any,
    field: str,
    low: float = -math.inf,
    high: float = math.inf,
    low_open: bool = False,
    high_open: bool = False,
) -> float:
    """Check value is a finite real in [low, high] (open ends optional) and return it as float."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ConfigError(field, f"expected a number, got {value!r}")
    x = float(value)
    lo_ok = x > low if low_open else x >= low
    hi_ok = x < high if high_open else x <= high
    if not math.isfinite(x) or not lo_ok or not hi_ok:
        lo = "(" if low_open else "["
        hi = ")" if high_open else "]"
        raise ConfigError(field, f"{x!r} is outside the allowed range {lo}{low}, {high}{hi}")
    return x


def positive(value: Any, field: str) -> float:
    """A finite number > 0."""
    return number(value, field, 0.0, low_open=True)


def nonneg(value: Any, field: str) -> float:
    """A finite number >= 0."""
    return number(value, field, 0.0)


def interval(value: Any, field: str, low: float = -math.inf, high: float = math.inf) -> tuple[float, float]:
    """A [lo, hi] pair of numbers within [low, high] with lo <= hi."""
    if not isinstance(value, list | tuple) or len(value) != 2:
        raise ConfigError(field, f"expected a [low, high] pair, got {value!r}")
    lo = number(value[0], f"{field}[0]", low, high)
    hi = number(value[1], f"{field}[1]", low, high)
    if lo > hi:
        raise ConfigError(field, f"low {lo} > high {hi}")
    return lo, hi
