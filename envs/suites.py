"""Identical-scenario suites (configs/suites.yaml): named, ordered lists of episodes (scenario, seed,
randomize). Every episode's parameters and initial state are drawn from its seed alone (numpy's
SeedSequence/PCG64, platform independent), so every controller sees the same episodes on every machine."""

from __future__ import annotations

import itertools
from dataclasses import dataclass

from .config import ConfigError, Node, boolean, configs_dir, integer, load_yaml, scenario_names

FILE = "suites.yaml"
RANGES = "seed_ranges"  # the file's table of seed ranges; every other top-level key is a suite


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

    @classmethod
    def from_dict(cls, d: dict) -> Episode:
        """An episode as asdict wrote it into a run's run.json (JSON has no tuples: its pinned parameters
        come back as lists), equal to the episode that was written."""
        return cls(d["scenario"], d["seed"], d["randomize"], tuple(tuple(kv) for kv in d.get("params", ())))

    def options(self) -> dict | None:
        """The reset options of the episode (the pinned values, without the structural key)."""
        pinned = {k: v for k, v in self.params if k not in STRUCTURAL}
        return {"params": pinned} if pinned else None

    def overrides(self) -> dict | None:
        """The scenario overrides the episode's structural keys make (None: the scenario as it is)."""
        return {k: v for k, v in self.params if k in STRUCTURAL} or None


STRUCTURAL = ("friction_model",)  # pinned keys that change how the env is built, not a drawn value


def suite_names() -> list[str]:
    return sorted(k for k in load_yaml(configs_dir() / FILE) if k != RANGES)


def seed_ranges() -> dict[str, tuple[int, int]]:
    """configs/suites.yaml's seed ranges: name -> (first, last), inclusive; checked to be disjoint."""
    node = Node(load_yaml(configs_dir() / FILE), FILE).section(RANGES)
    out = {}
    for name in list(node.keys()):  # a Node is read by key; it has no __iter__
        pair = node[name]
        if not (isinstance(pair, list) and len(pair) == 2):
            raise node.error(name, f"expected [first, last], got {pair!r}")
        first = node.check(integer, pair[0], node.field(f"{name}[0]"), 0)
        out[name] = (first, node.check(integer, pair[1], node.field(f"{name}[1]"), first))
    spans = sorted((lo, hi, name) for name, (lo, hi) in out.items())
    for (_, hi, a), (lo, _, b) in itertools.pairwise(spans):
        if lo <= hi:
            raise node.error(b, f"overlaps {a}'s range")
    return out


def seed_range(name: str) -> tuple[int, int]:
    """(first, last) seed of a range of configs/suites.yaml (a suite's, sim2real or training)."""
    ranges = seed_ranges()
    if name not in ranges:
        raise ConfigError(f"{RANGES}.{name}", f"no seed range; the table has {sorted(ranges)}", FILE)
    return ranges[name]


def _suite(name: str) -> Node:
    suites = Node(load_yaml(configs_dir() / FILE), FILE)
    if name not in suites or name == RANGES:
        raise ConfigError("suite", f"unknown suite {name!r}; available: {suite_names()}", FILE)
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
    from .scenario import scenario_config  # start-up cost: a command's --help lists suites, loads none

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
    lo, hi = seed_range(name)
    if not lo <= min(seeds) <= max(seeds) <= hi:
        raise s.error("seeds", f"{min(seeds)}-{max(seeds)} leave the suite's range [{lo}, {hi}] ({RANGES})")
    s.done()
    return [Episode(sc, seed, randomize) for sc in scenarios for seed in seeds]
