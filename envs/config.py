"""Loading YAML files from configs/ and checking values, with errors that name the file and the field.

Every YAML file (plant presets, scenarios, suites, controllers, published numbers) is read through a
`Node`: a checked view of one mapping. Reading a key that is absent is an error naming the file and the
key; `Node.done()` then reports every key the reader never asked for (a typo such as `episodes_s`). The
reader is the schema: there is no second list of keys to keep in step with the code.
"""

from __future__ import annotations

import copy
import functools
import math
import re
from collections.abc import Callable, Iterator, Mapping
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import yaml

# Bounds on any YAML file the suite reads (configs, a model's manifest, an export's runtime.yaml): a file a
# user is handed is input, and YAML lets a kilobyte expand to gigabytes through aliases or nest until the
# parser's recursion fails. The largest committed file (configs/tuned.yaml) is 48 kB, 12 levels deep,
# about 16,000 values expanded.
MAX_YAML_BYTES = 1 << 20  # a file's size, bytes
MAX_YAML_DEPTH = 64  # nested sequences and mappings
MAX_YAML_VALUES = 200_000  # values (scalars, sequences, mappings) with every alias expanded


class _Loader(yaml.SafeLoader):
    """SafeLoader that also reads 1e5 / 1.0e5 as floats (YAML 1.2; PyYAML's 1.1 rules need 1.0e+5),
    refuses a key given twice in one mapping (PyYAML keeps the last one silently) or a key that is not a
    plain value (`? [1, 2]`), and keeps to MAX_YAML_DEPTH and MAX_YAML_VALUES (checked on the composed
    document, before anything is constructed)."""

    def compose_node(self, parent: Any, index: Any) -> Any:
        self._depth = getattr(self, "_depth", 0) + 1
        if self._depth > MAX_YAML_DEPTH:
            raise yaml.composer.ComposerError(
                None, None, f"nested deeper than {MAX_YAML_DEPTH} levels", self.peek_event().start_mark
            )
        try:
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def get_single_node(self) -> Any:
        node = super().get_single_node()
        if node is not None and _expanded_size(node) > MAX_YAML_VALUES:
            raise yaml.composer.ComposerError(
                None,
                None,
                f"more than {MAX_YAML_VALUES} values once its aliases are expanded",
                node.start_mark,
            )
        return node

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        seen: dict[Any, int] = {}
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":  # `<<:` merge keys may repeat inherited keys
                continue
            if not isinstance(key_node, yaml.ScalarNode):
                raise yaml.constructor.ConstructorError(
                    None,
                    None,
                    "a mapping key must be a plain value, not a list or mapping",
                    key_node.start_mark,
                )
            key = self.construct_object(key_node, deep=True)
            line = key_node.start_mark.line + 1
            if key in seen:
                raise _DuplicateKey(str(key), line, seen[key])
            seen[key] = line
        return super().construct_mapping(node, deep)


def _expanded_size(root: yaml.Node) -> int:
    """How many values a composed YAML node stands for with every alias expanded (an alias is the same
    node object as its anchor: each node's size is counted once, iteratively, so no recursion)."""
    size: dict[int, int] = {}
    stack: list[tuple[yaml.Node, bool]] = [(root, False)]
    while stack:
        node, children_done = stack.pop()
        if id(node) in size:
            continue
        if isinstance(node, yaml.ScalarNode):
            size[id(node)] = 1
            continue
        kids = [x for pair in node.value for x in pair] if isinstance(node, yaml.MappingNode) else node.value
        if children_done:
            size[id(node)] = min(1 + sum(size[id(k)] for k in kids), MAX_YAML_VALUES + 1)
        else:
            stack.append((node, True))
            stack.extend((k, False) for k in kids if id(k) not in size)
    return size[id(root)]


class _DuplicateKey(Exception):
    def __init__(self, key: str, line: int, first: int):
        super().__init__(key, line, first)
        self.key, self.line, self.first = key, line, first


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
    list("-+0123456789"),
)


def one_line(text: Any, limit: int) -> str:
    """text on one line (control characters escaped) and at most `limit` characters: an error message
    quotes values from files a user was handed, which may hold anything."""
    text = str(text)
    if text.isprintable() and len(text) <= limit:
        return text
    text = "".join(c if c.isprintable() else repr(c)[1:-1] for c in text[: 4 * limit])
    return text if len(text) <= limit else f"{text[: limit - 1]}…"


class ConfigError(ValueError):
    """A configuration or parameter value is invalid; the message names the field (and the file, when the
    value came from one) and the allowed range."""

    def __init__(self, field: str, message: str, source: str = ""):
        field, message, source = one_line(field, 200), one_line(message, 2000), one_line(source, 300)
        self.field, self.message, self.source = field, message, source
        super().__init__(f"{source}: {field}: {message}" if source else f"{field}: {message}")

    def __reduce__(self) -> tuple:
        """Rebuilt from its three fields: a ConfigError raised in a worker process (training, validation,
        a parallel leaderboard) reaches the caller as itself, not as a broken process pool."""
        return (ConfigError, (self.field, self.message, self.source))


def configs_dir() -> Path:
    """The installed configs/ folder (frictiongym.configs)."""
    return Path(str(resources.files("frictiongym.configs")))


def preset_names(kind: str) -> list[str]:
    """Names of the YAML files under configs/<kind>/ (files starting with '_' are shared defaults)."""
    return sorted(p.stem for p in (configs_dir() / kind).glob("*.yaml") if not p.stem.startswith("_"))


def plant_names() -> list[str]:
    """Names of the plant presets under configs/plants/."""
    return preset_names("plants")


def scenario_names() -> list[str]:
    """Names of the scenarios under configs/scenarios/ (not the shared defaults file)."""
    return preset_names("scenarios")


def preset_path(name_or_path: str | Path, kind: str) -> Path:
    """configs/<kind>/<name>.yaml for a name, or the path itself for a .yaml path."""
    if not isinstance(name_or_path, str | Path) or not str(name_or_path):
        raise ConfigError(kind, f"expected a preset name or a .yaml path, got {name_or_path!r}")
    path = Path(name_or_path)
    if path.suffix not in (".yaml", ".yml"):
        path = configs_dir() / kind / f"{name_or_path}.yaml"
        if not path.exists():
            raise ConfigError(kind, f"unknown preset {name_or_path!r}; available: {preset_names(kind)}")
    elif not path.exists():
        raise ConfigError(kind, f"no such file {str(path)!r}")
    return path


def load_yaml(name_or_path: str | Path, kind: str = "plants") -> dict[str, Any]:
    """Load a YAML mapping by name (configs/<kind>/<name>.yaml) or by path. Every problem with the file
    (not UTF-8 text, a syntax error, a tab, a tag such as !!python/object, a key given twice, over the
    bounds, not a mapping) is a ConfigError naming the file, the line and, where there is one, the key."""
    path = preset_path(name_or_path, kind)
    try:
        with path.open("rb") as f:
            raw = f.read(MAX_YAML_BYTES + 1)
    except OSError as e:
        raise ConfigError("(file)", f"cannot be read: {e.strerror or e}", str(path)) from None
    return yaml_mapping(raw, str(path))


def yaml_mapping(raw: bytes, source: str) -> dict[str, Any]:
    """The YAML mapping in a file's bytes (source: the file, for errors), as load_yaml reads it: bounded
    (MAX_YAML_BYTES, MAX_YAML_DEPTH, MAX_YAML_VALUES), safe, every problem one ConfigError."""
    if len(raw) > MAX_YAML_BYTES:
        raise ConfigError(
            "(file)", f"larger than {MAX_YAML_BYTES} bytes: not a file the suite writes", source
        )
    try:
        data = copy.deepcopy(_parse(raw.decode("utf-8")))  # a copy: callers may edit what they are given
    except UnicodeDecodeError as e:
        raise ConfigError("(file)", f"not UTF-8 text (byte {e.start}): is it a YAML file?", source) from None
    except _DuplicateKey as e:
        raise ConfigError(
            e.key, f"line {e.line}: key given twice (first on line {e.first}); keep one", source
        ) from None
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None) or getattr(e, "context_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}" if mark is not None else "(no position)"
        what = " ".join(str(x) for x in (getattr(e, "context", None), getattr(e, "problem", None)) if x)
        raise ConfigError("(yaml)", f"{where}: {what or e}", source) from None
    if not isinstance(data, dict):
        raise ConfigError("(file)", "expected a YAML mapping", source)
    return data


@functools.lru_cache(maxsize=512)
def _parse(text: str) -> Any:
    """A YAML text's data, parsed once per process and text: PyYAML's pure-Python parser is 90 % of a
    scenario's load, and a leaderboard loads each scenario (and its plant and defaults files) several
    times. Keyed by the text itself, so an edited file is parsed again."""
    return yaml.load(text, Loader=_Loader)


def deep_merge(base: Any, over: Any) -> Any:
    """over merged into base as a new value, mappings key by key (over wins elsewhere). No key checks:
    the checked readers (Node) reject unknown keys, naming them; merge() checks them here."""
    if isinstance(base, Mapping) and isinstance(over, Mapping):
        return {**base, **{k: deep_merge(base.get(k), v) for k, v in over.items()}}
    return copy.deepcopy(over)


def load_extending(
    name_or_path: str | Path,
    kind: str,
    default: str | None = None,
    combine: Callable[[dict[str, Any], dict[str, Any]], dict[str, Any]] = deep_merge,
    _chain: tuple[Path, ...] = (),
) -> dict[str, Any]:
    """A YAML file of configs/<kind>/ (a name or a path) over the file its `extends:` names, recursively:
    combine(parent, child), the child's keys win (deep_merge). Without `extends:` a file extends
    `default` (the kind's defaults file, which itself extends nothing), or nothing. A cycle, or an
    `extends:` that is not a name or path, is an error naming the file."""
    path = preset_path(name_or_path, kind)
    data = load_yaml(path)
    parent = data.pop("extends", None if default is None or path.stem == default else default)
    if parent is None:
        return data
    chain = (*_chain, path.resolve())
    if not isinstance(parent, str) or preset_path(parent, kind).resolve() in chain:
        raise ConfigError("extends", f"expected another {kind} file, not a cycle: {parent!r}", path.name)
    return combine(load_extending(parent, kind, default, combine, chain), data)


def merge(base: Mapping[str, Any], overrides: Any, prefix: str = "", source: str = "") -> dict[str, Any]:
    """Deep-merge overrides into a copy of base. Keys must exist in base (typos are errors)."""
    if overrides is None:
        return copy.deepcopy(dict(base))
    if not isinstance(overrides, Mapping):
        raise ConfigError(prefix.rstrip(".") or "overrides", f"expected a mapping, got {overrides!r}", source)
    out = copy.deepcopy(dict(base))
    for key, value in overrides.items():
        field = f"{prefix}{key}"
        if key not in out:
            raise ConfigError(field, f"unknown key; allowed: {sorted(out)}", source)
        if isinstance(out[key], dict) and value is not None:  # None replaces (e.g. disturbance: None)
            out[key] = merge(out[key], value, prefix=f"{field}.", source=source)
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


def positive(value: Any, field: str, high: float = math.inf) -> float:
    """A finite number > 0 (and <= high)."""
    return number(value, field, 0.0, high, low_open=True)


def nonneg(value: Any, field: str, high: float = math.inf) -> float:
    """A finite number >= 0 (and <= high)."""
    return number(value, field, 0.0, high)


def integer(value: Any, field: str, low: float = -math.inf, high: float = math.inf) -> int:
    """An integer (Python or numpy; not a bool, not a float such as 2.7) in [low, high]."""
    if isinstance(value, bool | np.bool_) or not isinstance(value, int | np.integer):
        raise ConfigError(field, f"expected an integer, got {value!r}")
    if not low <= value <= high:
        raise ConfigError(field, f"{value} is outside the allowed range [{low}, {high}]")
    return int(value)


def boolean(value: Any, field: str) -> bool:
    """true or false (a string such as "false" is an error, not True)."""
    if not isinstance(value, bool):
        raise ConfigError(field, f"expected true or false, got {value!r}")
    return value


def interval(value: Any, field: str, low: float = -math.inf, high: float = math.inf) -> tuple[float, float]:
    """A [lo, hi] pair of numbers within [low, high] with lo <= hi."""
    if not isinstance(value, list | tuple) or len(value) != 2:
        raise ConfigError(field, f"expected a [low, high] pair, got {value!r}")
    lo = number(value[0], f"{field}[0]", low, high)
    hi = number(value[1], f"{field}[1]", low, high)
    if lo > hi:
        raise ConfigError(field, f"low {lo} > high {hi}")
    return lo, hi


class Node:
    """A checked, read-tracking view of one YAML mapping (see the module docstring).

    Typed readers (`positive`, `integer`, `boolean`, ...) check the value and name `path.key` (and the
    file) in any error. `section(key)` returns the child Node; `done()` raises on keys never read.
    """

    def __init__(self, data: Any, source: str = "", path: str = ""):
        if not isinstance(data, Mapping):
            raise ConfigError(path.rstrip(".") or "(file)", f"expected a mapping, got {data!r}", source)
        self.data, self.source, self.path = data, source, path
        self._read: set[str] = set()
        self._children: dict[str, Node] = {}

    def field(self, key: str) -> str:
        return f"{self.path}{key}"

    def error(self, key: str, message: str) -> ConfigError:
        return ConfigError(self.field(key), message, self.source)

    def __contains__(self, key: str) -> bool:
        return key in self.data

    def keys(self) -> Iterator[str]:
        return iter(self.data)

    def __getitem__(self, key: str) -> Any:
        """The raw value of a required key."""
        if key not in self.data:
            raise self.error(key, "missing required key")
        self._read.add(key)
        return self.data[key]

    def get(self, key: str, default: Any = None) -> Any:
        """The raw value of an optional key."""
        self._read.add(key)
        return self.data.get(key, default)

    def section(self, key: str, optional: bool = False) -> Node:
        """The child mapping at key (an empty one if optional and absent); the same Node every time."""
        if key not in self._children:
            value = self.get(key, {}) if optional else self[key]
            self._children[key] = Node(value if value is not None else {}, self.source, f"{self.path}{key}.")
        return self._children[key]

    def check(self, fn: Callable[..., Any], value: Any, field: str, *args: Any, **kw: Any) -> Any:
        """fn(value, field, *args) (a checker such as number or interval), naming this file on error;
        for values that are not a key of this section, such as list elements."""
        try:
            return fn(value, field, *args, **kw)
        except ConfigError as e:
            raise ConfigError(e.field, e.message, self.source) from None

    def _checked(self, fn, key: str, *args: Any, default: Any = ..., **kw: Any) -> Any:
        value = self[key] if default is ... else self.get(key, default)
        return self.check(fn, value, self.field(key), *args, **kw)

    def number(self, key: str, low: float = -math.inf, high: float = math.inf, **kw: Any) -> float:
        return self._checked(number, key, low, high, **kw)

    def positive(self, key: str, high: float = math.inf, **kw: Any) -> float:
        return self._checked(positive, key, high, **kw)

    def nonneg(self, key: str, high: float = math.inf, **kw: Any) -> float:
        return self._checked(nonneg, key, high, **kw)

    def integer(self, key: str, low: float = -math.inf, high: float = math.inf, **kw: Any) -> int:
        return self._checked(integer, key, low, high, **kw)

    def boolean(self, key: str, **kw: Any) -> bool:
        return self._checked(boolean, key, **kw)

    def interval(self, key: str, low: float = -math.inf, high: float = math.inf, **kw: Any):
        return self._checked(interval, key, low, high, **kw)

    def string(self, key: str, **kw: Any) -> str:
        """A non-empty string (a name, a file path)."""

        def check(value: Any, field: str) -> str:
            if not isinstance(value, str) or not value.strip():
                raise ConfigError(field, f"expected a non-empty string, got {value!r}")
            return value

        return self._checked(check, key, **kw)

    def choice(self, key: str, options: tuple[str, ...] | list[str], **kw: Any) -> str:
        def check(value: Any, field: str) -> str:
            if value not in options:
                raise ConfigError(field, f"{value!r} not in {list(options)}")
            return value

        return self._checked(check, key, **kw)

    def done(self) -> None:
        """Raise on the first key (depth first) that no reader asked for."""
        for key in self.data:
            if key not in self._read:
                raise self.error(key, f"unknown key; this section reads: {sorted(self._read)}")
        for child in self._children.values():
            child.done()
