"""The controller registry (agents/registry.py): saved models are judged applicable from their manifests
alone, as the loaded model would judge itself."""

from frictiongym.agents import registry
from frictiongym.envs.scenario import load_scenario
from frictiongym.envs.suites import load_suite


def test_a_saved_models_applicability_from_its_manifest_equals_the_loaded_models():
    folders = [*registry.committed_models("headline"), *registry.committed_models("sim2real")]
    models = tuple(str(f) for f in folders)
    scenarios = [load_scenario(s) for s in dict.fromkeys(e.scenario for e in load_suite("default"))]
    names = list(registry._manifests(models))
    assert len(names) == len(folders) >= 12
    applies = 0
    for name in names:
        from_manifest, loaded = registry.why_not(name, models), registry.make(name, models)
        assert from_manifest.__class__.__name__ == "partial"  # decided without loading the zip
        for sc in scenarios:
            assert from_manifest(sc) == loaded.why_not(sc), (name, sc.name)
            applies += from_manifest(sc) is None
    assert 0 < applies < len(names) * len(scenarios)  # some apply, some are refused (other plants, shapes)
