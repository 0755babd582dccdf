"""A model folder cannot run code (agents/learned/folder.py): every crafted folder, manifest or YAML fails
closed with a one-line error naming the file and what is wrong, and leaves no trace of its payload; the
one door for a pickle-bearing SB3 zip is convert-model with --trust-pickle."""

from __future__ import annotations

import io
import pickle
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import bit_flips, load_script, write_config

from frictiongym.agents import registry
from frictiongym.agents.evaluation import leaderboard
from frictiongym.agents.learned.convert import convert_folder
from frictiongym.agents.learned.folder import POLICY, SEAL, UntrustedModel, seal, sealed_names
from frictiongym.agents.learned.manifest import MANIFEST, Manifest
from frictiongym.agents.learned.policy import LearnedPolicy
from frictiongym.envs.config import ConfigError
from frictiongym.envs.suites import Episode

COMMITTED = Path(__file__).parents[1] / "agents" / "models" / "specialist" / "ResSAC-kang_regulation-s0"


class Payload:
    """A pickle that writes a marker file when it is loaded (what a hostile model file would do)."""

    def __init__(self, marker: Path):
        self.marker = marker

    def __reduce__(self):
        return (Path.write_text, (self.marker, "the payload ran"))


def hostile_zip(marker: Path) -> bytes:
    """An SB3-shaped model.zip whose `data` entry holds a cloudpickled payload, as SB3 saves lr_schedule."""
    import base64
    import json

    data = {"lr_schedule": {":type:": "<class 'function'>", ":serialized:": ""}}
    data["lr_schedule"][":serialized:"] = base64.b64encode(pickle.dumps(Payload(marker))).decode()
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        z.writestr("data", json.dumps(data))
    return buf.getvalue()


def safe_copy(tmp_path: Path) -> Path:
    folder = tmp_path / "models" / COMMITTED.name
    shutil.copytree(COMMITTED, folder)
    return folder


def edit_manifest(folder: Path, **changes) -> None:
    """The manifest changed and the folder sealed again: what a hostile author (or a careless one who
    re-seals) hands over; a changed manifest without a new seal is refused by the seal alone."""
    raw = yaml.safe_load((folder / MANIFEST).read_text())
    raw.update(changes)
    (folder / MANIFEST).write_text(yaml.safe_dump(raw, sort_keys=False))
    seal(folder, sealed_names(folder))


def refused_everywhere(folder: Path, marker: Path, field: str, capsys, source: str = MANIFEST) -> None:
    """The folder is refused by the registry (naming `source` in the folder, and the field) and the
    leaderboard's and windows' command lines (one line, rc 2), and its payload never ran."""
    with pytest.raises(ConfigError) as e:
        registry.model_factory(folder)
    assert e.value.field == field and e.value.source == str(folder / source)
    assert "\n" not in str(e.value)
    with pytest.raises(ConfigError):
        registry.make("x", [str(folder)])
    for script, args in (
        ("leaderboard", ["--scenarios", "kang_regulation", "--seeds", "5000", "--workers", "1"]),
        ("windows", ["--scenario", "kang_regulation", "--seeds", "5000", "--window-s", "1"]),
        ("sim2real", ["--scenario", "kang_regulation", "--workers", "1"]),
    ):
        code = load_script(script).main([*args, "--models", str(folder), "--out", str(folder.parent / "out")])
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 2 and len(err) == 1 and str(folder / source) in err[0], (script, err)
    # on Ray the driver reads every folder before any task is sent (a backend that is never reached)
    with pytest.raises(ConfigError):
        leaderboard.run(
            "inline",
            None,
            None,
            False,
            1,
            [Episode("kang_regulation", 5000, True)],
            (str(folder),),
            ray=NotReached(),
        )
    assert not marker.exists()


def safetensors_of(dtype: str, itemsize: int) -> bytes:
    """A one-element safetensors file of the given dtype, written by hand (the format: an 8-byte length,
    a JSON header, the data)."""
    import json
    import struct

    header = json.dumps({"w": {"dtype": dtype, "shape": [1], "data_offsets": [0, itemsize]}}).encode()
    return struct.pack("<Q", len(header)) + header + bytes(itemsize)


class NotReached:
    """A backend whose use fails the test."""

    def __getattr__(self, name):
        raise AssertionError(f"the backend was used ({name}) before the model folders were checked")


def test_a_committed_folder_loads_without_pickle_or_torch_and_keeps_its_hash(tmp_path):
    """What a committed folder holds: a manifest and policy.safetensors, its SHA-256 recorded; the
    policy acts from numpy layers (no SB3 model behind it)."""
    folder = safe_copy(tmp_path)
    assert sorted(p.name for p in folder.iterdir()) == sorted(
        [MANIFEST, POLICY, SEAL, "training_curve.png", "validation.csv"]
    )
    policy = registry.make(COMMITTED.name, [str(folder)])
    assert isinstance(policy, LearnedPolicy) and not hasattr(policy.network, "model")
    assert policy.params()["model_sha256"] == Manifest.read(folder).sha256[POLICY]


def test_a_pickled_normalizer_is_refused_before_it_is_read(tmp_path, capsys):
    folder, marker = safe_copy(tmp_path), tmp_path / "marker"
    (folder / "vecnormalize.pkl").write_bytes(pickle.dumps(Payload(marker)))
    edit_manifest(folder, normalizer="vecnormalize.pkl")
    with pytest.raises(UntrustedModel, match="convert-model"):
        Manifest.read(folder)
    refused = load_script("leaderboard").main(
        ["--scenarios", "kang_regulation", "--seeds", "5000", "--models", str(folder), "--out", str(tmp_path)]
    )
    assert refused == 2 and "--trust-pickle" in capsys.readouterr().err and not marker.exists()


def test_an_sb3_zip_is_refused_before_it_is_read(tmp_path, capsys):
    folder, marker = safe_copy(tmp_path), tmp_path / "marker"
    (folder / "model.zip").write_bytes(hostile_zip(marker))
    edit_manifest(folder, model="model.zip")
    with pytest.raises(UntrustedModel, match="stable-baselines3 zip"):
        Manifest.read(folder)
    code = load_script("windows").main(
        ["--scenario", "kang_regulation", "--seeds", "5000", "--models", str(folder), "--out", str(tmp_path)]
    )
    assert code == 2 and "convert-model" in capsys.readouterr().err and not marker.exists()


@pytest.mark.parametrize(
    "where", ["../outside.safetensors", "/tmp/outside.safetensors", "sub/policy.safetensors"]
)
def test_a_file_outside_the_folder_is_refused(tmp_path, where):
    folder = safe_copy(tmp_path)
    edit_manifest(folder, model=where)
    with pytest.raises(ConfigError, match="expected a name matching") as e:
        Manifest.read(folder)
    assert e.value.field == "model"


def test_a_linked_file_is_refused(tmp_path):
    folder = safe_copy(tmp_path)
    outside = tmp_path / "elsewhere.safetensors"
    (folder / POLICY).rename(outside)
    (folder / POLICY).symlink_to(outside)
    with pytest.raises(ConfigError, match="symbolic link"):
        Manifest.read(folder)


def test_a_changed_file_is_refused_by_the_seal(tmp_path, capsys):
    folder = safe_copy(tmp_path)
    data = bytearray((folder / POLICY).read_bytes())
    data[-3] ^= 1  # one bit of one weight
    (folder / POLICY).write_bytes(bytes(data))
    refused_everywhere(folder, tmp_path / "marker", POLICY, capsys, SEAL)


def test_a_file_changed_under_a_new_seal_is_refused_by_the_manifest_s_sha256(tmp_path, capsys):
    folder = safe_copy(tmp_path)
    data = bytearray((folder / POLICY).read_bytes())
    data[-3] ^= 1
    (folder / POLICY).write_bytes(bytes(data))
    seal(folder, sealed_names(folder))
    refused_everywhere(folder, tmp_path / "marker", "sha256.policy.safetensors", capsys)


def test_a_missing_sha256_is_refused(tmp_path):
    folder = safe_copy(tmp_path)
    edit_manifest(folder, sha256={})
    with pytest.raises(ConfigError, match="no SHA-256 recorded") as e:
        Manifest.read(folder)
    assert e.value.field == "sha256"


@pytest.mark.parametrize(
    ("data", "why"),
    [
        (b"\xff" * 64, "not a safetensors file of float arrays"),  # a header length past the file's end
        (b'\x08\x00\x00\x00\x00\x00\x00\x00{"a": 1}', "not a safetensors file of float arrays"),
        # a bfloat16 array (numpy has no such dtype: safetensors.numpy raised KeyError 'BF16')
        (safetensors_of("BF16", 2), "not a safetensors file of float arrays"),
        (safetensors_of("I32", 4), r"arrays \['w'\] are not float32 or float64"),
    ],
)
def test_a_malformed_policy_file_is_a_one_line_error(tmp_path, capsys, data, why):
    """A file whose SHA-256 its (hostile) author recorded but which is not a safetensors file."""
    import hashlib

    folder = safe_copy(tmp_path)
    (folder / POLICY).write_bytes(data)
    edit_manifest(folder, sha256={POLICY: hashlib.sha256(data).hexdigest()})
    with pytest.raises(ConfigError, match=why) as e:
        registry.model_factory(folder)
    assert e.value.field == "model" and "\n" not in str(e.value)


@pytest.mark.parametrize(
    ("network", "field"),
    [
        ({"layers": ["linear", "os.system"]}, "network.layers"),
        ({"observes": [999]}, "network.layers"),  # the arrays do not fit the stated input
        ({"columns": [-1]}, "network.columns"),
        ({"normalizer": {"epsilon": -1.0, "clip": 10.0}}, "network.normalizer.epsilon"),
        ({"extra": 1}, "network.extra"),
    ],
)
def test_a_network_section_that_does_not_fit_its_arrays_is_refused(tmp_path, network, field):
    folder = safe_copy(tmp_path)
    raw = yaml.safe_load((folder / MANIFEST).read_text())
    raw["network"].update(network)
    edit_manifest(folder, network=raw["network"])
    with pytest.raises(ConfigError) as e:
        registry.model_factory(folder)
    assert e.value.field == field


def test_a_yaml_tag_in_a_manifest_is_refused(tmp_path):
    folder, marker = safe_copy(tmp_path), tmp_path / "marker"
    text = (folder / MANIFEST).read_text()
    (folder / MANIFEST).write_text(text + f"extra: !!python/object/apply:pathlib.Path.touch [{marker}]\n")
    seal(folder, sealed_names(folder))
    with pytest.raises(ConfigError):
        Manifest.read(folder)
    assert not marker.exists()


@pytest.fixture
def sb3_folder(tmp_path):
    """A model folder of the SB3 form, as the suite wrote them before the safe format: model.zip and a
    pickled VecNormalize, with a manifest naming them; and the model and normaliser themselves."""
    from stable_baselines3.common.vec_env import VecNormalize

    from frictiongym.agents.training import build_model, load_config, make_training_env

    (cfg,) = load_config(write_config(tmp_path, "SAC"))
    venv = VecNormalize(make_training_env(cfg, 0))
    model = build_model(cfg, venv, 0, None)
    import torch

    with torch.no_grad():  # a non-trivial actor: the zeroed output layer would make every action equal
        for p in model.policy.parameters():
            p.add_(0.05 * torch.randn_like(p))
    venv.obs_rms.mean[:] = np.linspace(-1, 1, venv.obs_rms.mean.size)
    venv.obs_rms.var[:] = np.linspace(0.5, 2, venv.obs_rms.var.size)
    folder = tmp_path / "sb3" / "Tiny"
    folder.mkdir(parents=True)
    model.save(folder / "model.zip")
    (folder / "vecnormalize.pkl").write_bytes(pickle.dumps(venv))
    raw = {
        "name": "Tiny",
        "algorithm": "SAC",
        "model": "model.zip",
        "normalizer": "vecnormalize.pkl",
        "base_controller": cfg.base,
        "alpha": cfg.alpha,
        "command": f"python {tmp_path}/scripts/train.py --config x --out /somewhere/else",
    }
    (folder / MANIFEST).write_text(yaml.safe_dump(raw, sort_keys=False))
    return folder, model, venv, cfg


def test_convert_model_needs_trust_and_keeps_every_action(tmp_path, sb3_folder, capsys):
    """convert-model refuses without --trust-pickle (the payload never runs); with it, the converted
    folder's policy gives the SB3 model's actions (through its layers and frozen statistics) bit for bit
    on random inputs, and its command holds no machine path."""
    folder, model, venv, cfg = sb3_folder
    marker = tmp_path / "marker"
    hostile = tmp_path / "hostile" / "Tiny"
    shutil.copytree(folder, hostile)
    (hostile / "vecnormalize.pkl").write_bytes(pickle.dumps(Payload(marker)))
    convert = load_script("convert_model").main
    assert convert([str(hostile), "--out", str(tmp_path / "safe")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--trust-pickle" in err[0] and not marker.exists()

    out = convert_folder(folder, tmp_path / "safe", trust_pickle=True, root=tmp_path)
    assert sorted(p.name for p in out.iterdir()) == [SEAL, MANIFEST, POLICY]
    m = Manifest.read(out)
    assert m.command == "python scripts/train.py --config x --out runs"
    base = registry.base_controller(cfg.base)
    saved = LearnedPolicy(model, inputs=cfg.inputs, base=base, alpha=cfg.alpha, normalizer=venv)
    loaded = registry.make("Tiny", [str(out)])
    rng = np.random.default_rng(0)
    obs = rng.normal(0.0, 3.0, (200, model.observation_space.shape[0] - 1)).astype(np.float32)
    u = rng.uniform(-1, 1, (200, 1)).astype(np.float32)
    for p in (saved, loaded):
        p._fill, p._reference_end, p._differences = 0, 0, None
    assert np.array_equal(saved.actions(obs, u), loaded.actions(obs, u))
    assert len(np.unique(loaded.actions(obs, u))) > 50


def test_zoo_config_is_read_safely(tmp_path):
    """rl-zoo's config.yml (an OrderedDict written as a Python object) reads as a mapping; any other tag
    is refused before it is constructed."""
    from frictiongym.agents.training.zoo import zoo_config

    params = tmp_path / "run" / "KangRobot-v1"
    params.mkdir(parents=True)
    (params / "config.yml").write_text(
        "!!python/object/apply:collections.OrderedDict\n- - - n_timesteps\n    - 2000\n  - - policy\n"
        "    - MlpPolicy\n"
    )
    assert zoo_config(tmp_path / "run") == {"n_timesteps": 2000, "policy": "MlpPolicy"}
    marker = tmp_path / "marker"
    (params / "config.yml").write_text(f"!!python/object/apply:pathlib.Path.touch [{marker}]\n")
    with pytest.raises(ConfigError, match=r"config\.yml"):
        zoo_config(tmp_path / "run")
    assert not marker.exists()


@pytest.mark.parametrize("name", [MANIFEST, POLICY, SEAL, "validation.csv", "training_curve.png"])
def test_a_single_bit_flip_anywhere_in_a_committed_folder_is_refused(tmp_path, name):
    """The seal covers every file, the manifest's own text included (before it, 1,165 of 2,154 bit
    flips of a manifest loaded): 64 positions of each file, a random bit each, all refused."""
    folder = safe_copy(tmp_path)
    original = (folder / name).read_bytes()
    for pos, flipped in bit_flips(original, 64):
        (folder / name).write_bytes(flipped)
        with pytest.raises(ConfigError) as e:
            registry.model_factory(folder)
        assert "\n" not in str(e.value), pos
    (folder / name).write_bytes(original)
    assert registry.model_factory(folder)[0] == COMMITTED.name  # the sweep's folder itself was sound


def test_a_linked_manifest_or_linked_model_folder_is_refused(tmp_path):
    folder = safe_copy(tmp_path)
    outside = tmp_path / "elsewhere.yaml"
    (folder / MANIFEST).rename(outside)
    (folder / MANIFEST).symlink_to(outside)
    with pytest.raises(ConfigError, match="symbolic link") as e:
        registry.model_factory(folder)
    assert e.value.source == str(folder / SEAL)
    collection = tmp_path / "collection"
    collection.mkdir()
    (collection / "linked").symlink_to(COMMITTED)
    with pytest.raises(ValueError, match=r"\['linked'\] are links"):
        registry.model_dirs([collection])


def test_inputs_that_disagree_with_the_network_are_refused_at_load(tmp_path):
    """A manifest whose inputs.history is not what its network takes on its own scenario fails when the
    folder is read (it failed four episodes into a run with a numpy broadcast error)."""
    folder = safe_copy(tmp_path)
    raw = yaml.safe_load((folder / MANIFEST).read_text())
    edit_manifest(folder, inputs={**raw["inputs"], "history": 2})
    with pytest.raises(
        ConfigError, match="on its own scenario kang_regulation: the model observes shape"
    ) as e:
        registry.model_factory(folder)
    assert e.value.field == "inputs"


def test_an_alias_bomb_in_a_sealed_manifest_ends_at_once_in_one_line(tmp_path):
    """A kilobyte of YAML aliases in network.layers (it took 105 s and 3 GB to refuse, printing it)."""
    folder = safe_copy(tmp_path)
    text = (folder / MANIFEST).read_text()
    bomb = "bomb0: &b0 [linear, linear, linear, linear, linear, linear, linear, linear]\n" + "".join(
        f"bomb{i}: &b{i} [{', '.join([f'*b{i - 1}'] * 8)}]\n" for i in range(1, 9)
    )
    (folder / MANIFEST).write_text(
        bomb + text.replace("network:\n  layers:", "network:\n  layers: *b8\n  old:")
    )
    seal(folder, sealed_names(folder))
    with pytest.raises(ConfigError, match="more than 200000 values") as e:
        registry.model_factory(folder)
    assert len(str(e.value)) < 400
