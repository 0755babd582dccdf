"""A model folder's manifest (agents/learned/manifest.py): what training writes is what the registry reads."""

from pathlib import Path

import pytest
import yaml

from frictiongym.agents.learned.folder import seal, sealed_names
from frictiongym.agents.learned.manifest import MANIFEST, Manifest
from frictiongym.agents.learned.policy import PolicyInputs
from frictiongym.envs.config import ConfigError

MODELS = Path(__file__).parents[1] / "agents" / "models"


def write_sealed(folder: Path, text: str) -> None:
    """manifest.yaml written by hand, then the folder sealed as training seals it."""
    (folder / MANIFEST).write_text(text)
    seal(folder, sealed_names(folder))


def test_every_committed_manifest_reads_and_writes_back_byte_for_byte():
    folders = sorted(p.parent for p in MODELS.glob("*/*/" + MANIFEST))
    assert len(folders) >= 12
    for folder in folders:
        m = Manifest.read(folder)
        assert m.name == folder.name and m.plants and m.inputs is not None
        assert yaml.safe_dump(m.as_dict(), sort_keys=False) == (folder / MANIFEST).read_text(), folder


def test_a_minimal_manifest_needs_the_model_its_network_and_its_sha256(tmp_path):
    """name, algorithm, model, network and sha256 are enough (then no base, α = 1, any plant)."""
    (tmp_path / "policy.safetensors").write_bytes(b"")
    head = "name: PPO-kang\nalgorithm: PPO\nmodel: policy.safetensors\nnetwork: {layers: [linear]}\n"
    write_sealed(tmp_path, head + f"sha256: {{policy.safetensors: {'ab' * 32}}}\n")
    m = Manifest.read(tmp_path)
    assert (m.model, m.plants, m.alpha) == ("policy.safetensors", (), 1.0)
    assert m.policy_inputs == PolicyInputs()
    write_sealed(tmp_path, head + f"sha256: {{policy.safetensors: {'ab' * 32}}}\nbase_controller: PID\n")
    assert Manifest.read(tmp_path).policy_inputs == PolicyInputs(base_action=True)  # a residual sees its base


def test_the_differences_input_is_written_when_on_and_read_back(tmp_path):
    """`inputs.differences` (a later input) appears in a manifest only when on, and reads back as written;
    older manifests without it read as off."""
    (tmp_path / "policy.safetensors").write_bytes(b"")
    files = {"network": {"layers": ["linear"]}, "sha256": {"policy.safetensors": "ab" * 32}}
    on = Manifest(
        "R", "SAC", **files, base_controller="PID", inputs=PolicyInputs(base_action=True, differences=True)
    )
    on.write(tmp_path)
    seal(tmp_path, sealed_names(tmp_path))
    assert "differences: true" in (tmp_path / MANIFEST).read_text()
    assert Manifest.read(tmp_path).policy_inputs == PolicyInputs(base_action=True, differences=True)
    Manifest("R", "SAC", **files, base_controller="PID", inputs=PolicyInputs(base_action=True)).write(
        tmp_path
    )
    seal(tmp_path, sealed_names(tmp_path))
    assert "differences" not in (tmp_path / MANIFEST).read_text()
    assert Manifest.read(tmp_path).policy_inputs == PolicyInputs(base_action=True)


@pytest.mark.parametrize(
    ("text", "field"),
    [
        ("algoritm: SAC\n", "algoritm"),  # a typo is an unknown key
        ("normalizer: stats.pkl\n", "model"),  # a pickle: refused, naming the conversion
        ("model: other.safetensors\n", "model"),  # a file that is not there
        ("sha256: {policy.safetensors: abc}\n", "sha256"),
        ("network: [linear]\n", "network"),
        ("name: ''\n", "name"),
        ("alpha: -1\n", "alpha"),
        ("plants: m220\n", "plants"),
        ("plants: [nosuch]\n", "plants"),
        ("scenario: ../../configs/scenarios/m220_regulation.yaml\n", "scenario"),  # a name, never a path
        ("name: ../evil\n", "name"),
        ("algorithm: 'SAC\\nforged line'\n", "algorithm"),
        ("alpha: 30\n", "alpha"),
        ("inputs: {history: 100000}\n", "inputs.history"),
    ],
)
def test_a_bad_manifest_is_an_error_naming_the_file_and_key(tmp_path, text, field):
    (tmp_path / "policy.safetensors").write_bytes(b"")
    good = {
        "name": "A",
        "algorithm": "PPO",
        "model": "policy.safetensors",
        "network": {"layers": ["linear"]},
        "sha256": {"policy.safetensors": "ab" * 32},
    }
    bad = yaml.safe_load(text)
    write_sealed(tmp_path, yaml.safe_dump({**good, **bad}, sort_keys=False))
    with pytest.raises(ConfigError) as e:
        Manifest.read(tmp_path)
    assert e.value.field == field and e.value.source == str(tmp_path / MANIFEST)


# Fields RunConfig gained after some committed models were trained, with the value those runs had.
LATER_FIELDS = {"residual_smoothness": 0.0, "reference": {}, "eval_scenarios": []}


def test_every_committed_model_s_command_names_a_config_that_resolves_to_what_it_trained_with():
    """The exact command in each committed manifest re-runs the same training: its --config (a file of
    configs/agents/) resolves, for the manifest's scenario, to the config the manifest recorded, field
    for field (fields added later carry the value those runs had; update_to_data 1 with one env is
    SB3's train_freq 1 and gradient_steps 1)."""
    import dataclasses
    import shlex

    from frictiongym.agents.training import load_config

    for folder in sorted(p.parent for p in MODELS.glob("*/*/" + MANIFEST)):
        m = Manifest.read(folder)
        words = shlex.split(m.command)
        assert words[:2] == ["python", "scripts/train.py"], folder
        (cfg,) = load_config(words[words.index("--config") + 1], m.scenario)
        now = {**cfg.as_dict(), "inputs": dataclasses.asdict(cfg.inputs)}
        rec = {**LATER_FIELDS, **m.config, "inputs": {"differences": False, **m.config["inputs"]}}
        hp = rec["hyperparams"]
        if "update_to_data" not in rec and hp.get("train_freq") == hp.get("gradient_steps") == 1:
            rec["hyperparams"] = {k: v for k, v in hp.items() if k not in ("train_freq", "gradient_steps")}
            rec["update_to_data"] = 1.0
        assert rec.pop("source") == now.pop("source").split("/configs/", 1)[-1].join(["configs/", ""])
        assert now == rec, folder


def test_no_committed_text_file_holds_a_machine_path():
    """Commands and sources are relative to the repository: no committed text names /work, /tmp, /home,
    /root or /Users (the machines runs were made on)."""
    import re
    import subprocess

    root = Path(__file__).parents[1]
    files = subprocess.run(["git", "ls-files"], cwd=root, capture_output=True, text=True, check=True).stdout
    pattern = re.compile(r"(?<![\w.])/(work|tmp|home|root|Users)/")
    bad = []
    for name in files.split():
        path = root / name
        if path.suffix in (".yaml", ".yml", ".md", ".csv", ".txt", ".toml", ".cfg") and path.is_file():
            bad += [
                f"{name}:{i}"
                for i, line in enumerate(path.read_text(errors="ignore").splitlines(), 1)
                if pattern.search(line)
            ]
    assert not bad, bad


def test_the_recorded_command_is_what_was_typed_from_the_repository(monkeypatch, tmp_path):
    """A run's `command` (manifests, run.json, identified.yaml) is the frictiongym command as typed when
    that dispatched it (its argv[0] is "frictiongym COMMAND"), else python and the script, relative to
    the working directory below which it lies: no machine path, runnable from the repository."""
    from frictiongym.envs.records import command_line

    monkeypatch.setattr("sys.argv", ["frictiongym train", "--config", "residual_sac", "--out", "out/a b"])
    assert command_line() == "frictiongym train --config residual_sac --out 'out/a b'"
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr("sys.argv", [str(tmp_path / "scripts" / "train.py"), "--seed", "0"])
    assert command_line().endswith(" scripts/train.py --seed 0")
    assert command_line().split()[0].startswith("python")
    monkeypatch.setattr("sys.argv", ["/elsewhere/train.py"])
    assert command_line().endswith(" /elsewhere/train.py")
