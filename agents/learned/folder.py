"""A model folder's policy in a format that cannot run code, and the one door for a pickle-bearing SB3 zip.

A model folder (agents/models/<group>/<name>/, or any folder passed with --models) holds:

    manifest.yaml         what the model is and how it came to be (agents/learned/manifest.py), read with a
                          safe YAML loader; its `network` section is the architecture, its `sha256`
                          section the digest of every file it names
    policy.safetensors    the actor's weights and biases ("layer<i>.weight" (out, in), "layer<i>.bias"),
                          the action bounds ("action.low", "action.high") and the frozen observation
                          statistics ("normalizer.mean", "normalizer.var"): raw arrays behind a JSON header

Loading one reads those arrays and plain settings only: the actor is rebuilt from the manifest as numpy
layers (learned.LayerNetwork), whose actions are the ones the SB3 actor's float64 row-wise evaluation
gives (learned.RowwiseActor), so the leaderboard needs neither torch nor stable-baselines3 to evaluate a
model. Every file is read once, its SHA-256 compared with the manifest's before it is parsed, and every
file name must name a regular file inside the folder (no path, no link).

An SB3 `model.zip` (its `data` entry holds cloudpickle values) and a `vecnormalize.pkl` (a pickle) run code
when loaded. They are read only by `load_sb3_zip(..., trust_pickle=True)`, through `frictiongym
convert-model --trust-pickle`, which writes a safe folder from them, and `frictiongym zoo validate
--trust-pickle`: the caller says that it trusts the files.
"""

from __future__ import annotations

import hashlib
import io
import pickle
from pathlib import Path
from typing import Any

import numpy as np
from safetensors import SafetensorError
from safetensors.numpy import load, save

from frictiongym.agents.learned.policy import (
    ActionScale,
    LayerNetwork,
    Normalizer,
    RowwiseActor,
    algorithm_class,
)
from frictiongym.envs.config import ConfigError, Node
from frictiongym.envs.records import atomic_write

MANIFEST = "manifest.yaml"  # a model folder's description (agents/learned/manifest.py)

POLICY = "policy.safetensors"  # the safe format's one data file
LAYER_KINDS = ("linear", "relu", "tanh")  # RowwiseActor's layers


class UntrustedModel(ConfigError):
    """A model file that would run code when loaded, refused without an explicit trust in pickles."""


def sha256_bytes(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def file_in_folder(folder: Path, name: Any, node: Node, key: str) -> Path:
    """folder/name for a file a manifest names: a plain file name (no directory part, no '..'), a regular
    file in the folder, not a link (a link may point anywhere). Errors name the manifest and the key."""
    if (
        not isinstance(name, str)
        or not name
        or name in (".", "..")
        or Path(name).name != name
        or "\\" in name
    ):
        raise node.error(key, f"expected a file name inside the model folder, got {name!r}")
    path = Path(folder) / name
    if path.is_symlink():
        raise node.error(key, f"{name} is a symbolic link: a model folder holds its files itself")
    if not path.is_file():
        raise node.error(key, f"file {name} not found in {folder}")
    return path


def read_checked(path: Path, digests: dict[str, str], source: str) -> bytes:
    """A file's bytes, read once, after its SHA-256 matched the manifest's (a one-line ConfigError
    otherwise, naming the manifest and the file)."""
    data = path.read_bytes()
    want = digests.get(path.name)
    if want is None:
        raise ConfigError(f"sha256.{path.name}", "no SHA-256 recorded for this file", source)
    if sha256_bytes(data) != want:
        raise ConfigError(
            f"sha256.{path.name}",
            f"{path.name} does not match its recorded SHA-256 (changed or corrupt)",
            source,
        )
    return data


# ------------------------------------------------------------------------------------------- safe format
def network_section(network: LayerNetwork, normalizer: Normalizer | None) -> dict[str, Any]:
    """The manifest's `network` section: every setting of the network and normaliser but the arrays."""
    return {
        "layers": [kind for kind, _, _ in network.actor.layers],
        "columns": list(network.actor.columns) if network.actor.columns is not None else None,
        "observes": list(network.observes),
        "squash": network.scale.squash,
        "normalizer": {"epsilon": normalizer.epsilon, "clip": normalizer.clip} if normalizer else None,
    }


def policy_bytes(network: LayerNetwork, normalizer: Normalizer | None) -> bytes:
    """policy.safetensors's bytes for a network and its normaliser: the weights in float32 as the torch
    actor holds them (RowwiseActor keeps them as float64 copies of those, so nothing is lost), biases,
    action bounds and statistics in their own dtypes."""
    arrays: dict[str, np.ndarray] = {}
    for i, (kind, w, b) in enumerate(network.actor.layers):
        if kind == "linear":
            arrays[f"layer{i}.weight"] = np.ascontiguousarray(w.T.astype(np.float32))
            arrays[f"layer{i}.bias"] = np.ascontiguousarray(b.astype(np.float32))
    arrays["action.low"], arrays["action.high"] = network.scale.low, network.scale.high
    if normalizer is not None:
        arrays["normalizer.mean"], arrays["normalizer.var"] = normalizer.mean, normalizer.var
    for name, a in arrays.items():  # what the float32 round trip must keep, checked before writing
        if not np.isfinite(a).all():
            raise ValueError(f"{name} holds a non-finite value: not a model to save")
    for i, (kind, w, b) in enumerate(network.actor.layers):
        if kind == "linear" and not (
            np.array_equal(arrays[f"layer{i}.weight"].astype(np.float64).T, w)
            and np.array_equal(arrays[f"layer{i}.bias"].astype(np.float64), b)
        ):
            raise ValueError(f"layer {i}'s weights are not float32 values: they would change when saved")
    return save(arrays)


def read_policy(folder: Path, manifest: Any) -> tuple[LayerNetwork, Normalizer | None]:
    """The network and normaliser of a safe folder (`manifest`: its Manifest, as Manifest.read gives it),
    the file's SHA-256 checked first, every setting checked against the arrays; errors name the
    manifest and the key."""
    node = Node({"model": manifest.model, "network": manifest.network}, str(Path(folder) / MANIFEST))
    model = manifest.model
    path = file_in_folder(folder, model, node, "model")
    data = read_checked(path, manifest.sha256, node.source)
    try:
        arrays = load(data)
    except (SafetensorError, ValueError) as e:  # a header that is not what safetensors writes
        raise node.error("model", f"{model} is not a readable safetensors file ({e})") from None
    net = node.section("network")
    layers = net.get("layers")
    if not isinstance(layers, list) or not layers or any(k not in LAYER_KINDS for k in layers):
        raise net.error("layers", f"expected a list of {list(LAYER_KINDS)}, got {layers!r}")
    built: list[tuple[str, np.ndarray | None, np.ndarray | None]] = []
    observes = net.get("observes")
    if not (isinstance(observes, list) and len(observes) == 1 and _count(observes[0])):
        raise net.error("observes", f"expected [input size], got {observes!r}")
    columns = net.get("columns")
    if columns is not None and not (
        isinstance(columns, list) and all(_count(c, 0) and c < observes[0] for c in columns) and columns
    ):
        raise net.error("columns", f"expected null or input indices below {observes[0]}, got {columns!r}")
    width = len(columns) if columns is not None else observes[0]  # each linear layer's input size
    used = {"action.low", "action.high"}
    for i, kind in enumerate(layers):
        if kind != "linear":
            built.append((kind, None, None))
            continue
        w, b = arrays.get(f"layer{i}.weight"), arrays.get(f"layer{i}.bias")
        if w is None or b is None or w.ndim != 2 or b.shape != (w.shape[0],) or w.shape[1] != width:
            raise net.error(
                "layers", f"layer {i} (linear): no weight/bias arrays of input size {width} in {model}"
            )
        if w.dtype != np.float32 or b.dtype != np.float32:
            raise net.error("layers", f"layer {i}: expected float32 arrays, got {w.dtype}, {b.dtype}")
        built.append(("linear", w.astype(np.float64).T.copy(), b.astype(np.float64)))
        used |= {f"layer{i}.weight", f"layer{i}.bias"}
        width = w.shape[0]
    low, high = arrays.get("action.low"), arrays.get("action.high")
    if low is None or high is None or low.shape != (width,) or high.shape != (width,):
        raise net.error("layers", f"the output size {width} does not match action.low/high in {model}")
    squash = net.boolean("squash")
    normalizer = None
    if net.get("normalizer") is not None:
        n = net.section("normalizer")
        mean, var = arrays.get("normalizer.mean"), arrays.get("normalizer.var")
        if mean is None or var is None or mean.shape != (observes[0],) or var.shape != mean.shape:
            raise net.error("normalizer", f"no normalizer.mean/var of size {observes[0]} in {model}")
        if (var < 0).any():
            raise net.error("normalizer", "normalizer.var holds a negative variance")
        eps, clip = n.positive("epsilon"), n.positive("clip")
        n.done()
        normalizer = Normalizer(mean.astype(np.float64), var.astype(np.float64), eps, clip)
        used |= {"normalizer.mean", "normalizer.var"}
    if extra := sorted(set(arrays) - used):
        raise node.error("model", f"{model} holds arrays the manifest does not describe: {extra}")
    for name in used:
        if not np.isfinite(arrays[name]).all():
            raise node.error("model", f"{name} in {model} holds a non-finite value")
    net.done()
    actor = RowwiseActor(tuple(columns) if columns is not None else None, tuple(built))
    scale = ActionScale(low, high, squash)
    return LayerNetwork(actor, scale, (observes[0],), manifest.algorithm), normalizer


def _count(x: Any, least: int = 1) -> bool:
    return isinstance(x, int) and not isinstance(x, bool) and x >= least


def write_policy(folder: Path, network: LayerNetwork, normalizer: Normalizer | None) -> dict[str, Any]:
    """policy.safetensors into folder (atomically); returns the manifest's fields for it (model,
    network, sha256)."""
    data = policy_bytes(network, normalizer)
    atomic_write(Path(folder) / POLICY, lambda p: p.write_bytes(data))
    return {
        "model": POLICY,
        "network": network_section(network, normalizer),
        "sha256": {POLICY: sha256_bytes(data)},
    }


# ------------------------------------------------------------------------------------------- SB3 zips
def load_sb3_zip(
    model: Path, normalizer: Path | None, algorithm: str, *, trust_pickle: bool = False
) -> tuple[Any, Normalizer | None]:
    """An SB3 model.zip (and a pickled VecNormalize) as (model, normaliser statistics). Both files are
    pickles underneath: loading them runs whatever code they hold, so this refuses unless the caller
    passes trust_pickle=True (the command line's --trust-pickle)."""
    if not trust_pickle:
        raise UntrustedModel(
            "model",
            f"{model.name} is a stable-baselines3 zip, whose loading runs code (cloudpickle); convert it "
            "once, trusting its source: frictiongym convert-model FOLDER --trust-pickle --out DEST",
            str(model),
        )
    loaded = algorithm_class(algorithm).load(io.BytesIO(model.read_bytes()), device="cpu")
    stats = None
    if normalizer is not None:
        stats = Normalizer.of(pickle.loads(normalizer.read_bytes()))  # trusted: the caller said so
    return loaded, stats
