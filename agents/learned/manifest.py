"""A saved model's manifest (manifest.yaml beside policy.safetensors): what the model is (algorithm, its
network, what it observes, its base controller and α, the plants it applies to, the SHA-256 of every
file it names) and how it came to be (scenario, seed, steps, wall time, the exact command relative to
the repository, package version, the validation it was selected on). Training writes it, the registry
reads it; whether a model applies to a scenario is decided from it, without loading the weights.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from frictiongym.agents.learned.folder import MANIFEST, POLICY, UntrustedModel, read_sealed
from frictiongym.agents.learned.policy import MAX_HISTORY, PolicyInputs
from frictiongym.envs.config import ConfigError, Node, plant_names, scenario_names, yaml_mapping
from frictiongym.envs.records import atomic_text

# a run's SB3 model and VecNormalize (pickles: its checkpoint, and a zip converted by convert-model)
MODEL, NORMALIZER = "model.zip", "vecnormalize.pkl"


@dataclass(frozen=True)
class Manifest:
    """The fields of manifest.yaml, in its order. A loadable folder needs name, algorithm, model, network
    and sha256 (then no base, α = 1, any plant: `frictiongym convert-model` writes them for an SB3 zip);
    a trained one has every field."""

    name: str
    algorithm: str
    model: str = POLICY
    network: dict[str, Any] = field(default_factory=dict)  # folder.network_section
    sha256: dict[str, str] = field(default_factory=dict)  # file name -> SHA-256 of every file named
    scenario: str | None = None
    plants: tuple[str, ...] = ()  # the plants the model applies to (empty: any)
    base_controller: str | None = None
    alpha: float = 1.0
    inputs: PolicyInputs | None = None  # None: nothing beyond the scenario's observation (+ the base action)
    seed: int | None = None
    steps: int | None = None
    selected_step: int | None = None
    wall_time_s: float | None = None
    stopped_at_wall_time_limit: bool | None = None
    command: str | None = None
    package_version: str | None = None
    git_commit: str | None = None
    stable_baselines3: str | None = None
    torch_threads: int | None = None
    training_seeds: str | None = None
    validation: dict[str, Any] = field(default_factory=dict)
    config: dict[str, Any] = field(default_factory=dict)

    @property
    def policy_inputs(self) -> PolicyInputs:
        """What the policy observes (the base action whenever there is a base)."""
        return self.inputs or PolicyInputs(base_action=self.base_controller is not None)

    def as_dict(self) -> dict[str, Any]:
        """The YAML mapping (plain types), in field order."""
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        out["plants"] = list(self.plants)
        out["inputs"] = dataclasses.asdict(self.inputs) if self.inputs is not None else None
        if out["inputs"] is not None and not out["inputs"]["differences"]:
            del out["inputs"]["differences"]  # written when on: older manifests read back as written
        return out

    def write(self, folder: Path) -> None:
        atomic_text(Path(folder) / MANIFEST, yaml.safe_dump(self.as_dict(), sort_keys=False))

    @classmethod
    def read(cls, folder: Path) -> Manifest:
        """manifest.yaml of a sealed model folder (folder.read_sealed checks the seal first)."""
        return cls.parse(read_sealed(folder), str(Path(folder) / MANIFEST))

    @classmethod
    def parse(cls, files: Mapping[str, bytes], source: str) -> Manifest:
        """The manifest among a sealed folder's files (source: its path, for errors), every key checked
        against the schema below before use: names of letters, digits and _.+-, a known scenario and known
        plants by name (never a path), α in (0, 1], inputs within the training config's ranges, the model
        file one of the sealed files with its SHA-256 recorded. A pickle-bearing SB3 zip is refused,
        naming the conversion command."""
        if MANIFEST not in files:
            raise ConfigError("(file)", "missing from the sealed folder", source)
        m = Node(yaml_mapping(files[MANIFEST], source), source)
        kw: dict[str, Any] = {"name": _name(m, "name"), "algorithm": _name(m, "algorithm")}
        if m.get("normalizer") is not None or str(m.get("model", "")).endswith(".zip"):
            folder = Path(source).parent
            raise UntrustedModel(
                "model",
                "a stable-baselines3 zip (and pickled normalizer) runs code when loaded; convert the folder "
                f"once, trusting its source: frictiongym convert-model {folder} --trust-pickle --out DEST",
                source,
            )
        kw["model"] = _name(m, "model")
        if kw["model"] not in files or kw["model"] == MANIFEST:
            raise m.error("model", f"{kw['model']} is not a file of the sealed folder")
        digests = m.get("sha256")
        if not isinstance(digests, dict) or not all(
            isinstance(k, str) and isinstance(v, str) and len(v) == 64 and set(v) <= set("0123456789abcdef")
            for k, v in digests.items()
        ):
            raise m.error("sha256", "expected a mapping of file name to SHA-256 (64 lowercase hex digits)")
        if kw["model"] not in digests:
            raise m.error("sha256", f"no SHA-256 recorded for {kw['model']}")
        kw["sha256"] = dict(digests)
        network = m.get("network")
        if not isinstance(network, dict):
            raise m.error("network", "expected the network's mapping (layers, observes, ...)")
        kw["network"] = network
        if m.get("scenario") is not None:
            kw["scenario"] = m.choice("scenario", scenario_names())
        if m.get("base_controller") is not None:  # a base (registry.BASES or a built-in), checked there
            kw["base_controller"] = _name(m, "base_controller", _BASE)
        for key in ("command", "package_version", "git_commit"):
            if m.get(key) is not None:
                kw[key] = m.string(key)
        for key in ("stable_baselines3", "training_seeds"):
            if m.get(key) is not None:
                kw[key] = str(m[key])
        plants, known = m.get("plants") or [], plant_names()
        if not isinstance(plants, list) or not all(p in known for p in plants):
            raise m.error("plants", f"expected a list of plant names of {known}")
        kw["plants"] = tuple(plants)
        kw["alpha"] = m.positive("alpha", 1.0, default=1.0)
        if "inputs" in m:
            i = m.section("inputs")
            kw["inputs"] = PolicyInputs(
                i.integer("history", 0, MAX_HISTORY, default=0),
                i.boolean("privileged", default=False),
                i.boolean("base_action", default=kw.get("base_controller") is not None),
                i.boolean("differences", default=False),
            )
        for key in ("seed", "steps", "selected_step", "torch_threads"):
            if m.get(key) is not None:
                kw[key] = m.integer(key, 0)
        if m.get("wall_time_s") is not None:
            kw["wall_time_s"] = m.nonneg("wall_time_s")
        if m.get("stopped_at_wall_time_limit") is not None:
            kw["stopped_at_wall_time_limit"] = m.boolean("stopped_at_wall_time_limit")
        for key in ("validation", "config"):  # records of the run, kept as written
            value = m.get(key) or {}
            if not isinstance(value, dict):
                raise m.error(key, "expected a mapping")
            kw[key] = value
        try:
            m.done()
        except ConfigError as e:
            raise ConfigError(e.field, f"{e.message} (a manifest's fields: Manifest)", e.source) from None
        return cls(**kw)


_NAME = re.compile(r"[A-Za-z0-9_.+-]{1,100}")
_BASE = re.compile(r"[A-Za-z0-9_.+/-]{1,100}")  # a base's name may hold a slash (SF+relay/residual-base)


def _name(m: Node, key: str, pattern: re.Pattern[str] = _NAME) -> str:
    """A name (a model's, an algorithm's, a file's, a base's): 1-100 letters, digits and the pattern's
    punctuation."""
    value = m[key]
    if not isinstance(value, str) or not pattern.fullmatch(value):
        raise m.error(key, f"expected a name matching {pattern.pattern}")
    return value
