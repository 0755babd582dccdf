"""A saved model's manifest (manifest.yaml beside model.zip): what the model is (algorithm, what it observes,
its base controller and α, the plants it applies to) and how it came to be (scenario, seed, steps, wall
time, the exact command, package version, the validation it was selected on). Training writes it, the
registry reads it; whether a model applies to a scenario is decided from it, without loading the zip.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from frictiongym.envs.config import ConfigError, Node, load_yaml
from frictiongym.envs.records import atomic_text

from .learned import PolicyInputs

MODEL, NORMALIZER, MANIFEST = "model.zip", "vecnormalize.pkl", "manifest.yaml"  # a model folder's files


@dataclass(frozen=True)
class Manifest:
    """The fields of manifest.yaml, in its order. A hand-made folder needs name and algorithm only (then
    the model is model.zip, no normalizer, no base, α = 1, any plant); a trained one has every field."""

    name: str
    algorithm: str
    model: str = MODEL
    normalizer: str | None = None
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
        """manifest.yaml of a model folder, every key checked (errors name the file and the key), its model
        and normalizer files present."""
        path = Path(folder) / MANIFEST
        m = Node(load_yaml(path), str(path))
        kw: dict[str, Any] = {"name": m.string("name"), "algorithm": m.string("algorithm")}
        kw["model"] = m.string("model", default=MODEL)
        if m.get("normalizer") is not None:
            kw["normalizer"] = m.string("normalizer")
        for key in ("model", "normalizer"):
            if key in kw and not (Path(folder) / kw[key]).is_file():
                raise m.error(key, f"file {kw[key]} not found in {folder}")
        for key in ("scenario", "base_controller", "command", "package_version", "git_commit"):
            if m.get(key) is not None:
                kw[key] = m.string(key)
        for key in ("stable_baselines3", "training_seeds"):
            if m.get(key) is not None:
                kw[key] = str(m[key])
        plants = m.get("plants") or []
        if not isinstance(plants, list) or not all(isinstance(p, str) for p in plants):
            raise m.error("plants", f"expected a list of plant names, got {plants!r}")
        kw["plants"] = tuple(plants)
        kw["alpha"] = m.positive("alpha", 1.0, default=1.0)
        if "inputs" in m:
            i = m.section("inputs")
            kw["inputs"] = PolicyInputs(
                i.integer("history", 0, default=0),
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
                raise m.error(key, f"expected a mapping, got {value!r}")
            kw[key] = value
        try:
            m.done()
        except ConfigError as e:
            raise ConfigError(e.field, f"{e.message} (a manifest's fields: Manifest)", e.source) from None
        return cls(**kw)
