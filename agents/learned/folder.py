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
import os
import pickle
import re
import stat
from collections.abc import Iterable, Mapping
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
from frictiongym.envs.records import atomic_text, atomic_write

MANIFEST = "manifest.yaml"  # a model folder's description (agents/learned/manifest.py)
# The seal of a model or export folder: every file of it (sub-folders' included) with its SHA-256, in the
# form GNU `sha256sum` writes and checks (`sha256sum -c SHA256SUMS`). It covers the manifest's own text.
SEAL = "SHA256SUMS"
MAX_SEAL_BYTES = 1 << 16  # the seal file itself, bytes
MAX_FOLDER_BYTES = 1 << 26  # every sealed file together, bytes (a committed model folder: about 70 kB)
_SEAL_LINE = re.compile(r"([0-9a-f]{64})  ([A-Za-z0-9_.+-]+(?:/[A-Za-z0-9_.+-]+)?)\n")

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


def check_digest(name: str, data: bytes, digests: Mapping[str, str], source: str) -> bytes:
    """data (the bytes of file `name`) after its SHA-256 matched the manifest's (a one-line ConfigError
    otherwise, naming the manifest and the file)."""
    want = digests.get(name)
    if want is None:
        raise ConfigError(f"sha256.{name}", "no SHA-256 recorded for this file", source)
    if sha256_bytes(data) != want:
        raise ConfigError(
            f"sha256.{name}", f"{name} does not match its recorded SHA-256 (changed or corrupt)", source
        )
    return data


# ------------------------------------------------------------------------------------------- the seal
def seal(folder: Path, names: Iterable[str]) -> None:
    """Write folder/SHA256SUMS over the files `names` (paths relative to folder, at most one sub-folder
    deep), atomically, sorted: the last file a model or export folder gets."""
    folder = Path(folder)
    lines = [f"{sha256_bytes((folder / n).read_bytes())}  {n}\n" for n in sorted(set(names))]
    for line in lines:
        if not _SEAL_LINE.fullmatch(line):
            raise ValueError(f"{line.split()[1]!r}: not a file name a seal can hold (letters, digits, _.+-)")
    atomic_text(folder / SEAL, "".join(lines))


def sealed_names(folder: Path) -> list[str]:
    """The regular files of folder and of its sub-folders (one level), relative, for seal(): no link."""
    out = []
    for entry in sorted(os.scandir(folder), key=lambda e: e.name):
        if entry.name == SEAL or entry.name.startswith("."):
            continue
        if entry.is_dir(follow_symlinks=False):
            out += [
                f"{entry.name}/{e.name}"
                for e in sorted(os.scandir(entry.path), key=lambda e: e.name)
                if e.is_file(follow_symlinks=False) and not e.name.startswith(".")
            ]
        elif entry.is_file(follow_symlinks=False):
            out.append(entry.name)
    return out


class SealError(ConfigError):
    """A model or export folder whose seal (SHA256SUMS) is missing, malformed or does not match."""


def read_sealed(folder: Path, described_by: str = MANIFEST) -> dict[str, bytes]:
    """Every file a folder's seal lists, read once each, after the seal was checked: SHA256SUMS a regular
    file in the folder, each of its lines `<64 lowercase hex>  <name>` (a name of letters, digits and _.+-,
    at most one sub-folder deep, sorted, once), each listed file a regular file reached without a link,
    its SHA-256 the listed one, all together at most MAX_FOLDER_BYTES. Files the seal does not list are
    never opened; the seal must cover `described_by` (the folder's manifest.yaml or runtime.yaml). Any
    mismatch is a SealError naming the folder and the file."""
    folder = Path(folder)
    where = str(folder / SEAL)
    data = _read_plain(
        folder,
        SEAL,
        MAX_SEAL_BYTES,
        where,
        f"missing: a model or export folder is sealed by the suite when written; to trust an older one, "
        f"write it yourself: (cd {folder} && sha256sum FILE... > {SEAL}), its files sorted by name",
    )
    try:
        text = data.decode("ascii")
    except UnicodeDecodeError:
        raise SealError("(file)", "not a SHA256SUMS text (a byte outside ASCII)", where) from None
    lines = text.splitlines(keepends=True)
    names = []
    for i, line in enumerate(lines, 1):
        if not (m := _SEAL_LINE.fullmatch(line)) or any(p in (".", "..") for p in m[2].split("/")):
            raise SealError(
                f"line {i}", f"expected '<64 lowercase hex digits>  <file name>', got {line!r}", where
            )
        names.append(m[2])
    if not names or names != sorted(set(names)):
        raise SealError("(file)", "expected one line per file, sorted by name, each file once", where)
    if described_by not in names:
        raise SealError("(file)", f"the seal does not cover the folder's {described_by}", where)
    files, total = {}, 0
    for line, name in zip(lines, names, strict=True):
        body = _read_plain(folder, name, MAX_FOLDER_BYTES - total, where, "listed but missing")
        total += len(body)
        if sha256_bytes(body) != line[:64]:
            raise SealError(name, "does not match its SHA-256 in the seal (changed or corrupt)", where)
        files[name] = body
    return files


def _read_plain(folder: Path, name: str, limit: int, where: str, absent: str) -> bytes:
    """folder/name's bytes: each part of the path reached without following a link, the file regular and
    at most `limit` bytes (opened with O_NOFOLLOW, checked on the open descriptor)."""
    path = Path(folder)
    parts = name.split("/")
    for part in parts[:-1]:
        path = path / part
        try:
            if not stat.S_ISDIR(os.lstat(path).st_mode):
                raise SealError(name, f"{part} is not a folder of the sealed folder (a link?)", where)
        except FileNotFoundError:
            raise SealError(name, absent, where) from None
    path = path / parts[-1]
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
    except FileNotFoundError:
        raise SealError(name, absent, where) from None
    except OSError as e:  # ELOOP: a symbolic link
        why = (
            "a symbolic link: a sealed folder holds its files itself" if os.path.islink(path) else e.strerror
        )
        raise SealError(name, f"cannot be read: {why}", where) from None
    with os.fdopen(fd, "rb") as f:
        info = os.fstat(f.fileno())
        if not stat.S_ISREG(info.st_mode):
            raise SealError(name, "not a regular file", where)
        if info.st_size > limit:
            raise SealError(name, f"larger than the {limit} bytes a sealed folder may still hold", where)
        body = f.read(limit + 1)
    if len(body) > limit:
        raise SealError(name, f"larger than the {limit} bytes a sealed folder may still hold", where)
    return body


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


def read_policy(
    files: Mapping[str, bytes], manifest: Any, source: str
) -> tuple[LayerNetwork, Normalizer | None]:
    """The network and normaliser of a safe folder from its sealed files (read_sealed) and its Manifest
    (source: the manifest's path, for errors): the model file's SHA-256 checked against the manifest's,
    its dtypes (float32 weights, floating bounds and statistics), every setting checked against the
    arrays; errors name the manifest and the key."""
    node = Node({"model": manifest.model, "network": manifest.network}, source)
    model = manifest.model
    if model not in files:
        raise node.error("model", f"{model} is not a file of the sealed folder")
    data = check_digest(model, files[model], manifest.sha256, source)
    try:
        arrays = load(data)
    except (SafetensorError, ValueError, KeyError, TypeError) as e:  # a dtype numpy lacks (BF16): KeyError
        raise node.error("model", f"{model} is not a safetensors file of float arrays ({e!r})") from None
    if bad := sorted(k for k, a in arrays.items() if a.dtype not in (np.float32, np.float64)):
        raise node.error("model", f"{model}: arrays {bad} are not float32 or float64")
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
