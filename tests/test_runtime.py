"""A controller outside the env (agents/deploy/runtime.py): an exported artefact's runtime, fed the readings,
reference and preview of an env-driven run, gives that run's commands; every file is checked before use.

The runtime forms the observation with the env's arithmetic from the sensors' raw readings (recorded
where the env computes them): its commands are the env-driven run's bit for bit with numpy, and within
ONNX_TOLERANCE of a full-scale action with onnxruntime's float32 network."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import bit_flips

from frictiongym.agents import registry
from frictiongym.agents.base import EpisodeContext
from frictiongym.agents.deploy.runtime import RUNTIME, Runtime, export
from frictiongym.agents.evaluation.evaluate import EnvCache
from frictiongym.agents.learned.folder import SEAL, seal, sealed_names
from frictiongym.agents.settings import knowledge_defaults
from frictiongym.envs.config import ConfigError
from frictiongym.envs.suites import Episode, load_suite

pytestmark = pytest.mark.skipif(importlib.util.find_spec("onnxruntime") is None, reason="the deploy extra")
MODELS = registry.committed_models(*registry.LEADERBOARD_GROUPS, "sim2real")
# of a full-scale action: the float32 network against the float64 row-wise one (about 1e-6 a step), and the
# runtime's own held action, which enters its next observation (measured up to 6e-5 on the committed models)
ONNX_TOLERANCE = 1e-4


@pytest.fixture
def raw_readings(monkeypatch) -> dict:
    """The sensors' raw readings (before the observation's 1/s and float32) of the env's last reset or
    step, recorded where the env computes them (the single env's step, the batched measure at reset)."""
    import frictiongym.envs.core as core
    from frictiongym.envs.sensors import SensorArrays

    seen: dict = {"values": []}
    for name in ("encoder_reading", "tacho_reading"):
        original = getattr(core, name)

        def recording(*args, original=original):
            value = original(*args)
            seen["values"].append(float(value))
            return value

        monkeypatch.setattr(core, name, recording)
    measure = SensorArrays.measure

    def measured(self, *args):
        value = measure(self, *args)
        seen["values"] = [float(x) for x in value[0]]
        return value

    monkeypatch.setattr(SensorArrays, "measure", measured)
    return seen


def drive(
    controller, episode: Episode, runtimes: list[Runtime], raw: dict, steps: int | None = None
) -> list[float]:
    """The env-driven episode of `controller` (its own act on the env's observation, applied clipped);
    at each step every runtime is given what a drive would give it: the sensors' raw readings (recorded
    by raw_readings), the reference and its preview (the env's r(t)); returns, per runtime, the largest
    |command - the env-driven command| in full-scale actions."""
    env = EnvCache().env(controller, episode)
    sc = env.scenario
    n = len(sc.spec.sensors)
    raw["values"] = []
    obs, _ = env.reset(seed=episode.seed, options=episode.options())
    controller.reset(EpisodeContext(sc, sc.spec, knowledge_defaults()))
    for rt in runtimes:
        rt.reset()
    worst = [0.0] * len(runtimes)
    ref = env.core.ref[0]
    for k in range(steps or sc.episode_steps):
        a = float(np.asarray(controller.act(obs)).reshape(-1)[0])
        a = min(1.0, max(-1.0, a))
        readings = raw["values"][-n:]
        preview = ref[k + 1 : k + 1 + sc.preview_steps].tolist()
        for i, rt in enumerate(runtimes):
            u = rt.step(readings, ref[k], preview)
            worst[i] = max(worst[i], abs(u / sc.action_scale - a))
        raw["values"] = []
        obs, _, term, trunc, _ = env.step(np.array([a], np.float32))
        if term or trunc:
            break
    return worst


def test_exact_with_numpy_and_within_float32_with_onnx_on_a_test_episode(tmp_path, raw_readings):
    """The committed M220 generalist (residual over the speed schedule) on its first `test` episode of the
    0.2 Hz reversals."""
    folder = next(f for f in MODELS if f.name == "GenSAC-floorgated-m220_random-s0")
    art = export(str(folder), tmp_path / "art", "m220_reversal_tracking")
    assert sorted(p.name for p in art.iterdir()) == [SEAL, "model", "policy.onnx", RUNTIME]
    episode = next(e for e in load_suite("test") if e.scenario == "m220_reversal_tracking")
    c = registry.make(folder.name, [str(folder.parent)])
    numpy_err, onnx_err = drive(
        c, episode, [Runtime.load(art), Runtime.load(art, backend="onnxruntime")], raw_readings
    )
    assert numpy_err == 0.0 and onnx_err <= ONNX_TOLERANCE


@pytest.mark.slow
@pytest.mark.parametrize("folder", MODELS, ids=lambda f: f.name)
def test_every_committed_model_s_runtime_reproduces_its_test_episode(tmp_path, folder, raw_readings):
    """Every committed model on the first `test` episode of its scenario (a generalist's: its plant's
    first tracking scenario there)."""
    name = folder.name
    scenario = yaml.safe_load((folder / "manifest.yaml").read_text())["scenario"]
    tests = [e for e in load_suite("test") if e.scenario == scenario] or [
        e for e in load_suite("test") if e.scenario.split("_")[0] == scenario.split("_")[0]
    ]
    c = registry.make(name, [str(folder.parent)])
    episode = next(e for e in tests if c.why_not(EnvCache().scenario(e)) is None)
    art = export(str(folder), tmp_path / "art", episode.scenario)
    runtimes = [Runtime.load(art), Runtime.load(art, backend="onnxruntime")]
    numpy_err, onnx_err = drive(c, episode, runtimes, raw_readings)
    assert numpy_err == 0.0 and onnx_err <= ONNX_TOLERANCE


@pytest.mark.parametrize(
    ("name", "scenario"),
    [
        ("PID", "kang_ramp"),
        ("PID+FF", "m220_reversal_tracking"),
        ("LuGreObserver", "m220_random"),
        ("Southward", "kang_regulation"),
        ("RDFC", "kang_regulation"),  # a base that brings hardware (the analog rate loop) into the plant
        ("SF+relay", "flexible_zero_speed"),
        ("LabPD", "emps_tracking"),
        ("SpeedScheduled", "m220_random"),
        ("PD", "kang_ramp"),
        ("CoulombViscousFF", "m220_reversal_tracking"),
        ("SF", "flexible_zero_speed"),
        ("SF+highgain", "flexible_zero_speed"),
        ("TaskScheduled", "kang_ramp"),
        ("SF+relay/residual-base", "flexible_speed_step"),
    ],
)
def test_every_classical_family_s_runtime_gives_its_env_run_s_commands(
    tmp_path, name, scenario, raw_readings
):
    art = export(name, tmp_path / "art", scenario)
    assert not (art / "policy.onnx").exists()
    episode = Episode(scenario, 700000, True)
    assert drive(registry.make(name), episode, [Runtime.load(art)], raw_readings, steps=1500) == [0.0]


def reseal(art: Path, **changes) -> None:
    """runtime.yaml changed (keys set, or removed when None) and the artefact sealed again: what a
    hostile or careless author hands over."""
    spec = yaml.safe_load((art / RUNTIME).read_text())
    for key, value in changes.items():
        if value is None:
            del spec[key]
        else:
            spec[key] = value
    (art / RUNTIME).write_text(yaml.safe_dump(spec, sort_keys=False))
    seal(art, sealed_names(art))


def test_a_changed_file_is_refused_by_the_seal(tmp_path):
    folder = next(f for f in MODELS if f.name == "ResSAC-kang_regulation-s0")
    art = export(str(folder), tmp_path / "art")
    assert (art / SEAL).read_text().splitlines()[-1].endswith("  runtime.yaml")  # the spec is sealed too
    onnx = art / "policy.onnx"
    onnx.write_bytes(onnx.read_bytes() + b"\0")
    with pytest.raises(ConfigError, match=r"policy\.onnx: does not match its SHA-256 in the seal"):
        Runtime.load(art)


@pytest.mark.parametrize("name", [RUNTIME, "model/manifest.yaml", "model/policy.safetensors", SEAL])
def test_a_single_bit_flip_anywhere_in_an_export_is_refused(tmp_path, name):
    folder = next(f for f in MODELS if f.name == "ResSAC-kang_regulation-s0")
    art = export(str(folder), tmp_path / "art")
    for pos, flipped in bit_flips((art / name).read_bytes(), 24):
        (art / name).write_bytes(flipped)
        with pytest.raises(ConfigError) as e:
            Runtime.load(art)
        assert "\n" not in str(e.value), pos


@pytest.mark.parametrize(
    ("changes", "field"),
    [
        ({"params": {"kp": -1.0}}, "params"),  # another design
        ({"params": None}, "params"),  # a missing key (was a KeyError traceback in run-drive)
        ({"command_per_action": 100.0}, "command_per_action"),  # a 10x larger command
        ({"overrides": {"plant_overrides": {"actuator": {"limit_v": 100.0}}}}, "overrides"),
        ({"scenario": "../../configs/scenarios/kang_ramp.yaml"}, "scenario"),  # a name, never a path
        ({"controller": {"model": "/elsewhere"}}, "controller.model"),
        ({"controller": {"model": "model"}}, "(file)"),  # a model the artefact does not hold
        ({"extra": 1}, "extra"),
    ],
)
def test_runtime_yaml_must_be_what_the_package_derives(tmp_path, changes, field):
    """Sealed again after the change (the seal is integrity, not a signature): each key must still equal
    what this package derives from the controller and scenario, so nothing in an artefact scales the
    command or the supervisor's limits, points outside the folder or names a file."""
    art = export("PID", tmp_path / "pid", "kang_ramp")
    Runtime.load(art)
    reseal(art, **changes)
    with pytest.raises(ConfigError) as e:
        Runtime.load(art)
    assert e.value.field == field and "\n" not in str(e.value)
    assert e.value.source == str(art / ("model/manifest.yaml" if field == "(file)" else RUNTIME))


def test_an_onnx_graph_other_than_the_model_s_is_refused(tmp_path):
    """policy.onnx must be the graph this package builds from the sealed weights: a graph with external
    data (read relative to the working directory) or any other graph is refused before onnxruntime
    sees it."""
    pytest.importorskip("onnxruntime")
    import onnx

    folder = next(f for f in MODELS if f.name == "ResSAC-kang_regulation-s0")
    art = export(str(folder), tmp_path / "art")
    model = onnx.load_from_string((art / "policy.onnx").read_bytes())
    onnx.save_model(
        model,
        str(art / "policy.onnx"),
        save_as_external_data=True,
        size_threshold=0,
        all_tensors_to_one_file=True,
        location="weights.bin",
    )
    seal(art, sealed_names(art))
    with pytest.raises(ConfigError, match="not the graph this package builds") as e:
        Runtime.load(art, backend="onnxruntime")
    assert e.value.field == "policy.onnx"
    assert Runtime.load(art).controller.name == folder.name  # numpy never reads the graph


def test_the_export_command_writes_an_artefact_and_refuses_a_scenario_that_does_not_apply(tmp_path, capsys):
    from conftest import load_script

    main = load_script("export").main
    assert main(["PID+FF", "--scenario", "m220_random", "--out", str(tmp_path / "a")]) == 0
    assert Path(capsys.readouterr().out.strip()) == tmp_path / "a"
    assert main(["PID+FF", "--scenario", "m220_regulation", "--out", str(tmp_path / "b")]) == 2
    assert "does not apply to m220_regulation" in capsys.readouterr().err


@pytest.mark.slow
def test_the_step_cost_benchmark_runs_and_times_every_controller(tmp_path):
    from conftest import load_script

    out = tmp_path / "bench.csv"
    assert load_script("bench_runtime").main(["--steps", "20", "--out", str(out)]) == 0
    import csv

    rows = list(csv.DictReader(out.open()))
    assert len(rows) == 14 + 2 * len(MODELS)
    assert all(0 < float(r["median_us"]) <= float(r["p99_us"]) <= float(r["max_us"]) for r in rows)
