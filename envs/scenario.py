"""Scenarios (configs/scenarios/*.yaml): plant preset, friction model, sampling, reference, initial-state
distribution, randomisation, episode length and reward weights, loaded and checked into a Scenario."""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from .config import ConfigError, configs_dir, interval, load_yaml, merge, nonneg, number, positive
from .plants import PlantSpec, plant_spec
from .plants.mjcf import friction_joints
from .step import ObservationLayout, observation_layout

REFERENCE_TYPES = ("constant", "steps", "sine", "triangle")


def scenario_names() -> list[str]:
    """Names of the scenarios under configs/scenarios/."""
    return sorted(p.stem for p in (configs_dir() / "scenarios").glob("*.yaml"))


@dataclass(frozen=True)
class Reference:
    """Reference generator r(t) in the tracked sensor's unit (rad or V)."""

    type: str
    value: float = 0.0
    schedule: tuple[tuple[float, float], ...] = ()
    amplitude: float = 0.0
    frequency_hz: float = 0.0
    offset: float = 0.0
    phase_rad: float = 0.0

    def __call__(self, t: np.ndarray | float) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        if self.type == "constant":
            return np.full_like(t, self.value)
        if self.type == "steps":
            starts = np.array([s for s, _ in self.schedule])
            values = np.array([0.0] + [v for _, v in self.schedule])
            return values[np.searchsorted(starts, t + 1e-12, side="right")]
        w = 2.0 * np.pi * self.frequency_hz * t + self.phase_rad
        if self.type == "sine":
            return self.offset + self.amplitude * np.sin(w)
        return self.offset + self.amplitude * (2.0 / np.pi) * np.arcsin(np.sin(w))  # triangle


@dataclass(frozen=True)
class Scenario:
    """A checked scenario; `spec` is the plant at the scenario's control period."""

    name: str
    spec: PlantSpec
    episode_steps: int
    randomize: bool
    tracked_sensor: int
    output_scale: float
    action_scale: float
    settle_band: float
    reference: Reference
    preview_steps: int
    qpos_range: np.ndarray  # (nv, 2)
    qvel_range: np.ndarray  # (nv, 2)
    history: int
    privileged: bool
    reward_weights: dict[str, float]

    @property
    def control_period(self) -> float:
        return self.spec.control_period

    @cached_property
    def layout(self) -> ObservationLayout:
        """Named slices of this scenario's observation (envs/step.py)."""
        return observation_layout(
            len(self.spec.sensors),
            self.preview_steps,
            self.history,
            self.privileged,
            len(friction_joints(self.spec)),
        )

    @property
    def task(self) -> str:
        """ "regulation" (constant reference) or "tracking"."""
        return "regulation" if self.reference.type == "constant" else "tracking"


def _reference(r: dict) -> Reference:
    kind = r.get("type")
    if kind not in REFERENCE_TYPES:
        raise ConfigError("reference.type", f"{kind!r} not in {list(REFERENCE_TYPES)}")
    if kind == "constant":
        return Reference("constant", value=number(r.get("value", 0.0), "reference.value"))
    if kind == "steps":
        sched = r.get("schedule")
        if not isinstance(sched, list) or not sched:
            raise ConfigError("reference.schedule", "expected a non-empty list of [t_start, value] pairs")
        pairs = []
        for i, p in enumerate(sched):
            if not isinstance(p, list | tuple) or len(p) != 2:
                raise ConfigError(f"reference.schedule[{i}]", f"expected [t_start, value], got {p!r}")
            pairs.append(
                (
                    number(p[0], f"reference.schedule[{i}][0]", 0.0),
                    number(p[1], f"reference.schedule[{i}][1]"),
                )
            )
        if any(b[0] <= a[0] for a, b in itertools.pairwise(pairs)):
            raise ConfigError("reference.schedule", "start times must increase")
        return Reference("steps", schedule=tuple(pairs))
    return Reference(
        kind,
        amplitude=nonneg(r.get("amplitude", 0.0), "reference.amplitude"),
        frequency_hz=positive(r.get("frequency_hz"), "reference.frequency_hz"),
        offset=number(r.get("offset", 0.0), "reference.offset"),
        phase_rad=number(r.get("phase_rad", 0.0), "reference.phase_rad"),
    )


def _deep_update(base: dict, extra: dict) -> dict:
    """base updated recursively with extra (no key checks: the plant preset checks them)."""
    for k, v in extra.items():
        base[k] = _deep_update(dict(base.get(k) or {}), v) if isinstance(v, dict) else v
    return base


def _ranges(value: Any, nv: int, field_: str) -> np.ndarray:
    if not isinstance(value, list) or len(value) != nv:
        raise ConfigError(field_, f"expected {nv} [low, high] pairs (one per joint), got {value!r}")
    return np.array([interval(v, f"{field_}[{i}]") for i, v in enumerate(value)])


def load_scenario(name_or_path: str | Path, overrides: dict | None = None, **kwargs: Any) -> Scenario:
    """Load a scenario by name or path; `overrides` deep-merges YAML keys, kwargs set top-level keys
    (e.g. control_period_s=0.04, randomize=True, episode_s=5)."""
    cfg = load_yaml(name_or_path, kind="scenarios")
    overrides = dict(overrides or {})
    # plant overrides are checked against the plant preset (plant_spec), not the scenario's own dict
    plant_extra = overrides.pop("plant_overrides", None) or {}
    cfg = merge(cfg, overrides)
    cfg["plant_overrides"] = _deep_update(dict(cfg.get("plant_overrides") or {}), plant_extra)
    cfg = merge(cfg, {k: v for k, v in kwargs.items() if v is not None})
    name = Path(str(name_or_path)).stem
    period = positive(cfg["control_period_s"], "control_period_s")
    plant_ov = dict(cfg.get("plant_overrides") or {})
    plant_ov["sampling"] = {**plant_ov.get("sampling", {}), "control_period_s": period}
    spec = plant_spec(cfg["plant"], plant_ov, cfg.get("friction_model", "lugre"))
    task = cfg["task"]
    names = [s.name for s in spec.sensors]
    if task["tracked_sensor"] not in names:
        raise ConfigError("task.tracked_sensor", f"{task['tracked_sensor']!r} not in {names}")
    unit_key = "action_scale_nm" if spec.command_unit == "N·m" else "action_scale_v"
    if unit_key not in task:
        raise ConfigError(f"task.{unit_key}", f"required for a plant commanded in {spec.command_unit}")
    action_scale = number(task[unit_key], f"task.{unit_key}", 0.0, spec.command_limit, low_open=True)
    episode = positive(cfg["episode_s"], "episode_s")
    steps = round(episode / period)
    if abs(steps * period - episode) > 1e-9 * episode:
        raise ConfigError("episode_s", f"{episode} must be a whole number of control periods ({period})")
    randomize = cfg.get("randomize", False)
    if not isinstance(randomize, bool):
        raise ConfigError("randomize", f"expected true or false, got {randomize!r}")
    ref = cfg["reference"]
    obs = cfg.get("observation", {})
    weights = {
        k: nonneg(cfg["reward"].get(k, 0.0), f"reward.{k}") for k in ("tracking", "effort", "smoothness")
    }
    nv = len(spec.joints)
    n_init = 1 if spec.belts else nv
    return Scenario(
        name=name,
        spec=spec,
        episode_steps=steps,
        randomize=randomize,
        tracked_sensor=names.index(task["tracked_sensor"]),
        output_scale=positive(task["output_scale"], "task.output_scale"),
        action_scale=action_scale,
        settle_band=positive(task["settle_band"], "task.settle_band"),
        reference=_reference(ref),
        preview_steps=int(number(ref.get("preview_steps", 0), "reference.preview_steps", 0, 1000)),
        qpos_range=_ranges(cfg["initial_state"]["qpos"], n_init, "initial_state.qpos"),
        qvel_range=_ranges(cfg["initial_state"]["qvel"], n_init, "initial_state.qvel"),
        history=int(number(obs.get("history", 0), "observation.history", 0, 1000)),
        privileged=bool(obs.get("privileged", False)),
        reward_weights=weights,
    )
