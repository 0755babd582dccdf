"""A controller outside the env: an exported artefact and the runtime that steps it on a drive's readings.

`export(source, out, scenario)` writes a folder for any controller of the suite (a built-in by name, a
residual base, or a saved model's folder):

    runtime.yaml         what the runtime needs: the controller (a built-in's name, or `model/` for a
                         saved model), the scenario and the overrides its env runs with (the plant's
                         sampling, sensor scale, reference preview, history, the hardware a base brings),
                         the command scale, the controller's parameters after its design (a record the
                         runtime checks its own design against)
    model/               a saved model's files as the leaderboard loads them (manifest.yaml and
                         policy.safetensors: plain weights, no pickle), for a learned controller
    policy.onnx          the same network as ONNX (opset ONNX_OPSET; inputs: the normalised model input,
                         float32), for a learned controller
    SHA256SUMS           the seal: every file above with its SHA-256 (`sha256sum -c SHA256SUMS`)

`Runtime.load(folder)` rebuilds the controller and `step(readings, reference, preview)` gives the command
(V or N·m) for one control period: it forms the observation exactly as the env does (each reading and the
reference times 1/s, the preview, the action being held, the history; float32) and acts through the
controller's own `act`, so a runtime run reproduces the env-driven one (tests/test_runtime.py). The
network is evaluated with numpy (LayerNetwork) or, with backend="onnxruntime", by onnxruntime on the
ONNX graph in float32 (to 1e-5 of an action).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import yaml

from frictiongym.agents import registry
from frictiongym.agents.base import Controller, EpisodeContext
from frictiongym.agents.evaluation.evaluate import controller_overrides
from frictiongym.agents.learned.folder import read_sealed, seal
from frictiongym.agents.learned.manifest import MANIFEST, Manifest
from frictiongym.agents.learned.policy import LayerNetwork, LearnedPolicy
from frictiongym.agents.settings import knowledge_defaults
from frictiongym.envs.config import ConfigError, Node, scenario_names, yaml_mapping
from frictiongym.envs.records import atomic_text, atomic_write
from frictiongym.envs.scenario import Scenario, load_scenario
from frictiongym.envs.step import sanitize_observation

FORMAT = "frictiongym.runtime/2"  # /2: sealed (SHA256SUMS), runtime.yaml derived key for key
RUNTIME, ONNX, MODEL_DIR = "runtime.yaml", "policy.onnx", "model"
ONNX_OPSET = 17


def _scenario_of(controller: Controller, scenario: str) -> tuple[Scenario, dict[str, Any] | None]:
    """The scenario the controller's env runs (its hardware and observation blocks: controller_overrides),
    and those overrides."""
    overrides = controller_overrides(controller, load_scenario(scenario), None)
    return load_scenario(scenario, overrides), overrides


def _json_safe(x: Any) -> Any:
    """Controller parameters as YAML-safe plain values (numbers, strings, lists, mappings)."""
    if isinstance(x, dict):
        return {str(k): _json_safe(v) for k, v in x.items()}
    if isinstance(x, list | tuple | np.ndarray):
        return [_json_safe(v) for v in x]
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, bool | int | float | str) or x is None:
        return x
    return str(x)


def onnx_bytes(network: LayerNetwork) -> bytes:
    """The network's actor as an ONNX graph (float32): input `x` (batch, model input after the frozen
    normaliser), output `action` (batch, actions), the column selection, Gemm/Relu/Tanh layers and the
    action scaling (squash: low + (a + 1)/2·(high - low); else a clip)."""
    import onnx  # the deploy extra
    from onnx import TensorProto, helper, numpy_helper  # the deploy extra

    a = network.actor
    nodes, inits, h = [], [], "x"
    if a.columns is not None:
        inits.append(numpy_helper.from_array(np.array(a.columns, dtype=np.int64), "columns"))
        nodes.append(helper.make_node("Gather", ["x", "columns"], ["selected"], axis=1))
        h = "selected"
    for i, (kind, w, b) in enumerate(a.layers):
        out = f"h{i}"
        if kind == "linear":
            inits += [
                numpy_helper.from_array(w.T.astype(np.float32), f"W{i}"),
                numpy_helper.from_array(b.astype(np.float32), f"b{i}"),
            ]
            nodes.append(helper.make_node("Gemm", [h, f"W{i}", f"b{i}"], [out], transB=1))
        else:
            nodes.append(helper.make_node({"relu": "Relu", "tanh": "Tanh"}[kind], [h], [out]))
        h = out
    s = network.scale
    low, high = s.low.astype(np.float32), s.high.astype(np.float32)
    inits += [numpy_helper.from_array(low, "low"), numpy_helper.from_array(high, "high")]
    if s.squash:
        inits += [numpy_helper.from_array(np.array(0.5, np.float32), "half")]
        inits += [numpy_helper.from_array(np.array(1.0, np.float32), "one")]
        nodes += [
            helper.make_node("Add", [h, "one"], ["a1"]),
            helper.make_node("Mul", ["a1", "half"], ["a2"]),
            helper.make_node("Sub", ["high", "low"], ["span"]),
            helper.make_node("Mul", ["a2", "span"], ["a3"]),
            helper.make_node("Add", ["low", "a3"], ["action"]),
        ]
    else:
        nodes += [
            helper.make_node("Max", [h, "low"], ["a1"]),
            helper.make_node("Min", ["a1", "high"], ["action"]),
        ]
    n_in, n_out = network.observes[0], len(low)
    graph = helper.make_graph(
        nodes,
        "frictiongym_actor",
        [helper.make_tensor_value_info("x", TensorProto.FLOAT, ["batch", n_in])],
        [helper.make_tensor_value_info("action", TensorProto.FLOAT, ["batch", n_out])],
        inits,
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", ONNX_OPSET)])
    model.ir_version = 8
    onnx.checker.check_model(model)
    return model.SerializeToString()


def export(source: str, out: Path, scenario: str | None = None) -> Path:
    """Write the artefact of a controller (a registry name or a saved model's folder) for a scenario (a
    saved model's own scenario by default) into out, sealed (learned.folder.seal); returns out. The
    controller is designed (reset) on the scenario's nominal plant to record its parameters."""
    out = Path(out)
    folder = Path(source)
    files: dict[str, bytes] = {}
    if (folder / MANIFEST).is_file():
        sealed = read_sealed(folder)
        manifest = Manifest.parse(sealed, str(folder / MANIFEST))
        scenario = scenario or manifest.scenario
        if scenario is None:
            raise ConfigError("--scenario", f"{folder} names no scenario: give one", str(folder / MANIFEST))
        name, factory = registry.model_factory(folder, sealed)
        controller = factory()
        for f in (MANIFEST, manifest.model):
            files[f"{MODEL_DIR}/{f}"] = sealed[f]
        entry: dict[str, Any] = {"model": MODEL_DIR}
    else:
        if scenario is None:
            raise ConfigError("--scenario", f"a built-in controller ({source}) needs the scenario to run on")
        controller, name = registry.make(source), source
        entry = {"builtin": source}
    if isinstance(controller, LearnedPolicy) and isinstance(controller.network, LayerNetwork):
        files[ONNX] = onnx_bytes(controller.network)
    spec = _spec(name, entry, scenario, controller, ONNX in files)
    out.mkdir(parents=True, exist_ok=True)
    for rel, data in files.items():
        (out / rel).parent.mkdir(parents=True, exist_ok=True)
        atomic_write(out / rel, lambda p, data=data: p.write_bytes(data))
    atomic_text(out / RUNTIME, yaml.safe_dump(spec, sort_keys=False))
    seal(out, [RUNTIME, *files])
    return out


def _spec(
    name: str, entry: dict[str, str], scenario: str, controller: Controller, onnx: bool
) -> dict[str, Any]:
    """runtime.yaml's content for a controller on a scenario (with its network as policy.onnx or not), as
    this package derives it: what export writes and what Runtime.load requires, key for key (the
    controller is designed here: reset)."""
    sc, overrides = _scenario_of(controller, scenario)
    if (why := controller.why_not(sc)) is not None:
        raise ConfigError("--scenario", f"{name} does not apply to {scenario}: {why}")
    controller.reset(EpisodeContext(sc, sc.spec, knowledge_defaults()))
    return {
        "format": FORMAT,
        "name": name,
        "controller": entry,
        "scenario": scenario,
        "overrides": _json_safe(overrides),
        "control_period_s": sc.control_period,
        "command_per_action": sc.action_scale,
        "output_scale": sc.output_scale,
        "sensors": [s.name for s in sc.spec.sensors],
        "preview_steps": sc.preview_steps,
        "history": sc.history,
        "onnx_opset": ONNX_OPSET if onnx else None,
        "params": _json_safe(controller.params()),
    }


class OnnxNetwork:
    """A LayerNetwork's ONNX graph run by onnxruntime (float32), with the LayerNetwork's interface."""

    recurrent: ClassVar[bool] = False

    def __init__(self, model: bytes, like: LayerNetwork):
        import onnxruntime  # the deploy extra

        options = onnxruntime.SessionOptions()
        options.intra_op_num_threads = options.inter_op_num_threads = 1
        self.session = onnxruntime.InferenceSession(model, options, providers=["CPUExecutionProvider"])
        self.observes, self.algorithm = like.observes, like.algorithm

    def reset(self) -> None:
        """A new episode: no state."""

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return self.session.run(None, {"x": np.asarray(x, dtype=np.float32)})[0]


@dataclass
class Runtime:
    """A controller stepped on raw readings, outside the env (module docstring)."""

    controller: Controller
    scenario: Scenario
    spec: dict[str, Any]

    @classmethod
    def load(cls, folder: str | Path, backend: str = "numpy") -> Runtime:
        """An exported artefact, sealed (learned.folder.read_sealed: every file checked and read once
        before any is used); backend "numpy" or "onnxruntime" for a learned controller's network.
        runtime.yaml must be what this package writes for its controller and scenario, key for key: a
        known scenario by name, the overrides its controller brings (so nothing in the artefact scales
        the command or the supervisor's limits), the controller's design (the installed package designs
        as the exporting one did); policy.onnx the graph this package builds for the model. Any
        difference is a ConfigError naming the artefact and the key."""
        folder = Path(folder)
        source = str(folder / RUNTIME)
        files = read_sealed(folder, RUNTIME)
        node = Node(yaml_mapping(files[RUNTIME], source), source)
        if node.get("format") != FORMAT:
            raise node.error("format", f"expected {FORMAT!r}: export the controller again with this package")
        entry = node.section("controller")
        if list(entry.keys()) == ["model"]:
            if entry["model"] != MODEL_DIR:
                raise entry.error("model", f"expected {MODEL_DIR!r}, the artefact's own model folder")
            sub = {k[len(MODEL_DIR) + 1 :]: v for k, v in files.items() if k.startswith(f"{MODEL_DIR}/")}
            name, factory = registry.model_factory(folder / MODEL_DIR, sub)
            controller = factory()
        elif list(entry.keys()) == ["builtin"]:
            name = entry.string("builtin")
            controller = registry.make(name)
        else:
            raise node.error("controller", "expected {model: model} or {builtin: NAME}")
        scenario = node.choice("scenario", scenario_names())
        want = _spec(name, dict(entry.data), scenario, controller, ONNX in files)
        for key in dict.fromkeys([*node.keys(), *want]):
            if node.get(key) != want.get(key):
                why = (
                    "not a key of runtime.yaml"
                    if key not in want
                    else "differs from what this package derives"
                )
                raise node.error(
                    key,
                    f"{why} (from the controller and scenario): export again, or install the "
                    "package version that exported it",
                )
        if backend == "onnxruntime":
            if not isinstance(controller, LearnedPolicy) or ONNX not in files:
                raise ConfigError("backend", f"onnxruntime needs a learned controller's {ONNX}", source)
            if files[ONNX] != onnx_bytes(controller.network):
                raise ConfigError(
                    ONNX, "not the graph this package builds for the model: export again", source
                )
            controller.network = OnnxNetwork(files[ONNX], controller.network)
        elif backend != "numpy":
            raise ConfigError("backend", f"{backend!r}: expected 'numpy' or 'onnxruntime'", source)
        runtime = cls(controller, load_scenario(scenario, want["overrides"]), node.data)
        runtime.reset()
        return runtime

    def reset(self) -> None:
        """A new run: the controller's design and states afresh, no action held, history empty."""
        sc = self.scenario
        self.controller.reset(EpisodeContext(sc, sc.spec, knowledge_defaults()))
        self.inv = 1.0 / sc.output_scale
        self.action = 0.0
        n = len(sc.spec.sensors)
        self.history = np.zeros((sc.history, n + 1))

    def observation(
        self, readings: Sequence[float], reference: float, preview: Sequence[float]
    ) -> np.ndarray:
        """The env's observation for these readings (sensor units: rad or V), the reference r(t_k) and
        the preview r(t_{k+1}) ... r(t_{k+P}) in the tracked sensor's unit."""
        sc, inv = self.scenario, self.inv
        if len(readings) != len(sc.spec.sensors) or len(preview) != sc.preview_steps:
            raise ValueError(
                f"{len(sc.spec.sensors)} readings and {sc.preview_steps} preview samples expected, "
                f"got {len(readings)} and {len(preview)}"
            )
        sensors = [float(m) * inv for m in readings]
        parts = {
            "sensors": sensors,
            "reference": [float(reference) * inv],
            "preview": [float(r) * inv for r in preview],
            "previous_action": [self.action],
        }
        if sc.history:
            self.history[1:] = self.history[:-1].copy()
            self.history[0, :-1], self.history[0, -1] = sensors, self.action
            parts["history"] = self.history.reshape(-1).tolist()
        return sanitize_observation(sc.layout.pack(parts))

    def step(self, readings: Sequence[float], reference: float, preview: Sequence[float] = ()) -> float:
        """The command (V or N·m) for one control period: the controller's action on the observation of
        these readings, clipped to [-1, 1] as the env applies it, times the command scale."""
        obs = self.observation(readings, reference, preview)
        x = float(np.asarray(self.controller.act(obs)).reshape(-1)[0])
        self.action = x if -1.0 <= x <= 1.0 else (1.0 if x > 0.0 else -1.0)
        return self.action * self.scenario.action_scale
