"""A saved model's manifest (manifest.yaml beside policy.safetensors): what the model is (algorithm, its
network, what it observes, its base controller and α, the plants it applies to, the SHA-256 of every
file it names) and how it came to be (scenario, seed, steps, wall time, the exact command relative to
the repository, package version, the validation it was selected on). Training writes it, the registry
reads it; whether a model applies to a scenario is decided from it, without loading the weights.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from frictiongym.agents.learned.folder import MANIFEST, POLICY, UntrustedModel, file_in_folder
from frictiongym.agents.learned.policy import PolicyInputs
from frictiongym.envs.config import ConfigError, Node, load_yaml
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
        """manifest.yaml of a model folder, every key checked (errors name the file and the key), its model
        file a regular file inside the folder with a recorded SHA-256 (checked when it is loaded:
        folder.read_policy). A pickle-bearing SB3 zip is refused, naming the conversion command."""
        path = Path(folder) / MANIFEST
        m = Node(load_yaml(path), str(path))
        kw: dict[str, Any] = {"name": m.string("name"), "algorithm": m.string("algorithm")}
        if m.get("normalizer") is not None or str(m.get("model", "")).endswith(".zip"):
            raise UntrustedModel(
                "model",
                "a stable-baselines3 zip (and pickled normalizer) runs code when loaded; convert the folder "
                f"once, trusting its source: frictiongym convert-model {folder} --trust-pickle --out DEST",
                str(path),
            )
        kw["model"] = m.string("model")
        file_in_folder(Path(folder), kw["model"], m, "model")
        digests = m.get("sha256")
        if not isinstance(digests, dict) or not all(
            isinstance(k, str) and isinstance(v, str) and len(v) == 64 and set(v) <= set("0123456789abcdef")
            for k, v in digests.items()
        ):
            raise m.error(
                "sha256", f"expected a mapping of file name to SHA-256 (64 hex digits), got {digests!r}"
            )
        if kw["model"] not in digests:
            raise m.error("sha256", f"no SHA-256 recorded for {kw['model']}")
        kw["sha256"] = dict(digests)
        network = m.get("network")
        if not isinstance(network, dict):
            raise m.error(
                "network", f"expected the network's mapping (layers, observes, ...), got {network!r}"
            )
        kw["network"] = network
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
