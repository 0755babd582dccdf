"""The controller registry (agents/registry.py): saved models are judged applicable from their manifests
alone, as the loaded model would judge itself."""

from pathlib import Path

import pytest

from frictiongym.agents import registry
from frictiongym.agents.learned.manifest import Manifest
from frictiongym.envs.scenario import load_scenario
from frictiongym.envs.suites import load_suite

ROOT = Path(__file__).parents[1]


def test_a_saved_models_applicability_from_its_manifest_equals_the_loaded_models():
    folders = registry.committed_models(*registry.LEADERBOARD_GROUPS, "sim2real")
    # (the generalists fill a missing preview in on m220_regulation, learned.py)
    models = tuple(str(f) for f in folders)
    scenarios = [load_scenario(s) for s in dict.fromkeys(e.scenario for e in load_suite("default"))]
    names = list(registry._manifests(models))
    assert len(names) == len(folders) >= 15
    applies = 0
    for name in names:
        from_manifest, loaded = registry.why_not(name, models), registry.make(name, models)
        assert from_manifest.__class__.__name__ == "partial"  # decided without loading the zip
        for sc in scenarios:
            assert from_manifest(sc) == loaded.why_not(sc), (name, sc.name)
            applies += from_manifest(sc) is None
    assert 0 < applies < len(names) * len(scenarios)  # some apply, some are refused (other plants, shapes)


def test_every_committed_model_is_numpy_layers_within_float32_rounding_of_torch_s_forward():
    """Every committed model loads as a LayerNetwork (numpy layers from policy.safetensors: no SB3 model,
    no pickle), whose float64 row-wise actions are the float32 torch forward of the same weights to
    float32 rounding (|difference| <= 1e-5 on inputs spread over the normalised range: torch sums 64
    float32 terms per unit, measured up to 1.2e-6 on these models when they were SB3 zips)."""
    import numpy as np
    import torch

    from frictiongym.agents.learned.policy import LayerNetwork

    folders = registry.committed_models(*registry.LEADERBOARD_GROUPS, "sim2real")
    models = tuple(str(f) for f in folders)
    rng = np.random.default_rng(2)
    for name in registry._manifests(models):
        network = registry.make(name, models).network
        assert isinstance(network, LayerNetwork), name
        x = rng.normal(0.0, 2.0, (50, *network.observes)).astype(np.float32)
        h = torch.as_tensor(x if network.actor.columns is None else x[:, network.actor.columns])
        for kind, w, b in network.actor.layers:
            if kind == "linear":
                h = torch.nn.functional.linear(
                    h, torch.as_tensor(w.T.astype(np.float32)), torch.as_tensor(b.astype(np.float32))
                )
            else:
                h = torch.relu(h) if kind == "relu" else torch.tanh(h)
        assert network.scale.squash, name
        want = network.scale(h.numpy())
        assert np.abs(network(x) - want).max() <= 1e-5 and len(np.unique(want)) > 10, name


def test_the_default_leaderboard_runs_the_specialists_and_one_generalist_set_per_plant_it_has():
    """Issue 21: the generalists run on the default leaderboard beside the specialists, group by group,
    each a distinct controller name; a generalist set applies to every default-suite scenario of its
    plant (one layout per plant: learned.preview_fill), a specialist is not required to."""
    folders = registry.committed_models(*registry.LEADERBOARD_GROUPS)
    assert folders == [*registry.committed_models("specialist"), *registry.committed_models("generalist")]
    assert registry.LEADERBOARD_GROUPS == ("specialist", "generalist")  # what the command runs by default
    models = tuple(str(f) for f in folders)
    manifests = registry._manifests(models)
    assert len(manifests) == len(folders)  # names distinct
    default = [load_scenario(s) for s in dict.fromkeys(e.scenario for e in load_suite("default"))]
    plants = set()
    for folder, (name, m) in zip(folders, manifests.items(), strict=True):  # read in folder order
        if folder.parent.name != "generalist":
            continue
        plant = load_scenario(m.scenario).spec.name
        why_not = registry.why_not(name, models)
        own = [sc for sc in default if sc.spec.name == plant]
        assert own and all(why_not(sc) is None for sc in own), name
        plants.add(plant)
    assert plants == {"kang_robot", "m220", "flexible_servo", "emps"}


def test_a_residual_base_is_made_by_name_but_never_a_baseline_or_a_default_entry():
    """registry.BASES: the speed-scheduled blend is no seed's controller, so no default run ranks it and
    no leaderboard counts it as classical; asked for by name it runs like any controller."""
    import pytest

    from frictiongym.agents.evaluation.leaderboard import classical

    assert set(registry.BASES) == {"SpeedScheduled", "TaskScheduled", "SF+relay/residual-base"}
    used = {
        Manifest.read(f).base_controller
        for f in registry.committed_models("specialist", "generalist", "sim2real")
    }
    assert set(registry.BASES) <= used  # every base is one a committed model runs over
    assert set(registry.available()) - set(registry.default_entries()) == set(registry.BASES)
    for name in registry.BASES:
        assert name not in registry.BUILTIN and name not in registry.default_entries()
        assert not classical(name)
        assert registry.make(name).name == registry.base_controller(name).name == name
    assert registry.base_controller("PID").name == "PID"
    for bad in ("Zero", "Ideal", "PIDD"):
        with pytest.raises(ValueError, match=f"unknown base controller '{bad}'; allowed: .*SpeedScheduled"):
            registry.base_controller(bad)


def test_a_finished_run_may_name_a_group_of_model_folders_the_command_line_allows(tmp_path):
    """run.json records --models as given, e.g. the committed group agents/models/specialist: the report
    allows it when the command line names the same group (every model folder in it allowed), and refuses
    it, naming the flag, when the command line allows only one of its folders."""
    group = str(ROOT / "agents/models/specialist")
    assert registry.allowed_sources((group,), [group], "run.json") == (group,)
    one = registry.model_dirs([group])[0]
    assert registry.allowed_sources((str(one),), [group], "run.json") == (str(one),)
    with pytest.raises(ValueError, match=f"names the model folder '{group}': pass --models {group}"):
        registry.allowed_sources((group,), [one], "run.json")
