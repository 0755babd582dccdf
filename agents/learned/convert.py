"""Converting a model folder of the SB3 form (manifest.yaml naming model.zip and vecnormalize.pkl) into the
safe form (agents/learned/folder.py): the one place that loads those pickles, and only when trusted.
`frictiongym convert-model` is its front end."""

from __future__ import annotations

import shlex
from pathlib import Path

import yaml

from frictiongym.agents.learned.folder import (
    file_in_folder,
    load_sb3_zip,
    read_policy,
    read_sealed,
    seal,
    sealed_names,
    write_policy,
)
from frictiongym.agents.learned.manifest import MANIFEST, Manifest
from frictiongym.agents.learned.policy import LayerNetwork, network_of
from frictiongym.envs.config import Node, load_yaml
from frictiongym.envs.records import atomic_text, atomic_write


def portable_command(command: str, root: Path) -> str:
    """A recorded command with the machine's paths taken out: a path inside the repository `root`
    becomes relative to it, the value of --out (the run's own folder, which does not change the result)
    outside it becomes `runs`."""
    words = shlex.split(command)
    out = []
    for i, w in enumerate(words):
        p = Path(w)
        if p.is_absolute():
            if p.is_relative_to(root):
                w = str(p.relative_to(root))
            elif i and words[i - 1] == "--out":
                w = "runs"
        out.append(w)
    return shlex.join(out)


def convert_folder(src: Path, dest: Path, *, trust_pickle: bool = False, root: Path | None = None) -> Path:
    """A model folder of the SB3 form (manifest.yaml naming model.zip and vecnormalize.pkl) rewritten in
    the safe form into dest/<name>/ (policy.safetensors, the manifest with its network and SHA-256, the
    run's records copied): loads the pickles, so only with trust_pickle. The manifest keeps every other
    field; its command and config source lose the machine's paths (portable_command, relative to
    `root`, the repository). The new folder is read back as the leaderboard reads it before returning."""
    source = Path(src) / MANIFEST
    raw = load_yaml(source)
    node = Node(raw, str(source))
    name, algorithm = node.string("name"), node.string("algorithm")
    model_path = file_in_folder(Path(src), node.get("model", "model.zip"), node, "model")
    norm = node.get("normalizer")
    norm_path = file_in_folder(Path(src), norm, node, "normalizer") if norm is not None else None
    model, stats = load_sb3_zip(model_path, norm_path, algorithm, trust_pickle=trust_pickle)
    network = network_of(model)
    if not isinstance(network, LayerNetwork):
        raise node.error(
            "algorithm",
            f"{algorithm}'s policy here is not a chain of linear/ReLU/tanh layers (recurrent, gSDE, batch "
            "normalisation or JAX): the safe format cannot hold it",
        )
    folder = Path(dest) / name
    folder.mkdir(parents=True, exist_ok=True)
    fields = write_policy(folder, network, stats)
    kept = {k: v for k, v in raw.items() if k not in ("model", "normalizer", "network", "sha256")}
    manifest = {"name": name, "algorithm": algorithm, **fields, **kept}
    if root is not None:
        if isinstance(manifest.get("command"), str):
            manifest["command"] = portable_command(manifest["command"], root)
        config = manifest.get("config")
        if isinstance(config, dict) and isinstance(config.get("source"), str):
            config["source"] = f"configs/agents/{Path(config['source']).name}"
    for record in ("validation.csv", "training_curve.png"):
        if (Path(src) / record).is_file() and Path(src).resolve() != folder.resolve():
            data = (Path(src) / record).read_bytes()
            atomic_write(folder / record, lambda p, data=data: p.write_bytes(data))
    atomic_text(folder / MANIFEST, yaml.safe_dump(manifest, sort_keys=False))
    seal(folder, sealed_names(folder))
    written = Manifest.read(folder)
    read_policy(read_sealed(folder), written, str(folder / MANIFEST))
    written.write(folder)  # in the field order and form training writes
    seal(folder, sealed_names(folder))
    return folder
